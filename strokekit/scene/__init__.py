"""The scene stage: triangle meshes read from OBJ, PLY, STL and glTF/GLB, welded, with their
materials and objects (`Scene`), the tables derived from them on first use (normals, face edges,
sizes: `Scene`'s cached properties), and the ray backend that answers ray queries against it
(`Occluder`)."""

from strokekit.lazy import exports

#: Public names and their modules, each imported when first used.
_EXPORTS = {
    "SUPPORTED": "strokekit.scene.load",
    "Material": "strokekit.scene.load",
    "Scene": "strokekit.scene.load",
    "build_scene": "strokekit.scene.load",
    "load_scene": "strokekit.scene.load",
    "Occluder": "strokekit.scene.occluder",
}
__all__ = list(_EXPORTS)
__getattr__ = exports(__name__, _EXPORTS)
