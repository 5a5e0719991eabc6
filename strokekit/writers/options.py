"""The glTF ribbons' options (`GltfOptions`), without numpy: the options load without the
writers."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

from strokekit.errors import UsageError
from strokekit.options import option
from strokekit.ribbons.options import RibbonOptions

if TYPE_CHECKING:
    from strokekit.ribbons.brushes import Brush

#: --svg-lines: strokes whose width varies drawn as filled outlines (their width everywhere), or
#: every stroke as its centreline at its mean width (plotters).
SVG_LINES = ("outline", "centreline")


@dataclass(frozen=True)
class GltfOptions:
    """glTF ribbon output. width_px: ribbon width on screen; taper: the width tapers linearly over
    taper x the brush's head and tail lengths (bundled brushes: 2 widths each; 0 = no taper);
    brush: a bundled brush name (plain, ink, dry) or a PNG path; alpha_mode: "BLEND" or "MASK" (alpha_cutoff);
    space: "world" or "image"; color: None (per line kind for bundled brushes, the image's own
    colour for a user's brush) or "#rrggbb" for all; fps: sequence timing; pull: world mode,
    fraction of depth the ribbons move toward the camera."""

    width_px: float = option(3.0, "--ribbon-width", "Ribbon width in px.", show_default=True, needs="gltf")
    taper: float = option(1.0, "--taper", "Head/tail taper (0: none).", show_default=True, needs="gltf")
    brush: str = option("ink", "--brush", "plain, ink, dry, or a PNG of your own stroke.", show_default=True,
                        needs="gltf")
    alpha_mode: str = option("BLEND", "--alpha-mode", "glTF alpha of the ribbons: blended, or cut out (mask).",
                             choices={"blend": "BLEND", "mask": "MASK"}, show_default=True, needs="gltf")
    alpha_cutoff: float = 0.5
    space: str = option(
        "world", "--ribbon-space", "Ribbons in the scene facing the camera, or flat in pixel units for 2D compositing.",
        choices=("world", "image"), show_default=True, needs="gltf")
    color: str | None = None
    fps: float = 24.0
    miter_limit: float = 4.0
    pull: float = 0.003
    unlit: bool = True
    level_texcoord: bool = True

    def __post_init__(self):
        if self.alpha_mode not in ("BLEND", "MASK"):
            raise UsageError(f"alpha_mode must be BLEND or MASK, got {self.alpha_mode!r}", option="alpha_mode")
        if not 0 <= self.alpha_cutoff <= 1:
            raise UsageError(f"alpha cutoff must be in [0, 1], got {self.alpha_cutoff}")
        if not (math.isfinite(self.taper) and self.taper >= 0):
            raise UsageError(f"taper must be a finite number >= 0, got {self.taper}", option="taper")
        if not self.fps > 0:
            raise UsageError(f"fps must be > 0, got {self.fps}")
        if self.color is not None:
            hex_srgb(self.color)
        RibbonOptions(width_px=self.width_px, space=self.space, miter_limit=self.miter_limit, pull=self.pull)

    def ribbon_options(self, brush: Brush) -> RibbonOptions:
        """The ribbon geometry these options ask for, head/tail sized from the brush."""
        w = self.width_px
        # the width tapers over the brush's head and tail (times `taper`): with taper 1 the taper
        # ends where the texture regions end, so both share their vertices
        head, tail = brush.head_px(w), brush.tail_px(w)
        return RibbonOptions(width_px=w, taper_head_px=head * self.taper, taper_tail_px=tail * self.taper,
                             head_px=head, tail_px=tail, tex_head=brush.tex_head,
                             tex_tail=brush.tex_tail, miter_limit=self.miter_limit, space=self.space, pull=self.pull)


def hex_srgb(c: str) -> tuple[float, float, float]:
    """#rrggbb -> its sRGB-encoded (r, g, b) in [0, 1]; a UsageError when it is not one."""
    s = c.lstrip("#")
    if len(s) != 6 or any(ch not in "0123456789abcdefABCDEF" for ch in s):
        raise UsageError(f"colour must be #rrggbb, got {c!r}")
    return tuple(int(s[i:i + 2], 16) / 255.0 for i in (0, 2, 4))
