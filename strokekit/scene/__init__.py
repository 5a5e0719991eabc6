"""The scene stage: triangle meshes read from OBJ, PLY, STL and glTF/GLB, welded, with their
materials and objects (`Scene`); per-scene tables derived once (normals, face edges, sizes); and
the Embree occluder that answers ray queries against it."""

from strokekit.scene.load import SUPPORTED, Material, Scene, build_scene, load_scene
from strokekit.scene.occluder import Occluder
from strokekit.scene.tables import scene_cache

__all__ = ["SUPPORTED", "Material", "Scene", "build_scene", "load_scene", "Occluder", "scene_cache"]
