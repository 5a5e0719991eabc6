"""The camera stage: a frame's view (`Camera`: eye, lens, image), camera paths read from JSON
or glTF camera nodes or generated (orbit, dolly), and the frame selection of a run."""

from strokekit.camera.frames import parse_frames
from strokekit.camera.gltf import gltf_camera_count, gltf_camera_path
from strokekit.camera.paths import camera_path_from_json, dolly_path, load_camera_path, orbit_path, parallel_path
from strokekit.camera.view import Camera, CameraPath

__all__ = ["Camera", "CameraPath", "camera_path_from_json", "dolly_path", "gltf_camera_count", "gltf_camera_path",
           "load_camera_path", "orbit_path", "parallel_path", "parse_frames"]
