"""Ribbons: the triangle strips along strokes that the glTF writer stores, textured with a
brush image (`build_ribbons` -> `RibbonMesh`)."""

from strokekit.lazy import exports

#: Public names and their modules, each imported when first used.
_EXPORTS = {
    "Brush": "strokekit.ribbons.brushes",
    "RibbonMesh": "strokekit.ribbons.mesh",
    "RibbonOptions": "strokekit.ribbons.options",
    "build_ribbons": "strokekit.ribbons.mesh",
    "get_brush": "strokekit.ribbons.brushes",
}
__all__ = list(_EXPORTS)
__getattr__ = exports(__name__, _EXPORTS)
