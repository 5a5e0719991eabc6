"""Options of a line render, the named accuracy presets (`--quality`), and how an options
field is given on the command line (`Flag`, declared beside the field with `option`)."""

from __future__ import annotations

import dataclasses
import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

from strokekit.errors import UsageError, did_you_mean
from strokekit.kinds import KINDS, MAX_OCCLUSION

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
#: bisection does not (it locates every change to bisection_tol_px) and cost memory without
#: end; a change located finer than 1e-6 px is below what the float32 ray
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
class Flag:
    """How an options field is given on the command line; cli/flags.py makes the click option.
    A field without one is set from Python only.

    name: the flag ("--sample-spacing"); short: its one-letter form; help: what the help says of
    it. off: the flag that turns a bool field off ("--no-svg"); switch: a bool flag without a
    value, True when given (invert: the field gets False). choices: the words it takes, or {word:
    field value}. low, high: bounds (whole numbers when both are ints and the default is).
    text: "names" or "numbers", comma-separated (count: how many numbers). path: a file or
    folder name. show_default: the help shows the default, the field's or `shown` (for a field
    whose None means "not said"); else the help text says it. needs: the condition under which
    the flag means something (cli/commands/render_options.py NEEDS), a usage error otherwise.
    name_of_value: the parsed value's name, when not the flag's (see `dest`)."""

    name: str
    help: str
    short: str | None = None
    off: str | None = None
    switch: bool = False
    invert: bool = False
    choices: tuple | Mapping = ()
    low: float | None = None
    high: float | None = None
    text: str | None = None
    count: int | None = None
    path: bool = False
    show_default: bool = False
    shown: Any = None
    needs: str | None = None
    name_of_value: str | None = None

    @property
    def dest(self) -> str:
        """The name of the flag's parsed value: `name_of_value`, else the flag without dashes
        ("--no-shade": no_shade)."""
        return self.name_of_value or self.name.lstrip("-").replace("-", "_")


def option(default=dataclasses.MISSING, name: str = "", help: str = "", *, factory=dataclasses.MISSING, **flag):
    """A dataclass field given on the command line as `name` (see Flag for `flag`)."""
    return dataclasses.field(default=default, default_factory=factory,
                             metadata={"flag": Flag(name, help, **flag)})


def flag_of(f: dataclasses.Field) -> Flag | None:
    """The Flag of a dataclass field (None: set from Python only)."""
    return f.metadata.get("flag")


@dataclass(frozen=True)
class LineOptions:
    """What lines to find and how accurately. Pixel values are image-space pixels."""

    kinds: tuple[str, ...] = option(
        DEFAULT_KINDS, "--kinds", "Line kinds, comma-separated: silhouette, border, crease, material, nonmanifold, "
        "smooth_contour, suggestive, intersection.", text="names", show_default=True)
    crease_angle_deg: float = option(60.0, "--crease-angle", "Crease threshold in degrees [60].")
    # Edges shorter than this many px on screen get one visibility ray at their middle and are
    # drawn whole or not at all (a partly hidden one is off by up to its length): the draft
    # preset, for previews of fine meshes. Longer edges, and every edge at 0, are sampled and
    # split where their visibility changes.
    whole_edge_px: float = option(
        0.0, "--whole-edge", "Edges shorter than N px get one visibility ray and are drawn whole or not at all "
        "(draft: 12; default 0: every edge is split where its visibility changes) (overrides --quality).")
    sample_spacing_px: float = option(
        4.0, "--sample-spacing", f"Visibility samples every N px, at least {MIN_SAMPLE_SPACING_PX:g} (overrides "
        "--quality; a spacing whose samples would not fit in this machine's memory is refused before any work).")
    bisection_tol_px: float = option(
        0.01, "--bisection-tol",
        f"Visibility change located to N px, at least {MIN_BISECTION_TOL_PX:g} (overrides --quality).")
    # False: visibility changes are not bisected; each is placed in the middle of the bracket
    # between its two samples, within sample_spacing_px / 2 (bisection_tol_px is not used), and
    # every sample goes in one occlusion call (the draft preset; visibility.visible_runs).
    bisect_changes: bool = True
    # False: skip the plain-ray re-test of samples whose lifted ray is stopped near its start by
    # the front side of a triangle (Occluder.visible_rows; the draft preset).
    retest_front_hits: bool = True
    split_angle_deg: float = option(90.0, "--split-angle", "Split strokes at turns sharper than N degrees [90].")
    max_length_px: float = option(  # 0: no limit
        0.0, "--max-length", "Split lines longer than N px, at their points (a piece may pass N by one segment) "
        "[no limit]; brush paths are drawn over the lines, whole.")
    min_length_px: float = option(  # strokes shorter than this are dropped
        0.0, "--min-length", "Drop lines shorter than N px [0]; brush paths are drawn over the lines left.")
    simplify_tol_px: float = option(0.0, "--simplify", "Simplify strokes within N px (Douglas-Peucker) [0: off].")
    merge_overlaps: bool = option(  # drop zig-zag spurs that retrace a longer stroke
        True, "--drop-retraced", "Drop strokes that retrace a longer stroke of their kind within 0.5 px (zig-zag "
        "spurs, coincident copies) [default: drop; draft: keep].", off="--keep-retraced")
    overlap_tol_px: float = 0.5
    # Parts of contour strokes that run beside a longer stroke of their kind within this many px
    # are dropped (mesh contours come out shingled; strokeops.drop_doubled). 0 (the default) keeps
    # every visible contour edge: the lines are exact, and the brush paths (strokekit.paths) are
    # what shares one stroke among the shingles of a contour. Done per frame, so a frame draws the
    # same lines alone, in a sequence, with or without tracking.
    doubled_px: float = option(
        0.0, "--doubled", "Drop parts of contour lines running beside a longer one within N px (mesh-contour "
        "shingles) [0: every visible contour edge is kept; brush paths share one stroke among them; at most "
        f"{MAX_DOUBLED_PX:g}].")
    occlusion_offset: float = 1e-5  # ray offset as a fraction of the scene radius
    contours: str = option(  # or "smooth": interpolated contours replace mesh silhouettes
        "mesh", "--contours", "Mesh contours (silhouette edges) or smooth interpolated contours.",
        choices=("mesh", "smooth"), show_default=True)
    suggestive_kr_threshold: float = option(  # dimensionless (x 1/scene radius): skip faces with flatter radial curvature
        0.0, "--suggestive-kr-threshold",
        "Suggestive contours: skip faces whose radial curvature stays below this / scene radius [0].",
        needs="suggestive")
    suggestive_derivative_threshold: float = option(  # dimensionless (scaled by the scene radius): min R^2 D_w k_r tan(theta)
        50.0, "--suggestive-threshold", "Suggestive contours: minimum derivative of radial curvature, scale-free [50].",
        needs="suggestive")
    period_px: float = option(  # texture period for u
        30.0, "--period", f"Texture period P in px for the parametrization u [30; at most {MAX_PERIOD_PX:g}].")
    # Hidden lines: None draws the visible lines (level 0, the occlusion test alone); (lo, hi)
    # draws the pieces whose occlusion level (the number of surfaces in front of them) is in
    # lo..hi, each stroke with its level (lines.occlusion). hi = MAX_OCCLUSION: any depth. On the
    # command line: --hidden or --occlusion A-B.
    occlusion: tuple[int, int] | None = None

    def __post_init__(self):
        unknown = [k for k in self.kinds if k not in KINDS]
        if unknown:
            raise UsageError(f"unknown line kind(s) {', '.join(unknown)} ({did_you_mean(unknown[0], KINDS)}known: "
                             f"{', '.join(KINDS)})")
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
            if (len(rng) != 2 or any(isinstance(v, bool) or not isinstance(v, numbers.Integral) for v in rng)
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
