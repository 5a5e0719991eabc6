"""Line styles: line sets selecting strokes (by kind, occlusion level, object or material) and
drawing them in a colour, a width and dashes, the width varied along each stroke by thickness
modifiers (`Style`, read from a TOML file by `read_style`); `apply_style` gives a frame's strokes
their widths per point (`StyledStrokes`), which every writer draws."""

from strokekit.style.file import read_style
from strokekit.style.linesets import (
    KIND_COLORS,
    Along,
    Calligraphy,
    Curvature,
    Depth,
    LineSet,
    Noise,
    Style,
)
from strokekit.style.widths import StyleContext, StyledStrokes, apply_style, style_context

__all__ = ["KIND_COLORS", "Along", "Calligraphy", "Curvature", "Depth", "LineSet", "Noise", "Style", "StyleContext",
           "StyledStrokes", "apply_style", "read_style", "style_context"]
