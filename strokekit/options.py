"""Options of a line render, and the named accuracy presets (`--quality`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from strokekit.errors import UsageError
from strokekit.model import KINDS, MAX_OCCLUSION

#: Accuracy knobs per preset. whole_edge_px: edges shorter than this on screen get one
#: visibility ray at their middle and are drawn whole or not at all (0: none);
#: sample_spacing_px: distance between visibility samples along an edge on screen;
#: bisection_tol_px: where visibility changes, the split point is located to this (draft does not
#: bisect, bisect_changes False: its changes lie in the middle of a 2 px bracket, within 1 px);
#: retest_front_hits: see LineOptions; supersample: raster masks; simplify_tol_px: polyline
#: simplification (0 = none); doubled_px and merge_overlaps: the cleanup of lines drawn twice
#: (draft previews keep them); supersample K and edge_supersample R: the raster pass's samples
#: per pixel side, and the band-edge pixels resampled R x R (0: none).
QUALITY_PRESETS: dict[str, dict] = {
    "draft": {"whole_edge_px": 12.0, "sample_spacing_px": 2.0, "bisection_tol_px": 1.0, "supersample": 1,
              "edge_supersample": 0,
              "simplify_tol_px": 0.0, "doubled_px": 0.0, "merge_overlaps": False, "bisect_changes": False,
              "retest_front_hits": False},
    "default": {"sample_spacing_px": 4.0, "bisection_tol_px": 0.01, "supersample": 1, "edge_supersample": 4,
                "simplify_tol_px": 0.0},
    "exact": {"sample_spacing_px": 0.25, "bisection_tol_px": 1e-3, "supersample": 4, "edge_supersample": 0,
              "simplify_tol_px": 0.0},
}

DEFAULT_KINDS = ("silhouette", "border", "crease", "material", "nonmanifold")

#: Bounds of the accuracy knobs. Visibility samples closer than 0.01 px find nothing the
#: bisection does not (it locates every change to bisection_tol_px) and cost memory without end
#: (1e-9 px asked for 33 TiB); a change located finer than 1e-6 px is below what the float32 ray
#: tracer can tell; doubled parts looked for beyond 16 px compare every sample with every other
#: (the close pairs of a frame grow with the square of the radius) and drop lines a few pixels
#: apart that are two lines. The line pass's memory is also estimated before a run
#: (lines.budget.check_lines_fit).
MIN_SAMPLE_SPACING_PX = 0.01
MIN_BISECTION_TOL_PX = 1e-6
MAX_DOUBLED_PX = 16.0
#: A texture period longer than the largest image (camera.view.MAX_IMAGE_PX) never repeats on a
#: stroke; from about 1e7 px the fit of u (tracking.ufit) breaks down numerically.
MAX_PERIOD_PX = 100_000.0

@dataclass(frozen=True)
class LineOptions:
    """What lines to find and how accurately. Pixel values are image-space pixels."""

    kinds: tuple[str, ...] = DEFAULT_KINDS
    crease_angle_deg: float = 60.0
    # Edges shorter than this many px on screen get one visibility ray at their middle and are
    # drawn whole or not at all (seed 000's per-edge test; a partly hidden one is off by up to
    # its length): the draft preset, for previews of fine meshes. Longer edges, and every edge
    # at 0, are sampled and split where their visibility changes (BRIEF 2).
    whole_edge_px: float = 0.0
    sample_spacing_px: float = 4.0
    bisection_tol_px: float = 0.01
    # False: visibility changes are not bisected; each is placed in the middle of the bracket
    # between its two samples, within sample_spacing_px / 2 (bisection_tol_px is not used), and
    # every sample goes in one occlusion call (the draft preset; visibility.visible_runs).
    bisect_changes: bool = True
    # False: skip the plain-ray re-test of samples whose lifted ray is stopped near its start by
    # the front side of a triangle (Occluder.visible_rows; the draft preset).
    retest_front_hits: bool = True
    split_angle_deg: float = 90.0
    max_length_px: float = 0.0  # 0: no limit
    min_length_px: float = 0.0  # strokes shorter than this are dropped
    simplify_tol_px: float = 0.0
    merge_overlaps: bool = True  # drop zig-zag spurs that retrace a longer stroke
    overlap_tol_px: float = 0.5
    # Parts of contour strokes that run beside a longer stroke of their kind within this many px
    # are dropped (mesh contours come out shingled; strokeops.drop_doubled). 0 (the default) keeps
    # every visible contour edge: the lines are exact, and the brush paths (strokekit.paths) are
    # what shares one stroke among the shingles of a contour. Done per frame, so a frame draws the
    # same lines alone, in a sequence, with or without tracking.
    doubled_px: float = 0.0
    occlusion_offset: float = 1e-5  # ray offset as a fraction of the scene radius
    contours: str = "mesh"  # or "smooth": interpolated contours replace mesh silhouettes
    suggestive_kr_threshold: float = 0.0  # dimensionless (x 1/scene radius): skip faces with flatter radial curvature
    suggestive_derivative_threshold: float = 50.0  # dimensionless (scaled by the scene radius): min R^2 D_w k_r tan(theta)
    period_px: float = 30.0  # texture period for u
    # Hidden lines (issue 20): None draws the visible lines (level 0, the occlusion test alone);
    # (lo, hi) draws the pieces whose occlusion level (the number of surfaces in front of them)
    # is in lo..hi, each stroke with its level (lines.occlusion). hi = MAX_OCCLUSION: any depth.
    occlusion: tuple[int, int] | None = None

    def __post_init__(self):
        unknown = [k for k in self.kinds if k not in KINDS]
        if unknown:
            raise UsageError(f"unknown line kind(s) {', '.join(unknown)} (known: {', '.join(KINDS)})")
        if not self.kinds:
            raise UsageError("no line kinds selected")
        # One order (KINDS'), each kind once: the drawing does not depend on the order they were
        # given in, so neither do the run's options digest (a resume) nor the files.
        object.__setattr__(self, "kinds", tuple(k for k in KINDS if k in set(self.kinds)))
        for name in ("sample_spacing_px", "bisection_tol_px", "period_px"):
            v = getattr(self, name)
            if not (v > 0 and math.isfinite(v)):
                raise UsageError(f"{name} must be a finite number > 0, got {v}", option=name)
        for name in ("max_length_px", "min_length_px", "simplify_tol_px", "doubled_px", "whole_edge_px"):
            v = getattr(self, name)
            if not (v >= 0 and math.isfinite(v)):
                raise UsageError(f"{name} must be a finite number >= 0 px, got {v}", option=name)
        for name, low, why in (("sample_spacing_px", MIN_SAMPLE_SPACING_PX, "closer samples find nothing the "
                                "bisection does not and only cost memory"),
                               ("bisection_tol_px", MIN_BISECTION_TOL_PX, "finer than the float32 ray tracer can "
                                "tell")):
            if getattr(self, name) < low:
                raise UsageError(f"{name} must be at least {low:g} px ({why}), got {getattr(self, name):g}",
                                 option=name)
        if self.period_px > MAX_PERIOD_PX:
            raise UsageError(f"period_px must be at most {MAX_PERIOD_PX:g} px (the largest image side), got "
                             f"{self.period_px:g}", option="period_px")
        if self.doubled_px > MAX_DOUBLED_PX:
            raise UsageError(f"doubled_px must be at most {MAX_DOUBLED_PX:g} px (lines farther apart are two lines, "
                             f"and the search grows with the square of the distance), got {self.doubled_px:g}",
                             option="doubled_px")
        if not 0 < self.crease_angle_deg < 180:
            raise UsageError(f"crease_angle_deg must be in (0, 180) degrees, got {self.crease_angle_deg}",
                             option="crease_angle_deg")
        if not 0 < self.split_angle_deg <= 180:
            raise UsageError(f"split_angle_deg must be in (0, 180] degrees, got {self.split_angle_deg}",
                             option="split_angle_deg")
        if self.contours not in ("mesh", "smooth"):
            raise UsageError(f"contours must be 'mesh' or 'smooth', got {self.contours!r}")
        if self.occlusion is not None:
            rng = tuple(self.occlusion)
            if (len(rng) != 2 or any(isinstance(v, bool) or not isinstance(v, (int, np.integer)) for v in rng)
                    or not 0 <= rng[0] <= rng[1] <= MAX_OCCLUSION):
                raise UsageError(f"occlusion must be two whole levels lo <= hi within 0-{MAX_OCCLUSION} (deeper "
                                 f"pieces count as {MAX_OCCLUSION}), got {self.occlusion!r}", option="occlusion")
            object.__setattr__(self, "occlusion", (int(rng[0]), int(rng[1])))
        for name in ("suggestive_derivative_threshold", "suggestive_kr_threshold"):  # thresholds on magnitudes
            v = getattr(self, name)
            if not (v >= 0 and math.isfinite(v)):
                raise UsageError(f"{name} must be a finite number >= 0, got {v}", option=name)

    @staticmethod
    def preset(quality: str = "default", **overrides) -> "LineOptions":
        """Options of a named quality preset with explicit overrides (None values ignored)."""
        if quality not in QUALITY_PRESETS:
            raise UsageError(f"unknown quality {quality!r} (known: {', '.join(QUALITY_PRESETS)})")
        names = {f.name for f in fields(LineOptions)}
        base = {k: v for k, v in QUALITY_PRESETS[quality].items() if k in names}
        given = {k: v for k, v in overrides.items() if v is not None}
        base.update(given)
        if "bisection_tol_px" in given and "bisect_changes" not in given:
            base["bisect_changes"] = True  # a tolerance asked for is a bisection asked for (draft has none)
        return LineOptions(**base)

    @property
    def layers(self) -> tuple[str, ...]:
        """The SVG layers this drawing has, hidden ones (under the visible lines) first: the kinds,
        then, with hidden levels, hidden-<kind> for each (writers.svg.svg_document)."""
        if self.occlusion is None:
            return self.kinds
        lo, hi = self.occlusion
        return (tuple("hidden-" + k for k in self.kinds) if hi >= 1 else ()) + (self.kinds if lo == 0 else ())

    def to_json(self) -> dict:
        """Every option (occlusion only when set: a visible-only run's digest stays as it was)."""
        return {f.name: (list(v) if isinstance(v := getattr(self, f.name), tuple) else v) for f in fields(self)
                if not (f.name == "occlusion" and self.occlusion is None)}
