"""Line styles: line sets selecting strokes (by kind, occlusion level, object or material) and
drawing them in a colour, a width and dashes, the width varied along each stroke by thickness
modifiers (`Style`, read from a TOML file by `read_style`); `apply_style` gives a frame's strokes
their widths per point (`StyledStrokes`), which every writer draws."""

from strokekit.lazy import exports

#: Public names and their modules, each imported when first used.
_EXPORTS = {
    "KIND_COLORS": "strokekit.style.linesets",
    "Along": "strokekit.style.linesets",
    "Calligraphy": "strokekit.style.linesets",
    "Curvature": "strokekit.style.linesets",
    "Depth": "strokekit.style.linesets",
    "LineSet": "strokekit.style.linesets",
    "Noise": "strokekit.style.linesets",
    "Style": "strokekit.style.linesets",
    "StyleContext": "strokekit.style.widths",
    "StyledStrokes": "strokekit.style.widths",
    "apply_style": "strokekit.style.widths",
    "read_style": "strokekit.style.file",
    "style_context": "strokekit.style.widths",
}
__all__ = list(_EXPORTS)
__getattr__ = exports(__name__, _EXPORTS)
