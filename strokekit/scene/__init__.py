"""The scene stage: triangle meshes read from OBJ, PLY, STL and glTF/GLB, welded, with their
materials and objects (`Scene`), the tables derived from them on first use (normals, face edges,
sizes: `Scene`'s cached properties), and the ray backend that answers ray queries against it
(`Occluder`)."""

from strokekit.scene.load import SUPPORTED, Material, Scene, build_scene, load_scene
from strokekit.scene.occluder import Occluder

__all__ = ["SUPPORTED", "Material", "Scene", "build_scene", "load_scene", "Occluder"]
