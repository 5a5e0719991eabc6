"""strokekit: 3D scenes to coherent line drawings.

Pipeline: scene -> frame view -> feature edges -> visible runs -> strokes -> tracked strokes -> writers.
"""

from .camera import Camera, CameraPath, load_camera_path, orbit_path
from .errors import InputError, StrokekitError, UsageError
from .lines import LineRenderer
from .model import KINDS, FeatureEdges, Strokes, VisibleRuns
from .options import LineOptions
from .scene import Scene, build_scene, load_scene

__version__ = "0.1.0"
__all__ = ["Camera", "CameraPath", "load_camera_path", "orbit_path", "InputError", "StrokekitError", "UsageError",
           "LineRenderer", "KINDS", "FeatureEdges", "Strokes", "VisibleRuns", "LineOptions", "Scene", "build_scene",
           "load_scene"]
