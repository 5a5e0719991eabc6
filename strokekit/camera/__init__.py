"""The camera stage: a frame's view (`Camera`: eye, lens, image), camera paths read from JSON
or glTF camera nodes or generated (orbit, dolly), and the frame selection of a run."""

from strokekit.lazy import exports

#: Public names and their modules, each imported when first used.
_EXPORTS = {
    "Camera": "strokekit.camera.view",
    "CameraPath": "strokekit.camera.view",
    "camera_path_from_json": "strokekit.camera.paths",
    "dolly_path": "strokekit.camera.paths",
    "gltf_camera_count": "strokekit.camera.gltf",
    "gltf_camera_path": "strokekit.camera.gltf",
    "load_camera_path": "strokekit.camera.paths",
    "orbit_path": "strokekit.camera.paths",
    "parallel_path": "strokekit.camera.paths",
    "parse_frames": "strokekit.camera.frames",
}
__all__ = list(_EXPORTS)
__getattr__ = exports(__name__, _EXPORTS)
