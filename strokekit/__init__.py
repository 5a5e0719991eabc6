"""strokekit: 3D scenes to coherent line drawings.

Pipeline: scene -> frame view -> feature edges -> visible runs -> strokes -> tracked strokes -> writers;
`render_sequence` takes a camera path through it in memory, `strokekit.run.run` to files.
"""

import importlib

from strokekit.camera.paths import load_camera_path, orbit_path
from strokekit.camera.view import Camera, CameraPath
from strokekit.errors import InputError, StrokekitError, UsageError
from strokekit.lines.renderer import LineRenderer
from strokekit.model import KINDS, FeatureEdges, Strokes, VisibleRuns
from strokekit.options import LineOptions
from strokekit.scene.load import Scene, build_scene, load_scene

__version__ = "0.1.0"
__all__ = ["Camera", "CameraPath", "load_camera_path", "orbit_path", "InputError", "StrokekitError", "UsageError",
           "LineRenderer", "KINDS", "FeatureEdges", "Strokes", "VisibleRuns", "LineOptions", "Scene", "build_scene",
           "load_scene", "Frame", "RenderRequest", "render_sequence"]


def __getattr__(name: str):
    # The sequence API is imported when first used: a plain `import strokekit` does not load the run.
    if name in ("Frame", "RenderRequest", "render_sequence"):
        return getattr(importlib.import_module("strokekit.run"), name)
    raise AttributeError(f"module 'strokekit' has no attribute {name!r}")
