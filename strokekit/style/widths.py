"""A frame's strokes in their style (`apply_style` -> `StyledStrokes`): each stroke drawn by the
first line set that selects it (the others are not drawn), and a width in px at every point:
the set's width times its thickness modifiers, in order.

Where the width varies along a segment, points are added on it, so that the width drawn linearly
between points (the SVG's outline, the ribbons) is the modifiers' width: the width is found at
samples splitting each segment evenly, at most SAMPLE_PX apart, and of those the sample farthest
off the line between the segment's ends is kept as a point where it is off by more than
WIDTH_TOL_PX, then each side looked at again, until the width drawn is within WIDTH_TOL_PX of
the modifiers' at every sample. The points added lie on the stroke: its centreline does not
change.

The formulas (strokekit.style.linesets has each modifier's parameters), at a point at arc length
s of a stroke of length L, u its texture coordinate (periods of P px), id its stroke id:
- along: tip + (1 - tip) min(ease(s / head), ease((L - s) / tail)), ease(x) = x (2 - x) on
  [0, 1], head and tail scaled by min(1, L / (head + tail)), none at a joined end (joins);
- depth: near + (far - near) clip((z - z_near) / (z_far - z_near), 0, 1), z the view depth;
- curvature: flat + (curved - flat) clip(k radius, 0, 1), k = the angle between the chords
  P(s - a) -> P(s) and P(s) -> P(s + b) over (a + b) / 2, a = min(span, s), b = min(span, L - s),
  and 0 where a or b is below END_CHORD_PX (a chord that short has no direction to speak of);
- calligraphy: thin + (1 - thin) |sin(theta - angle)|, theta the direction of P(s + b) - P(s - a)
  with a = min(span, s), b = min(span, L - s), y up;
- noise: 1 + amplitude n(u P / wavelength), n a value noise (values in [-1, 1] at whole
  numbers, hashed from the seed, the id and frame // boil; smoothstep between);
and the width is at least MIN_WIDTH_PX."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from strokekit.errors import UsageError
from strokekit.model import KINDS, Strokes, kind_of, occlusion_of, row_norm
from strokekit.numba_cache import LazyKernels
from strokekit.sampling import locate
from strokekit.style.joins import stroke_joins
from strokekit.style.linesets import (
    JOIN_ANGLE_DEG,
    JOIN_PX,
    KIND_COLORS,
    MIN_WIDTH_PX,
    Along,
    Calligraphy,
    Curvature,
    Depth,
    LineSet,
    Noise,
    Style,
)

#: The curvature is 0 this close to a stroke's end (px): a shorter chord's direction is noise.
END_CHORD_PX = 0.5


@dataclass(frozen=True, eq=False)
class StyleContext:
    """What a frame's style needs of its scene, found where the scene is (run.frame.render_frame):
    depth_range (near, far) view depth of the visible surface (the depth modifier's default);
    for selection by object or material, the faces the frame's lines lie on (sorted), the object
    and material index of each, and the scene's object and material names."""

    depth_range: tuple[float, float] | None = None
    faces: np.ndarray | None = None
    face_object: np.ndarray | None = None
    face_material: np.ndarray | None = None
    objects: tuple[str, ...] = ()
    materials: tuple[str, ...] = ()


def style_context(style: Style, scene, camera, lines: Strokes, surface_depth=None) -> StyleContext | None:
    """The StyleContext of a frame (None when the style needs none). `scene`: the scene
    (vertices, faces, face_object, face_material, objects, materials); `lines`: the frame's lines
    (their faces and surface points); `surface_depth`: f(camera, pixels) -> depth of the first
    surface (raster.surface_depth_at), probed on a grid every DEPTH_GRID_PX for the visible depth
    range. The nearest visible depth is the scene's nearest vertex where that one is in the image
    and beyond the near plane (nothing can hide it: a triangle is nowhere nearer than its nearest
    vertex), else the nearest of the probes and line points; the farthest is the farthest probe
    or line point."""
    if not (style.needs_scene_depths or style.needs_faces):
        return None
    depth_range = None
    if style.needs_scene_depths:
        z = [camera.depth(lines.surface)] if len(lines.points) else []
        if surface_depth is not None:
            xs = np.arange(0.5 * DEPTH_GRID_PX, camera.width, DEPTH_GRID_PX)
            ys = np.arange(0.5 * DEPTH_GRID_PX, camera.height, DEPTH_GRID_PX)
            box = _screen_box(scene, camera)
            if box is not None:  # (a probe outside the scene's screen box hits nothing)
                xs = xs[(xs >= box[0]) & (xs <= box[2])]
                ys = ys[(ys >= box[1]) & (ys <= box[3])]
            gx, gy = np.meshgrid(xs, ys)
            if gx.size:
                z.append(surface_depth(camera, np.stack([gx.ravel(), gy.ravel()], 1)))
        near = _nearest_vertex_depth(scene, camera) if surface_depth is not None else None
        if near is not None:
            z.append(np.array([near]))
        z = np.concatenate(z) if z else np.zeros(0)
        z = z[np.isfinite(z) & (z > 0)]
        if near is not None:
            z = z[z >= near]  # (a probe's float32 depth a hair nearer than the vertex)
        depth_range = (float(z.min()), float(z.max())) if len(z) else None
    faces = fo = fm = None
    if style.needs_faces:
        faces = np.unique(lines.face[lines.face >= 0])
        fo = np.asarray(scene.face_object)[faces]
        fm = np.asarray(scene.face_material)[faces]
    return StyleContext(depth_range, faces, fo, fm, tuple(scene.objects), tuple(m.name for m in scene.materials))


def _nearest_vertex_depth(scene, camera) -> float | None:
    """The view depth of the scene's nearest vertex (of a face) when it is visible for sure: in
    the image and beyond the near plane (then every face lies beyond it too); else None."""
    if not len(scene.vertices) or not len(scene.faces):
        return None
    fwd = np.asarray(camera.basis[2], float)
    i = int(scene.face_vertex_ids[np.argmin(np.asarray(scene.face_vertices, float) @ fwd)])
    V = np.asarray(scene.vertices, float)
    z = float(camera.depth(V[i:i + 1])[0])
    if not z > camera.near_distance(scene.radius):
        return None
    xy, _ = camera.project(V[i:i + 1])
    x, y = float(xy[0, 0]), float(xy[0, 1])
    return z if 0.0 <= x <= camera.width and 0.0 <= y <= camera.height else None


def _screen_box(scene, camera) -> tuple[float, float, float, float] | None:
    """(x0, y0, x1, y1) px, grown by 1 px: a box holding the image of every scene point (that of
    the corners of its bounding box, all beyond the near plane); None where there is none."""
    lo, hi = scene.bounds
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    xy, z = camera.project(corners)
    if not camera.is_ortho and not (z > camera.near_distance(scene.radius)).all():
        return None
    if not np.isfinite(xy).all():
        return None
    return (float(xy[:, 0].min()) - 1.0, float(xy[:, 1].min()) - 1.0, float(xy[:, 0].max()) + 1.0,
            float(xy[:, 1].max()) + 1.0)


#: The visible depth range is probed every this many px (and at every line point).
DEPTH_GRID_PX = 16.0


@dataclass(frozen=True, eq=False)
class StyledStrokes:
    """Strokes as drawn: `strokes` those a line set selects (points added where the width needs
    them, module doc), width (N,) px at each point, lineset (S,) the index of each stroke's set in
    `sets`, kept (S0,) which of the strokes given were drawn, depth_range: what the depth
    modifiers took for the frame's visible depths (None: none did), free (S, 2): which stroke
    ends are free (not joined to the next piece of their line: there the along modifier's head
    and tail are; None without one)."""

    strokes: Strokes
    width: np.ndarray
    lineset: np.ndarray
    sets: tuple[LineSet, ...]
    style: Style
    kept: np.ndarray
    depth_range: tuple[float, float] | None = None
    free: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.strokes)

    @cached_property
    def constant(self) -> np.ndarray:
        """(S,) whether each stroke has one width all along (drawn as a centreline)."""
        o = self.strokes.offsets
        if len(self) == 0:
            return np.zeros(0, bool)
        w = self.width
        starts = o[:-1]
        hi = np.maximum.reduceat(w, starts) if len(w) else np.zeros(len(self))
        lo = np.minimum.reduceat(w, starts) if len(w) else np.zeros(len(self))
        return hi - lo <= 1e-9 * np.maximum(hi, 1.0)

    @cached_property
    def mean_width(self) -> np.ndarray:
        """(S,) each stroke's width averaged over its length (the mean of its points' on a stroke
        with no length)."""
        st, w = self.strokes, self.width
        o = st.offsets
        if len(self) == 0:
            return np.zeros(0)
        seg = st.segment_lengths  # (0 at each stroke's first point)
        area = np.zeros(len(w))
        area[1:] = 0.5 * (w[1:] + w[:-1]) * seg[1:]
        area[o[:-1]] = 0.0
        tot = np.add.reduceat(area, o[:-1])
        n = np.diff(o)
        mean_pts = np.add.reduceat(w, o[:-1]) / n
        L = st.lengths
        return np.where(L > 0, tot / np.where(L > 0, L, 1.0), mean_pts)

    def set_width(self, k: int) -> float:
        """The base width of set k (px)."""
        w = self.sets[k].width
        return self.style.width if w is None else w

    def color(self, k: int, kind: str) -> str:
        """The colour of set k's strokes of `kind` (a name in KINDS): the set's own, else the
        kind's (KIND_COLORS), as the default style draws it."""
        own = self.sets[k].color
        return own if own is not None else KIND_COLORS[kind]

    def dashes(self, k: int, hidden: bool) -> tuple[float, ...]:
        """The dash pattern (px; () solid) of set k's strokes, hidden or visible ones: its own, else
        the style's for hidden strokes (None: ISO 128 at the set's width), solid for visible ones."""
        d = self.sets[k].dashes
        if d is not None:
            return d
        if not hidden:
            return ()
        if self.style.dashes is not None:
            return self.style.dashes
        w = self.set_width(k)
        return (12.0 * w, 3.0 * w)


def apply_style(strokes: Strokes, layers: tuple[str, ...], style: Style | None = None,
                context: StyleContext | None = None) -> StyledStrokes:
    """The strokes of a frame drawn in `style` (default: Style()), whose SVG layers are `layers`
    (LineOptions.layers: the default style's sets); `context`: style_context's (needed to select
    by object or material; the depth modifier without depths otherwise takes the strokes' own
    depth range)."""
    style = style if style is not None else Style()
    sets = style.line_sets(layers)
    which = _assign(strokes, sets, context)
    kept = which >= 0
    if not kept.all():
        strokes = strokes.select(kept)
        which = which[kept]
    base = np.array([s.width if s.width is not None else style.width for s in sets], float)
    counts = np.diff(strokes.offsets)
    if not any(s.thickness for s in sets):
        width = np.repeat(base[which], counts) if len(which) else np.zeros(len(strokes.points))
        return StyledStrokes(strokes, width, which, sets, style, kept)
    depth_range = None
    if any(isinstance(m, Depth) and m.near_depth is None for s in sets for m in s.thickness):
        depth_range = context.depth_range if context is not None and context.depth_range is not None else \
            _own_depth_range(strokes)
    free = _free_ends(strokes, which, sets)
    strokes, width = _widths(strokes, which, sets, base, free, depth_range)
    return StyledStrokes(strokes, width, which, sets, style, kept, depth_range, free=free)


def _assign(strokes: Strokes, sets: tuple[LineSet, ...], context: StyleContext | None) -> np.ndarray:
    """(S,) the first set selecting each stroke, -1 where none does."""
    S = len(strokes)
    which = np.full(S, -1, np.int64)
    if S == 0:
        return which
    kind = kind_of(strokes.kind).astype(np.int64)
    level = occlusion_of(strokes.kind).astype(np.int64)
    obj = mat = None
    for k in range(len(sets) - 1, -1, -1):
        s = sets[k]
        sel = np.ones(S, bool)
        if s.kinds is not None:
            sel &= np.isin(kind, [KINDS.index(x) for x in s.kinds])
        if s.occlusion is not None:
            sel &= (level >= s.occlusion[0]) & (level <= s.occlusion[1])
        if s.objects is not None or s.materials is not None:
            if context is None or context.faces is None:
                raise UsageError(f"line set {s.name!r} selects by object or material: its strokes' faces need the "
                                 "scene (run.frame.render_frame finds them)")
            if obj is None:
                obj = _majority(strokes, context.faces, context.face_object)
                mat = _majority(strokes, context.faces, context.face_material)
            if s.objects is not None:
                sel &= np.isin(obj, [i for i, n in enumerate(context.objects) if n in s.objects])
            if s.materials is not None:
                sel &= np.isin(mat, [i for i, n in enumerate(context.materials) if n in s.materials])
        which[sel] = k
    return which


def _majority(strokes: Strokes, faces: np.ndarray, value: np.ndarray) -> np.ndarray:
    """(S,) the value (object or material index) most of each stroke's points' faces have
    (the lowest on a tie; -1 for a stroke with no known face)."""
    f = strokes.face
    at = np.searchsorted(faces, f)
    at = np.minimum(at, max(len(faces) - 1, 0))
    known = (f >= 0) & (len(faces) > 0)
    if len(faces):
        known &= faces[at] == f
    v = np.where(known, value[at] if len(faces) else -1, -1).astype(np.int64)
    n_v = int(value.max()) + 2 if len(value) else 1
    S = len(strokes)
    counts = np.bincount(strokes.stroke_of_point * n_v + (v + 1), minlength=S * n_v).reshape(S, n_v)
    counts[:, 0] = 0
    best = counts.argmax(axis=1) - 1
    return np.where(counts.max(axis=1) > 0, best, -1)


def _own_depth_range(strokes: Strokes) -> tuple[float, float] | None:
    if strokes.camera is None or not len(strokes.points):
        return None
    z = strokes.camera.depth(strokes.surface)
    z = z[np.isfinite(z)]
    return (float(z.min()), float(z.max())) if len(z) else None


def _free_ends(strokes: Strokes, which: np.ndarray, sets: tuple[LineSet, ...]) -> np.ndarray | None:
    """(S, 2) whether each stroke's start and end are free (not joined to the next piece of its
    line, strokekit.style.joins; strokes of different sets never join); None without an along
    modifier (which alone needs them)."""
    S = len(strokes)
    if not any(isinstance(m, Along) for s in sets for m in s.thickness):
        return None
    label = strokes.kind.astype(np.int64) + 128 * which
    joins = stroke_joins(np.asarray(strokes.points, float), strokes.stroke_of_point.astype(np.int64), S, label,
                         JOIN_PX, JOIN_ANGLE_DEG, arc=strokes.arc_length)
    return ~joins.joined


# --- points added where the width varies ------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class Sites:
    """Places on the strokes where widths are evaluated: stroke index st, arc length s, position
    P (M, 2), texture coordinate u, view depth z (nan: unknown), on `strokes`."""

    strokes: Strokes
    st: np.ndarray
    s: np.ndarray
    P: np.ndarray
    u: np.ndarray
    z: np.ndarray

    @staticmethod
    def of_points(strokes: Strokes) -> Sites:
        z = strokes.camera.depth(strokes.surface) if strokes.camera is not None and len(strokes.points) \
            else np.full(len(strokes.points), np.nan)
        return Sites(strokes, strokes.stroke_of_point, strokes.arc_length, strokes.points, strokes.u, z)

    def at(self, st: np.ndarray, s: np.ndarray) -> Sites:
        """Sites at arc lengths s of strokes st: linear on screen, the depth as the surface point
        between (sampling.surface_between: 1/z linear under perspective)."""
        i, j, a = locate(self.strokes, st, s)
        P = self.P[i] + a[:, None] * (self.P[j] - self.P[i])
        u = self.u[i] + a * (self.u[j] - self.u[i])
        zi, zj = self.z[i], self.z[j]
        cam = self.strokes.camera
        if cam is not None and not cam.is_ortho:
            with np.errstate(divide="ignore", invalid="ignore"):
                z = 1.0 / ((1 - a) / zi + a / zj)
        else:
            z = zi + a * (zj - zi)
        return Sites(self.strokes, st, s, P, u, z)

    def take(self, k: np.ndarray) -> Sites:
        return Sites(self.strokes, self.st[k], self.s[k], self.P[k], self.u[k], self.z[k])


#: The width drawn between two points is linear: of the samples along each segment, those are
#: kept as points that bring it within this of the modifiers' width at every sample (px).
WIDTH_TOL_PX = 0.02
#: The samples split each segment evenly, at most this far apart (px).
SAMPLE_PX = 0.5


def _widths(strokes: Strokes, which: np.ndarray, sets: tuple[LineSet, ...], base: np.ndarray, free: np.ndarray,
            depth_range) -> tuple[Strokes, np.ndarray]:
    """The strokes with the points their widths need (module doc) and the width at each
    (compiled: style.compiled.fit_widths)."""
    S = len(strokes)
    if S == 0:
        return strokes, np.zeros(0)
    K = style_kernels()
    ALONG, DEPTH, CURVATURE, CALLIGRAPHY, NOISE = K.ALONG, K.DEPTH, K.CURVATURE, K.CALLIGRAPHY, K.NOISE
    rows, starts, ends, keys = [], [0], [], []
    for s in sets:
        for m in s.thickness:
            if isinstance(m, Along):
                head, tail = along_lengths(m, strokes, np.arange(S), free)
                rows.append((ALONG, m.tip, len(ends) // 2, 0, 0, 0))
                ends += [head, tail]
            elif isinstance(m, Depth):
                zn, zf = (m.near_depth, m.far_depth) if m.near_depth is not None else \
                    depth_range if depth_range is not None else (0.0, 0.0)
                known = m.near_depth is not None or depth_range is not None
                rows.append((DEPTH, m.near, m.far, zn, zf, float(known)))
            elif isinstance(m, Curvature):
                rows.append((CURVATURE, m.flat, m.curved, m.radius, m.span, END_CHORD_PX))
            elif isinstance(m, Calligraphy):
                rows.append((CALLIGRAPHY, 0, m.thin, m.span, np.cos(np.radians(m.angle)), np.sin(np.radians(m.angle))))
            elif isinstance(m, Noise):
                key = int(strokes.frame) // m.boil if m.boil else 0
                rows.append((NOISE, m.amplitude, m.wavelength, len(keys), 0, 0))
                keys.append(noise_keys(strokes.ids, m.seed, key))
            else:
                raise TypeError(f"not a thickness modifier: {m!r}")
        starts.append(len(rows))
    mods = np.array(rows, float).reshape(-1, 6)
    ends_a = np.ascontiguousarray(np.stack(ends, 1) if ends else np.zeros((S, 0)))
    keys_a = np.ascontiguousarray(np.stack(keys, 1) if keys else np.zeros((S, 0), np.uint64))
    cam = strokes.camera
    N = len(strokes.points)
    z = cam.depth(strokes.surface) if cam is not None and N else np.full(N, np.nan)
    persp = cam is not None and not cam.is_ortho
    seg, frac, w = K.fit_widths(
        np.ascontiguousarray(strokes.points, float), np.ascontiguousarray(strokes.arc_length, float),
        np.ascontiguousarray(strokes.u, float), np.ascontiguousarray(z, float),
        np.ascontiguousarray(strokes.offsets, np.int64), np.ascontiguousarray(which, np.int64),
        np.ascontiguousarray(strokes.lengths, float), np.ascontiguousarray(base, float), mods,
        np.asarray(starts, np.int64), ends_a, keys_a, persp, float(strokes.period_px), MIN_WIDTH_PX,
        WIDTH_TOL_PX, SAMPLE_PX)
    if len(seg) == N:
        return strokes, w
    points, u, surface = K.spread(np.ascontiguousarray(strokes.points, float), np.ascontiguousarray(strokes.u, float),
                                  np.ascontiguousarray(strokes.surface, float), np.ascontiguousarray(z, float), seg,
                                  frac, persp)
    counts = np.bincount(strokes.stroke_of_point[seg], minlength=S)
    out = strokes.replace(points=points, surface=surface, face=strokes.face[seg], u=u,
                          offsets=np.concatenate([[0], np.cumsum(counts)]).astype(np.int64))
    return out, w


#: The widths' kernels (warmed with the outlines' before a styled run's frames: run.kernels.LINE_STYLE).
STYLE_KERNELS = LazyKernels("strokekit.style.compiled")
style_kernels = STYLE_KERNELS.kernels


def noise_keys(ids: np.ndarray, seed: int, key: int) -> np.ndarray:
    """(S,) uint64: value_noise's hash key of each stroke id, for this seed and boil key."""
    base = np.full(len(ids), seed & 0xFFFFFFFF, np.uint64) * _GOLDEN + np.uint64(key & 0xFFFFFFFF)
    return _mix(_mix(base) ^ np.asarray(ids, np.int64).view(np.uint64))


def _width_at(sites: Sites, which: np.ndarray, sets: tuple[LineSet, ...], base: np.ndarray, free: np.ndarray,
              depth_range) -> np.ndarray:
    """The width at each site: its set's width times the set's modifiers, at least MIN_WIDTH_PX."""
    set_of = which[sites.st]
    width = base[set_of]
    for k, s in enumerate(sets):
        if not s.thickness:
            continue
        on = np.flatnonzero(set_of == k) if len(sets) > 1 else np.arange(len(set_of))
        if not len(on):
            continue
        here = sites.take(on) if len(on) < len(set_of) else sites
        f = np.ones(len(on))
        for m in s.thickness:
            f = f * modifier_factor(m, here, free, depth_range)
        width[on] = width[on] * f
    return np.maximum(width, MIN_WIDTH_PX)


def along_lengths(m: Along, strokes: Strokes, st: np.ndarray, free: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(head, tail) px of strokes `st` for the along modifier `m` (end_lengths)."""
    scale = strokes.period_px if m.unit == "period" else 1.0
    return end_lengths(np.full(len(st), m.head * scale), np.full(len(st), m.tail * scale), free[st],
                       strokes.lengths[st])


def end_lengths(head: np.ndarray, tail: np.ndarray, free: np.ndarray, length: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """Head and tail lengths (px, per stroke) at free ends (free (S, 2)), none at joined ones,
    shrunk together on strokes shorter than both."""
    a, b = head * free[:, 0], tail * free[:, 1]
    k = np.minimum(1.0, length / np.where(a + b > 0, a + b, 1.0))
    return a * k, b * k


# --- the modifiers --------------------------------------------------------------------------------

def ease(x: np.ndarray) -> np.ndarray:
    """0 -> 0, 1 -> 1 with zero slope at 1: the brush reaches full width smoothly."""
    x = np.clip(x, 0.0, 1.0)
    return x * (2.0 - x)


def along_profile(s: np.ndarray, length: np.ndarray, head: np.ndarray, tail: np.ndarray, tip: float) -> np.ndarray:
    """The along modifier's factor at arc length s of strokes of `length`, with these head and
    tail lengths (px, per point; 0: none) and tip factor."""
    grow = np.where(head > 0, ease(s / np.maximum(head, 1e-300)), 1.0)
    fade = np.where(tail > 0, ease((length - s) / np.maximum(tail, 1e-300)), 1.0)
    return tip + (1 - tip) * np.minimum(grow, fade)


def modifier_factor(m, sites: Sites, free: np.ndarray, depth_range: tuple[float, float] | None) -> np.ndarray:
    """The factor of modifier `m` at the sites (module doc for the formulas); free (S, 2): which
    stroke ends are free (joins)."""
    strokes, st, s = sites.strokes, sites.st, sites.s
    L = strokes.lengths[st]
    if isinstance(m, Along):
        uniq, inv = np.unique(st, return_inverse=True)
        head, tail = along_lengths(m, strokes, uniq, free)
        return along_profile(s, L, head[inv], tail[inv], m.tip)
    if isinstance(m, Depth):
        if m.near_depth is not None:
            zn, zf = m.near_depth, m.far_depth
        elif depth_range is not None:
            zn, zf = depth_range
        else:
            return np.full(len(st), m.near)
        t = np.clip((sites.z - zn) / (zf - zn), 0.0, 1.0) if zf > zn else np.zeros(len(st))
        t = np.where(np.isfinite(t), t, 0.5)
        return m.near + (m.far - m.near) * t
    if isinstance(m, Curvature):
        a, b = np.minimum(m.span, s), np.minimum(m.span, L - s)
        c1 = sites.P - point_at(strokes, st, s - a)
        c2 = point_at(strokes, st, s + b) - sites.P
        ang = np.arctan2(np.abs(c1[:, 0] * c2[:, 1] - c1[:, 1] * c2[:, 0]), np.einsum("ij,ij->i", c1, c2))
        ok = (a >= END_CHORD_PX) & (b >= END_CHORD_PX) & (row_norm(c1) > 1e-12) & (row_norm(c2) > 1e-12)
        k = np.where(ok, ang / np.where(ok, 0.5 * (a + b), 1.0), 0.0)
        return m.flat + (m.curved - m.flat) * np.clip(k * m.radius, 0.0, 1.0)
    if isinstance(m, Calligraphy):
        a, b = np.minimum(m.span, s), np.minimum(m.span, L - s)
        d = point_at(strokes, st, s + b) - point_at(strokes, st, s - a)
        theta = np.arctan2(-d[:, 1], d[:, 0])
        f = m.thin + (1 - m.thin) * np.abs(np.sin(theta - np.radians(m.angle)))
        return np.where(row_norm(d) > 1e-12, f, 1.0)
    if isinstance(m, Noise):
        u = np.where(np.isfinite(sites.u), sites.u, s / strokes.period_px)
        key = int(strokes.frame) // m.boil if m.boil else 0
        return 1.0 + m.amplitude * value_noise(u * strokes.period_px / m.wavelength, strokes.ids[st], m.seed, key)
    raise TypeError(f"not a thickness modifier: {m!r}")


def point_at(strokes: Strokes, stroke: np.ndarray, s: np.ndarray) -> np.ndarray:
    """(M, 2) the points at arc length s of strokes `stroke` (held at the ends)."""
    i, j, a = locate(strokes, stroke, s)
    P = strokes.points
    return P[i] + a[:, None] * (P[j] - P[i])


_GOLDEN = np.uint64(0x9E3779B97F4A7C15)


def _mix(x: np.ndarray) -> np.ndarray:
    """SplitMix64's finalizer: a well-spread 64-bit hash of x (uint64 arrays, wrapping)."""
    x = (x ^ (x >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    x = (x ^ (x >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return x ^ (x >> np.uint64(31))


def _lattice(key: np.ndarray, i: np.ndarray) -> np.ndarray:
    """The noise's value in [-1, 1) at whole number i for each hash key."""
    h = _mix(key + i.astype(np.int64).view(np.uint64) * _GOLDEN)
    return (h >> np.uint64(11)).astype(np.float64) * (2.0 ** -52) - 1.0


def value_noise(x: np.ndarray, ids: np.ndarray, seed: int, key: int) -> np.ndarray:
    """A smooth noise of x in [-1, 1], its own for each stroke id, seed and key (the boil's):
    values hashed at the whole numbers, smoothstep between."""
    k = noise_keys(ids, seed, key)
    i0 = np.floor(x)
    t = x - i0
    t = t * t * (3.0 - 2.0 * t)
    v0 = _lattice(k, i0)
    v1 = _lattice(k, i0 + 1)
    return v0 + (v1 - v0) * t

