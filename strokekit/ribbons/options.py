"""How strokes become ribbons (`RibbonOptions`) and the bundled brushes' names, without numpy:
the options load without the ribbon code."""

from __future__ import annotations

import math
from dataclasses import dataclass

from strokekit.camera.limits import MAX_IMAGE_PX
from strokekit.errors import UsageError
from strokekit.style.linesets import JOIN_ANGLE_DEG, JOIN_PX

#: The brushes strokekit draws itself (ribbons.brushes); any other name is a PNG of the user's.
BUNDLED = ("plain", "ink", "dry")


@dataclass(frozen=True)
class RibbonOptions:
    """How strokes become ribbons. Lengths in image pixels.

    width_px: full ribbon width where the stroke is not tapered.
    taper_head_px / taper_tail_px: length of the width taper at the start / end (0: none);
      taper_min: width fraction at the very tip (> 0 keeps tip triangles non-degenerate);
      taper_steps: vertices placed inside each taper (1: a linear ramp; more: an eased curve).
    cap: a free end runs on past the stroke's end point by this fraction of its width (0.5: as far
      as the SVG's round cap), so that the faint tip of the taper lies beyond the line's end, not
      on it (0: the ribbon stops at the end point).
    head_px / tail_px: length on screen of the brush texture's head and tail regions;
      tex_head / tex_tail: the share of the texture width those regions occupy.
    miter_limit: largest miter length / half width before the outer join is bevelled (SVG's 4).
    join_px, join_angle_deg: two stroke ends this close whose line runs on through them, turning at
      most join_angle_deg, are joined (module doc; join_px 0: every end is a free end).
    space: "world" (ribbons placed in the scene, facing the camera) or "image" (x, H - y, 0 in px).
    pull: world mode, fraction of its depth by which each vertex is moved toward the camera
      along its own view ray (keeps the pixel, avoids z-fighting with the surface)."""

    width_px: float = 3.0
    taper_head_px: float = 6.0
    taper_tail_px: float = 10.0
    taper_min: float = 0.25
    taper_steps: int = 1
    cap: float = 0.5
    head_px: float = 3.0
    tail_px: float = 6.0
    tex_head: float = 0.25
    tex_tail: float = 0.25
    miter_limit: float = 4.0
    join_px: float = JOIN_PX
    join_angle_deg: float = JOIN_ANGLE_DEG
    space: str = "world"
    pull: float = 0.003

    def __post_init__(self):
        if not (math.isfinite(self.width_px) and 0 < self.width_px <= MAX_IMAGE_PX):
            raise UsageError(f"ribbon width must be > 0 px and at most {MAX_IMAGE_PX} px (the largest image side), "
                             f"got {self.width_px:g}")
        for name in ("taper_head_px", "taper_tail_px", "head_px", "tail_px"):
            if not (math.isfinite(getattr(self, name)) and getattr(self, name) >= 0):
                raise UsageError(f"{name.replace('_', '-')} must be >= 0, got {getattr(self, name)}")
        if not 0 < self.taper_min <= 1:
            raise UsageError(f"taper-min must be in (0, 1], got {self.taper_min}")
        if not (0 <= self.tex_head < 1 and 0 <= self.tex_tail < 1 and self.tex_head + self.tex_tail < 1):
            raise UsageError("brush head and tail must leave part of the texture to the body")
        if not self.miter_limit >= 1:
            raise UsageError(f"miter limit must be >= 1, got {self.miter_limit}")
        if not (math.isfinite(self.join_px) and self.join_px >= 0):
            raise UsageError(f"join-px must be a finite number >= 0, got {self.join_px}")
        if not 0 <= self.join_angle_deg < 90:
            raise UsageError(f"join angle must be in [0, 90) degrees, got {self.join_angle_deg}")
        if self.space not in ("world", "image"):
            raise UsageError(f"ribbon space must be 'world' or 'image', got {self.space!r}")
        if not 0 <= self.pull < 1:
            raise UsageError(f"pull must be in [0, 1), got {self.pull}")
        if not (math.isfinite(self.cap) and 0 <= self.cap <= 4):
            raise UsageError(f"ribbon cap must be in [0, 4] widths, got {self.cap}")
        if int(self.taper_steps) < 1:
            raise UsageError(f"taper steps must be >= 1, got {self.taper_steps}")
