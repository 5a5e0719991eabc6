"""Writers turn finished strokes, ribbons and raster images into file bytes (SVG, JSON, GLB,
PNG). They compute no geometry."""

from strokekit.lazy import exports

#: Public names and their modules, each imported when first used.
_EXPORTS = {
    "GltfOptions": "strokekit.writers.options",
    "glb_for_frame": "strokekit.writers.gltf",
    "glb_for_sequence": "strokekit.writers.gltf",
    "png_bytes": "strokekit.writers.png",
    "read_png": "strokekit.writers.png",
    "read_strokes_json": "strokekit.writers.strokes_json",
    "strokes_json": "strokekit.writers.strokes_json",
    "svg_document": "strokekit.writers.svg",
}
__all__ = list(_EXPORTS)
__getattr__ = exports(__name__, _EXPORTS)
