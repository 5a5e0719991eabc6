"""Ribbons: the triangle strips along strokes that the glTF writer stores, textured with a
brush image (`build_ribbons` -> `RibbonMesh`)."""

from strokekit.ribbons.brushes import Brush, get_brush
from strokekit.ribbons.mesh import RibbonMesh, RibbonOptions, build_ribbons

__all__ = ["Brush", "RibbonMesh", "RibbonOptions", "build_ribbons", "get_brush"]
