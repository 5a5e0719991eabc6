"""strokekit: 3D scenes to coherent line drawings.

Pipeline: scene -> frame view -> feature edges -> visible runs -> strokes -> tracked strokes -> writers;
`render_sequence` takes a camera path through it in memory, `strokekit.run.run` to files.
"""

from strokekit.lazy import exports

__version__ = "0.1.0"

#: Public names and their modules, each imported when first used.
_EXPORTS = {
    "Camera": "strokekit.camera.view",
    "CameraPath": "strokekit.camera.view",
    "load_camera_path": "strokekit.camera.paths",
    "orbit_path": "strokekit.camera.paths",
    "InputError": "strokekit.errors",
    "StrokekitError": "strokekit.errors",
    "UsageError": "strokekit.errors",
    "LineRenderer": "strokekit.lines.renderer",
    "KINDS": "strokekit.model",
    "FeatureEdges": "strokekit.model",
    "Strokes": "strokekit.model",
    "VisibleRuns": "strokekit.model",
    "LineOptions": "strokekit.options",
    "Scene": "strokekit.scene.load",
    "build_scene": "strokekit.scene.load",
    "load_scene": "strokekit.scene.load",
    "Frame": "strokekit.run.frame",
    "RenderRequest": "strokekit.run.request",
    "render_sequence": "strokekit.run.sequence",
}
__all__ = list(_EXPORTS)
__getattr__ = exports(__name__, _EXPORTS)
