"""A drawing's style: line sets (`LineSet`), each selecting strokes by kind, occlusion level,
object or material, and giving them a colour, a base width, dashes and thickness modifiers
(`Along`, `Depth`, `Curvature`, `Calligraphy`, `Noise`), multiplied in order. `Style` holds the
sets and the defaults the command line's shortcuts set (--stroke-width, --dashes); without sets
it is one set per SVG layer in the kind's colour, the drawing strokekit always made.

The modifiers are factors of the width; strokekit.style.widths evaluates them per point."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field, fields

from strokekit.errors import UsageError
from strokekit.kinds import KINDS, MAX_OCCLUSION
from strokekit.options import option

#: Each line kind's colour (sRGB, the SVG's and the ribbons' tint) in the default style.
KIND_COLORS = {
    "silhouette": "#000000", "border": "#1f4e9c", "crease": "#b3261e", "material": "#2e7d32",
    "nonmanifold": "#8e24aa", "smooth_contour": "#000000", "suggestive": "#555555", "intersection": "#e65100",
}

#: The thinnest a modifier may make a line (px): an outline needs a positive radius.
MIN_WIDTH_PX = 0.01
#: The widest line (px): as wide as the largest image (camera.view.MAX_IMAGE_PX).
MAX_WIDTH_PX = 100_000.0
#: Two stroke ends this close (px) whose line runs on through them, turning at most
#: JOIN_ANGLE_DEG, are one line drawn as two strokes (strokekit.style.joins).
JOIN_PX = 2.5
JOIN_ANGLE_DEG = 45.0

_HEX = re.compile(r"#[0-9a-fA-F]{6}")
_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]*")


def check_colour(value: str, key: str = "color") -> str:
    """`value` if it is #rrggbb (lower-cased), else a UsageError about `key`."""
    if not (isinstance(value, str) and _HEX.fullmatch(value)):
        raise UsageError(f"{key} must be a colour #rrggbb, got {value!r}", option=key)
    return value.lower()


def _number(owner, name: str, low: float | None = None, high: float | None = None, *, above: bool = False):
    v = getattr(owner, name)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise UsageError(f"{name} must be a finite number, got {v!r}", option=name)
    if low is not None and (v <= low if above else v < low):
        raise UsageError(f"{name} must be {'>' if above else '>='} {low:g}, got {v:g}", option=name)
    if high is not None and v > high:
        raise UsageError(f"{name} must be at most {high:g}, got {v:g}", option=name)
    object.__setattr__(owner, name, float(v))


# --- thickness modifiers ---------------------------------------------------------------------------

@dataclass(frozen=True)
class Along:
    """Head, body and tail (seed 000, Fig 2.25): the width grows from `tip` x over the first
    `head` of the stroke (where the brush lands) and falls back to it over the last `tail`
    (where it lifts); only the body between stretches with the stroke. Lengths in px, or in
    texture periods (unit "period"); both shrink together on a stroke shorter than head + tail.
    Where a stroke meets the next piece of its line (strokekit.style.joins) there is no head or
    tail. The ramp is eased: x (2 - x) of the share of the head or tail covered."""

    by = "along"
    head: float = 0.0
    tail: float = 0.0
    unit: str = "px"
    tip: float = 0.25

    def __post_init__(self):
        _number(self, "head", 0.0, MAX_WIDTH_PX)
        _number(self, "tail", 0.0, MAX_WIDTH_PX)
        _number(self, "tip", 0.0, 1.0, above=True)
        if self.unit not in ("px", "period"):
            raise UsageError(f"unit must be 'px' or 'period', got {self.unit!r}", option="unit")


@dataclass(frozen=True)
class Depth:
    """Width by view depth: `near` x at `near_depth`, `far` x at `far_depth`, linear between
    and held beyond. Depths in scene units; None: the frame's nearest and farthest visible
    surface points (each frame's own)."""

    by = "depth"
    near: float = 1.0
    far: float = 1.0
    near_depth: float | None = None
    far_depth: float | None = None

    def __post_init__(self):
        _number(self, "near", 0.0)
        _number(self, "far", 0.0)
        for name in ("near_depth", "far_depth"):
            if getattr(self, name) is not None:
                _number(self, name, 0.0)
        if (self.near_depth is None) != (self.far_depth is None):
            raise UsageError("near_depth and far_depth go together (neither: the frame's visible depths)",
                             option="near_depth" if self.near_depth is None else "far_depth")
        if self.near_depth is not None and not self.near_depth < self.far_depth:
            raise UsageError(f"near_depth must be below far_depth, got {self.near_depth:g} and {self.far_depth:g}",
                             option="near_depth")


@dataclass(frozen=True)
class Curvature:
    """Width by screen curvature: `flat` x where the line runs straight, `curved` x where its
    radius of curvature is `radius` px or less, linear in the curvature between. The curvature
    at a point is the turn between the chords to the points `span` px before and after it,
    over span (less near the stroke's ends, 0 within half a pixel of them)."""

    by = "curvature"
    flat: float = 1.0
    curved: float = 0.5
    radius: float = 10.0
    span: float = 3.0

    def __post_init__(self):
        _number(self, "flat", 0.0)
        _number(self, "curved", 0.0)
        _number(self, "radius", 0.0, MAX_WIDTH_PX, above=True)
        _number(self, "span", 0.0, MAX_WIDTH_PX, above=True)


@dataclass(frozen=True)
class Calligraphy:
    """A broad nib held at `angle` degrees (counter-clockwise from the image's x axis, y up):
    the line is `thin` x where it runs along the nib, full width across it: thin + (1 - thin)
    |sin(direction - angle)|. The direction at a point is the chord between the points
    `span` px before and after it."""

    by = "calligraphy"
    angle: float = 45.0
    thin: float = 0.3
    span: float = 2.0

    def __post_init__(self):
        _number(self, "angle", -360.0, 360.0)
        _number(self, "thin", 0.0, 1.0)
        _number(self, "span", 0.0, MAX_WIDTH_PX, above=True)


@dataclass(frozen=True)
class Noise:
    """A variation along the stroke: 1 + amplitude n, n in [-1, 1] a smooth value noise of the
    stroke's texture coordinate (u x period / wavelength) and its id, so it stays on the surface
    while the stroke persists. boil: a new noise every N frames (a deliberate boil, "on twos":
    2); 0: never. seed: another noise."""

    by = "noise"
    amplitude: float = 0.3
    wavelength: float = 30.0
    seed: int = 0
    boil: int = 0

    def __post_init__(self):
        _number(self, "amplitude", 0.0, 1.0)
        _number(self, "wavelength", 0.0, MAX_WIDTH_PX, above=True)
        for name in ("seed", "boil"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 0 or v >= 2**32:
                raise UsageError(f"{name} must be a whole number in 0..2^32-1, got {v!r}", option=name)


MODIFIERS = {m.by: m for m in (Along, Depth, Curvature, Calligraphy, Noise)}
Modifier = Along | Depth | Curvature | Calligraphy | Noise


def modifier_json(m: Modifier) -> dict:
    """{"by": name, parameter: value, ...}: the frame JSON's account of a modifier."""
    return {"by": m.by, **{f.name: getattr(m, f.name) for f in fields(m)}}


# --- line sets -------------------------------------------------------------------------------------

#: visibility = "visible" / "hidden" / "any": the occlusion levels selected.
VISIBILITY = {"visible": (0, 0), "hidden": (1, MAX_OCCLUSION), "any": None}


@dataclass(frozen=True)
class LineSet:
    """Strokes selected and how they are drawn. Selection (all that are given must hold): kinds
    (None: every kind), occlusion (lo, hi) levels (None: every level; 0 is visible), objects and
    materials by name (None: any; the object or material most of the stroke's points lie on).
    color: #rrggbb, None: the kind's (KIND_COLORS). width: px, None: the style's. dashes: on,
    off, ... px along the stroke, () solid, None: ISO 128's for hidden strokes, solid for visible
    ones. thickness: modifiers, multiplied in order."""

    name: str
    kinds: tuple[str, ...] | None = None
    occlusion: tuple[int, int] | None = None
    objects: tuple[str, ...] | None = None
    materials: tuple[str, ...] | None = None
    color: str | None = None
    width: float | None = None
    dashes: tuple[float, ...] | None = None
    thickness: tuple[Modifier, ...] = ()

    def __post_init__(self):
        if not (isinstance(self.name, str) and _NAME.fullmatch(self.name)):
            raise UsageError(f"name must be letters, digits, '_', '-' or '.', got {self.name!r}", option="name")
        if self.kinds is not None:
            unknown = [k for k in self.kinds if k not in KINDS]
            if unknown:
                raise UsageError(f"kinds: unknown line kind(s) {', '.join(map(repr, unknown))} (known: "
                                 f"{', '.join(KINDS)})", option="kinds")
            if not self.kinds:
                raise UsageError("kinds is empty: the line set selects nothing", option="kinds")
            object.__setattr__(self, "kinds", tuple(k for k in KINDS if k in set(self.kinds)))
        for key in ("objects", "materials"):
            v = getattr(self, key)
            if v is not None and not v:
                raise UsageError(f"{key} is empty: the line set selects nothing", option=key)
        if self.occlusion is not None:
            lo, hi = self.occlusion
            if not 0 <= lo <= hi <= MAX_OCCLUSION:
                raise UsageError(f"occlusion must be levels lo <= hi within 0-{MAX_OCCLUSION}, got "
                                 f"{list(self.occlusion)}", option="occlusion")
        if self.color is not None:
            object.__setattr__(self, "color", check_colour(self.color))
        if self.width is not None:
            _number(self, "width", 0.0, MAX_WIDTH_PX, above=True)
        if self.dashes is not None:
            object.__setattr__(self, "dashes", check_dashes(self.dashes))

    def selects_kind(self, kind: str, level: int) -> bool:
        """Whether strokes of `kind` at occlusion `level` can be in the set (the object and
        material aside)."""
        return ((self.kinds is None or kind in self.kinds)
                and (self.occlusion is None or self.occlusion[0] <= level <= self.occlusion[1]))

    def to_json(self, style: Style) -> dict:
        """The frame JSON's account of the set: what it selects, its colour, width and modifiers."""
        out: dict = {"name": self.name}
        for key in ("kinds", "occlusion", "objects", "materials"):
            if getattr(self, key) is not None:
                out[key] = list(getattr(self, key))
        out["color"] = self.color
        out["width"] = self.width if self.width is not None else style.width
        if self.dashes is not None:
            out["dashes"] = list(self.dashes)
        if self.thickness:
            out["thickness"] = [modifier_json(m) for m in self.thickness]
        return out


def check_dashes(dashes) -> tuple[float, ...]:
    """A dash pattern as floats: pairs of lengths >= 0 px, not all 0, or () for solid."""
    d = tuple(dashes)
    if d and (len(d) % 2 or any(isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x)
                                or x < 0 for x in d) or not sum(d) > 0):
        raise UsageError(f"dashes must be pairs of dash and gap lengths in px (numbers >= 0, not all 0), got "
                         f"{list(d)}", option="dashes")
    return tuple(float(x) for x in d)


@dataclass(frozen=True)
class Style:
    """The drawing's line sets and their defaults. width: of every set without its own
    (--stroke-width); dashes: the hidden strokes' of sets without their own (None: ISO 128's,
    12 and 3 widths; --dashes); sets: in order, a stroke drawn by the first that selects it and
    not drawn when none does; () is the default drawing: one set per SVG layer (kind, and
    hidden-<kind>), each in its kind's colour. source: the style file (for messages)."""

    width: float = option(1.5, "--stroke-width", "Line width in px (of every line set of a --style file without "
                          "its own width).", show_default=True, low=MIN_WIDTH_PX, high=MAX_WIDTH_PX)
    dashes: tuple[float, ...] | None = None
    sets: tuple[LineSet, ...] = ()
    source: str | None = field(default=None, compare=False)

    def __post_init__(self):
        _number(self, "width", 0.0, MAX_WIDTH_PX, above=True)
        if self.dashes is not None:
            object.__setattr__(self, "dashes", check_dashes(self.dashes))
        names = [s.name for s in self.sets]
        twice = sorted({n for n in names if names.count(n) > 1})
        if twice:
            raise UsageError(f"line set name(s) {', '.join(twice)} given twice", option="name")

    def line_sets(self, layers: tuple[str, ...]) -> tuple[LineSet, ...]:
        """The sets that draw a frame with these SVG layers (LineOptions.layers): the style's,
        or one per layer: the kind's visible strokes, or its hidden ones (hidden-<kind>), the
        frame's layers first, then every other (a stroke of any kind is drawn)."""
        if self.sets:
            return self.sets
        out = []
        every = tuple(layers) + tuple(x for k in KINDS for x in ("hidden-" + k, k) if x not in layers)
        for layer in every:
            kind = layer.removeprefix("hidden-")
            hidden = layer != kind
            out.append(LineSet(layer, kinds=(kind,), occlusion=(1, MAX_OCCLUSION) if hidden else (0, 0),
                               color=KIND_COLORS[kind], dashes=self.dashes if hidden else None))
        return tuple(out)

    def to_json(self) -> dict:
        """The style as plain values (the run manifest's digest: the file it came from aside)."""
        return {"width": self.width, "dashes": None if self.dashes is None else list(self.dashes),
                "sets": [s.to_json(self) for s in self.sets]}

    @property
    def is_default(self) -> bool:
        """No line sets: the drawing's layers, each in its kind's colour (SVG layers as always)."""
        return not self.sets

    @property
    def has_thickness(self) -> bool:
        """Whether a set has thickness modifiers (its widths are evaluated by the style kernels)."""
        return any(s.thickness for s in self.sets)

    @property
    def needs_scene_depths(self) -> bool:
        """Whether a depth modifier takes the frame's visible depth range."""
        return any(isinstance(m, Depth) and m.near_depth is None for s in self.sets for m in s.thickness)

    @property
    def needs_faces(self) -> bool:
        """Whether a set selects by object or material (the strokes' faces are then looked up)."""
        return any(s.objects is not None or s.materials is not None for s in self.sets)

    def check_draws(self, kinds: tuple[str, ...], occlusion: tuple[int, int] | None) -> None:
        """UsageError (option: the set's index) for a set that selects no stroke a run drawing
        `kinds` at `occlusion` levels (LineOptions) can make."""
        lo, hi = occlusion if occlusion is not None else (0, 0)
        for i, s in enumerate(self.sets):
            kinds_ok = s.kinds is None or any(k in s.kinds for k in kinds)
            levels_ok = s.occlusion is None or (s.occlusion[0] <= hi and lo <= s.occlusion[1])
            if not (kinds_ok and levels_ok):
                what = f"kinds {', '.join(s.kinds)}" if s.kinds is not None else "every kind"
                levels = (f"occlusion {s.occlusion[0]}-{s.occlusion[1]}" if s.occlusion is not None else "any level")
                drawn = f"{', '.join(kinds)} at " + (f"occlusion {lo}-{hi}" if occlusion is not None else
                                                     "occlusion 0 (visible; --hidden draws the others)")
                raise UsageError(f"line set {s.name!r} selects nothing the run draws: it takes {what} at {levels}, "
                                 f"the run draws {drawn} (--kinds, --hidden, --occlusion)",
                                 option=f"lineset.{i}.{'occlusion' if kinds_ok else 'kinds'}")
