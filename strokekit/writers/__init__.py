"""Writers turn finished strokes, ribbons and raster images into file bytes (SVG, JSON, GLB,
PNG). They compute no geometry."""

from strokekit.writers.gltf import GltfOptions, glb_for_frame, glb_for_sequence
from strokekit.writers.png import png_bytes, read_png
from strokekit.writers.strokes_json import read_strokes_json, strokes_json
from strokekit.writers.svg import svg_document

__all__ = ["GltfOptions", "glb_for_frame", "glb_for_sequence", "png_bytes", "read_png", "read_strokes_json",
           "strokes_json", "svg_document"]
