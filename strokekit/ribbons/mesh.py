"""Textured ribbons of strokes (seed 000 section 2.1.1 and its annex): one quad per segment, a join
triangle pair on the outer side of every turn, the overlap on the inner side removed, u along the
stroke and v = 0 / 0.5 / 1 across.

The outline is built in pixels, so the ribbon has its requested width on screen whatever the
placement; it is then either lifted into the world (default) or kept flat in image space.

Geometry of one segment k (points P_j -> P_j+1, unit direction t, normal n = t rotated +90
degrees in pixel coordinates, x right and y down: the stroke's right-hand side on screen) is six
vertices, two per row across the stroke, drawn here for a stroke running left to right::

    S_L ---- E_L      v = 0   (P - n d, the left-hand side)
     |  \\     |
    S_C ---- E_C      v = 0.5 (the stroke's own points)
     |  \\     |
    S_R ---- E_R      v = 1   (P + n d, the right-hand side)

so a brush image is laid along the stroke as it is drawn: its top row (v = 0) on the left of the
direction of travel, above a stroke that runs left to right.

and four triangles. At a turn between segments k and k+1 (turn angle theta):

- inner side: the two inner vertices meet at the intersection I of the two inner offset lines
  (distance d / cos(theta/2) along the bisector), so the quads do not overlap and a translucent
  brush never shows doubled opacity. When I would fall back further than a segment can take
  (the retreats from both ends of a segment on the same side must fit in it: very short
  segments, hairpin turns) the quads keep their own inner vertices instead: a small overlap,
  but never a flipped triangle;
- outer side: two join triangles (C, A, M), (C, M, B) fill the gap between the end edge of quad
  k and the start edge of quad k+1; M is the miter point while the miter ratio 1/cos(theta/2)
  stays under `miter_limit`, else the middle of A and B (a bevel, split in two).

Texture u: the brush texture is a strip [head | body | tail] (texture u in [0, tex_head],
[tex_head, 1 - tex_tail], [1 - tex_tail, 1]). The first `head_px` pixels of a stroke show the
head, the last `tail_px` the tail, both at a fixed size (scaled down together on strokes shorter
than head + tail); in between the body repeats once per unit of the stroke's own parametrization
`strokes.u` (in texture periods, coherent from frame to frame when tracking made it so). Vertices
are inserted where a region starts and wherever u crosses an integer, and every segment owns its
vertices, so the texture seams are exact and no texel is stretched across a repeat.

Joins between strokes (strokekit.style.joins `stroke_joins`): where a stroke's end meets the end of another stroke of its
kind (or its own other end: a loop) within `join_px`, the line running on through it (tangents
within `join_angle_deg`), the two are one line drawn as two strokes (a brush path cut where its id
changes, a loop's seam). There the ribbons neither taper nor show the brush's head or tail (whose
alpha fades to its tip): the body runs to the joint, both ends move to the middle of the two and
share one end edge across the line's bisecting direction, so the two ribbons meet with neither a
pinch nor a hole, nor an overlap. The ends left are free ends: tapered, head and tail, and run on
past the stroke's end by `cap` times the width (half of it by default, as far as the SVG's round
cap), so that the faint tip of the taper lies beyond the line's end, not on it.

Second texture set (TEXCOORD_1 in the glTF): (level, level_weight) of the stroke's self-similar
octave, constant along the stroke (`RibbonMesh.level_uv`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from strokekit.camera.view import Camera
from strokekit.errors import UsageError
from strokekit.model import Strokes
from strokekit.ribbons.options import RibbonOptions
from strokekit.style.joins import arc_lengths, stroke_bounds, stroke_joins
from strokekit.style.widths import along_profile, end_lengths


@dataclass(frozen=True, eq=False)
class RibbonMesh:
    """Triangles of the ribbons of one frame.

    positions (V, 3) float64: world units (space "world") or pixels (x, H - y, 0) (space "image").
    pixels (V, 2) float64: the same vertices in image pixels (x right, y down).
    uv (V, 2) float32-ready: brush texture coordinates (u along, v = 0 / 0.5 / 1 across).
    level_uv (V, 2): (level, level_weight) of the vertex's stroke (TEXCOORD_1).
    arc (V,): arc length in px from the stroke start; u_raw (V,): strokes.u at the vertex.
    indices (T, 3) int64: counter-clockwise as seen from the camera.
    vertex_offsets, triangle_offsets (S+1,): stroke s owns vertices [vo[s], vo[s+1]) and
    triangles [to[s], to[s+1]) (empty for strokes with no length).
    kind, ids, level, level_weight (S,): copied from the strokes."""

    positions: np.ndarray
    pixels: np.ndarray
    uv: np.ndarray
    level_uv: np.ndarray
    arc: np.ndarray
    u_raw: np.ndarray
    indices: np.ndarray
    vertex_offsets: np.ndarray
    triangle_offsets: np.ndarray
    kind: np.ndarray
    ids: np.ndarray
    level: np.ndarray
    level_weight: np.ndarray
    space: str = "world"

    def __len__(self) -> int:
        return len(self.vertex_offsets) - 1

    @property
    def stroke_of_vertex(self) -> np.ndarray:
        return np.repeat(np.arange(len(self)), np.diff(self.vertex_offsets))

    @property
    def stroke_of_triangle(self) -> np.ndarray:
        return np.repeat(np.arange(len(self)), np.diff(self.triangle_offsets))


# --- polyline preparation -------------------------------------------------------------------------

_EPS_PX = 1e-6  # segments shorter than this (pixels) are zero-length: dropped before anything else


def _drop_short(arr: dict, sid: np.ndarray) -> tuple[dict, np.ndarray]:
    """Drop every point closer than _EPS_PX to the previous point of its stroke, and non-finite points."""
    p = arr["p"]
    keep = np.all(np.isfinite(p), axis=1)
    if len(p) > 1:
        step = np.linalg.norm(np.diff(p, axis=0), axis=1)
        same = sid[1:] == sid[:-1]
        keep[1:] &= ~(same & ~(step > _EPS_PX))
    return {k: v[keep] for k, v in arr.items()}, sid[keep]


def _insert(arr: dict, sid: np.ndarray, j: np.ndarray, t: np.ndarray) -> tuple[dict, np.ndarray]:
    """Insert points inside segments (j -> j+1) at fractions t in (0, 1), all arrays interpolated
    linearly; order along the strokes is kept by sorting on the key j + t."""
    if len(j) == 0:
        return arr, sid
    key = np.concatenate([np.arange(len(sid), dtype=float), j + t])
    order = np.argsort(key, kind="stable")
    out = {}
    for name, v in arr.items():
        tt = t.reshape((-1,) + (1,) * (v.ndim - 1))
        new = v[j] * (1.0 - tt) + v[j + 1] * tt
        out[name] = np.concatenate([v, new])[order]
    return out, np.concatenate([sid, sid[j]])[order]


def _cuts_at(arc: np.ndarray, sid: np.ndarray, starts: np.ndarray, ends: np.ndarray,
             cut_stroke: np.ndarray, cut_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Segment start index j and fraction t of the points at arc length cut_s on strokes cut_stroke.
    starts/ends (S,) first and one-past-last point of each stroke. Cuts on existing points are dropped."""
    ok = (ends[cut_stroke] - starts[cut_stroke]) >= 2
    cut_stroke, cut_s = cut_stroke[ok], cut_s[ok]
    if len(cut_s) == 0:
        return np.zeros(0, np.int64), np.zeros(0)
    # a global coordinate increasing along all strokes in order: arc + a stroke base far apart
    span = arc.max(initial=0.0) + 1.0
    g = arc + sid * span
    gc = cut_s + cut_stroke * span
    j = np.searchsorted(g, gc, side="right") - 1
    j = np.clip(j, starts[cut_stroke], ends[cut_stroke] - 2)
    seg = arc[j + 1] - arc[j]
    t = (cut_s - arc[j]) / np.where(seg > 0, seg, 1.0)
    inside = (t > 1e-9) & (t < 1 - 1e-9)
    return j[inside], t[inside]


# --- the ribbon -----------------------------------------------------------------------------------

def _capped(p: np.ndarray, starts: np.ndarray, ends: np.ndarray, free: np.ndarray, reach) -> np.ndarray:
    """The points p (N, 2) with the free ends (free (S, 2): start, end) of strokes (points
    starts..ends) of two points or more moved outward along their end segment by `reach` px (a
    number, or (N,) per point)."""
    two = np.flatnonzero(ends - starts >= 2)
    reach = np.broadcast_to(np.asarray(reach, float), (len(p),))
    out = p.copy()
    for w, at, nb in ((0, starts, starts + 1), (1, ends - 1, ends - 2)):
        k = two[free[two, w]]
        d = p[at[k]] - p[nb[k]]
        d /= np.maximum(np.linalg.norm(d, axis=1), 1e-12)[:, None]
        out[at[k]] = p[at[k]] + d * reach[at[k]][:, None]
    return out


def build_ribbons(strokes: Strokes, camera: Camera | None = None,
                  options: RibbonOptions | None = None, surface_depth=None, widths: np.ndarray | None = None
                  ) -> RibbonMesh:
    """Ribbon triangles for every stroke of one frame (vectorized over all strokes).

    strokes: points (N, 2) px, surface (N, 3) world, u (N,) texture periods. camera: the frame's
    camera (default strokes.camera); needed for space "world" and for the image height.
    widths: (N,) the ribbon's width at each point (px; strokekit.style's, linear between points:
    the options' width and taper are then not used, and the texture's head and tail scale with
    each stroke's mean width); None: options.width_px, tapered at the free ends by the along
    profile (strokekit.style.widths.along_profile) over taper_head_px and taper_tail_px.
    surface_depth (space "world"): f(camera, pixels (V, 2)) -> (V,) view depth of the scene's first
    surface at those pixels (inf: none), e.g. raster.surface_depth_at(occluder). The vertices of a
    stroke point lie at the nearest of its depth and the surface's at any of them: beside a
    silhouette the surface bulges toward the camera within the ribbon's half width (a sphere's, by
    ~2% of its depth at 1.5 px), and a ribbon at the stroke's depth showed only its outer half
    over the mesh.
    Zero-length segments are dropped; strokes with no length get empty ranges."""
    o = options or RibbonOptions()
    cam = camera if camera is not None else strokes.camera
    if cam is None:
        raise UsageError("ribbons need the frame's camera")
    n_s = len(strokes)
    sid = strokes.stroke_of_point.astype(np.int64)
    u = np.asarray(strokes.u, float)
    if not np.all(np.isfinite(u)):  # fall back on arc length for unknown parameters
        u = np.where(np.isfinite(u), u, strokes.arc_length / strokes.period_px)
    arr = {"p": np.asarray(strokes.points, float), "u": u}
    if widths is not None:
        arr["w"] = np.asarray(widths, float)
    if o.space == "world":
        z = cam.depth(strokes.surface) if len(strokes.points) else np.zeros(0)
        dist = float(np.linalg.norm(np.subtract(cam.target, cam.eye)))
        bad = ~np.isfinite(z) | (~cam.is_ortho & (z <= 1e-9 * dist))
        z = np.where(bad, dist, z)  # unknown surface point: place it at the target distance
        # points inserted inside a segment interpolate linearly in the image: 1/z is what is
        # linear there under perspective (z itself under orthographic)
        arr["z"] = z if cam.is_ortho else 1.0 / z
    arr, sid = _drop_short(arr, sid)
    # Joined ends move to their joint (module doc).
    joins = stroke_joins(arr["p"], sid, n_s, strokes.kind, o.join_px, o.join_angle_deg)
    if joins.joined.any():
        starts, ends = stroke_bounds(sid, n_s)
        p = arr["p"].copy()
        for w, at in ((0, starts), (1, ends - 1)):
            js = np.flatnonzero(joins.joined[:, w])
            p[at[js]] = joins.point[js, w]
        arr["p"] = p
        arr, sid = _drop_short(arr, sid)
    free = ~joins.joined
    starts, ends = stroke_bounds(sid, n_s)
    if o.cap > 0:  # (ends moved outward: no segment gets shorter, the bounds hold)
        arr["p"] = _capped(arr["p"], starts, ends, free, o.cap * (arr["w"] if widths is not None else o.width_px))

    # --- per-stroke lengths, head/tail and taper regions
    s = arc_lengths(arr["p"], sid)
    has = ends - starts >= 2
    L = np.where(has, s[np.maximum(ends - 1, 0)] if len(s) else 0.0, 0.0)

    # the texture's head and tail, and the taper: end regions at the free ends (none at a joined
    # one), shrunk together on strokes shorter than both
    if widths is None:
        head, tail = end_lengths(o.head_px, o.tail_px, free, L)
        thead, ttail = end_lengths(o.taper_head_px, o.taper_tail_px, free, L)
    else:  # texels kept square: the texture's ends scale with the stroke's width
        n_pt = np.bincount(sid, minlength=n_s)
        scale = np.bincount(sid, arr["w"], minlength=n_s) / np.maximum(n_pt, 1) / o.width_px
        head, tail = end_lengths(o.head_px * scale, o.tail_px * scale, free, L)
        thead = ttail = np.zeros(n_s)

    # cuts: region boundaries and the taper profile samples
    steps = int(o.taper_steps)
    frac = np.arange(1, steps + 1) / steps
    cut_cols = [head, L - tail] + [thead * f for f in frac] + [L - ttail * f for f in frac]
    cut_s = np.stack(cut_cols, axis=1).ravel() if n_s else np.zeros(0)
    cut_stroke = np.repeat(np.arange(n_s), len(cut_cols))
    j, t = _cuts_at(s, sid, starts, ends, cut_stroke, cut_s)
    arr["s"] = s
    arr, sid = _insert(arr, sid, j, t)

    # cuts where u crosses an integer inside the body: each body segment shows one period piece
    s = arr["s"]
    u = arr["u"]
    same = sid[1:] == sid[:-1]
    seg_j = np.nonzero(same)[0]
    sm = 0.5 * (s[seg_j] + s[seg_j + 1])
    body = (sm > head[sid[seg_j]]) & (sm < L[sid[seg_j]] - tail[sid[seg_j]])
    bj = seg_j[body]
    u0, u1 = u[bj], u[bj + 1]
    lo, hi = np.minimum(u0, u1), np.maximum(u0, u1)
    first = np.floor(lo) + 1.0
    count = np.maximum(0, (np.ceil(hi) - first)).astype(np.int64)
    # a segment spanning hundreds of periods shows sub-pixel marks anyway: no cuts (no blow-up)
    count[count > 256] = 0
    if count.sum():
        rep = np.repeat(np.arange(len(bj)), count)
        within = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
        # integers in increasing order; when u decreases along the segment, t decreases: sort keys handle it
        k_int = first[rep] + within
        du = u1[rep] - u0[rep]
        t = (k_int - u0[rep]) / du
        ok = (t > 1e-9) & (t < 1 - 1e-9)
        arr, sid = _insert(arr, sid, bj[rep][ok], t[ok])
    arr, sid = _drop_short(arr, sid)
    p, s, u = arr["p"], arr["s"], arr["u"]

    # --- segments
    seg_j = np.nonzero(sid[1:] == sid[:-1])[0]
    K = len(seg_j)
    sk = sid[seg_j]
    d_vec = p[seg_j + 1] - p[seg_j]
    seg_len = np.linalg.norm(d_vec, axis=1)
    tan = d_vec / seg_len[:, None]
    nrm = np.stack([-tan[:, 1], tan[:, 0]], axis=1)

    # half width at every point: the widths given, or tapered at both ends
    if widths is None:
        half = 0.5 * o.width_px * along_profile(s, L[sid], thead[sid], ttail[sid], o.taper_min)
    else:
        half = 0.5 * arr["w"]

    # seven vertex slots per segment: rows L, C, R at the start, then at the end, then the outer
    # join vertex M of the turn at its end (unused on the last segment and on straight joins)
    P0, P1 = p[seg_j], p[seg_j + 1]
    h0, h1 = half[seg_j][:, None], half[seg_j + 1][:, None]
    vpix = np.empty((K, 7, 2))
    vpix[:, 0], vpix[:, 1], vpix[:, 2] = P0 + nrm * h0, P0, P0 - nrm * h0
    vpix[:, 3], vpix[:, 4], vpix[:, 5] = P1 + nrm * h1, P1, P1 - nrm * h1
    vpix[:, 6] = P1

    # texture u per segment end: head, body (one period piece), tail
    th, tt = o.tex_head, o.tex_tail
    sa, sb = s[seg_j], s[seg_j + 1]
    smid = 0.5 * (sa + sb)
    hk, tk, Lk = head[sk], tail[sk], L[sk]
    in_head = smid < hk
    in_tail = ~in_head & (smid > Lk - tk)
    per = np.floor(0.5 * (u[seg_j] + u[seg_j + 1]))
    bw = 1.0 - th - tt

    def tex_u(sv, uv):
        body_u = th + bw * np.clip(uv - per, 0.0, 1.0)
        head_u = th * np.clip(sv / np.maximum(hk, 1e-300), 0.0, 1.0)
        tail_u = (1.0 - tt) + tt * np.clip((sv - (Lk - tk)) / np.maximum(tk, 1e-300), 0.0, 1.0)
        return np.where(in_head, head_u, np.where(in_tail, tail_u, body_u))

    ua, ub = tex_u(sa, u[seg_j]), tex_u(sb, u[seg_j + 1])
    vuv = np.empty((K, 7, 2))
    vuv[:, :3, 0] = ua[:, None]
    vuv[:, 3:, 0] = ub[:, None]
    vuv[:, :, 1] = np.array([1.0, 0.5, 0.0, 1.0, 0.5, 0.0, 0.5])  # vertices 0, 3 at +n: the right side
    pt = np.empty((K, 7), np.int64)  # the stroke point each vertex hangs on (its depth, arc length, u)
    pt[:, :3] = seg_j[:, None]
    pt[:, 3:] = (seg_j + 1)[:, None]

    # joined ends: the end edge both ribbons share (StrokeJoins.normal), at full width
    k_first = np.searchsorted(sk, np.arange(n_s), side="left")
    k_last = np.searchsorted(sk, np.arange(n_s), side="right") - 1
    shared = []
    for w, ks, (plus, at, minus), nxt in ((0, k_first, (0, 1, 2), 0), (1, k_last, (3, 4, 5), 1)):
        js = np.flatnonzero(joins.joined[:, w] & (k_last >= k_first))
        k = ks[js]
        h = half[seg_j[k] + nxt][:, None]
        vpix[k, plus] = vpix[k, at] + joins.normal[js, w] * h
        vpix[k, minus] = vpix[k, at] - joins.normal[js, w] * h
        shared.append(k)

    tris = np.full((K, 6, 3), -1, np.int64)  # four quad triangles, then two join triangles
    base = 7 * np.arange(K)[:, None, None]
    tris[:, :4] = base + np.array([[1, 4, 3], [1, 3, 0], [2, 5, 4], [2, 4, 1]])[None]

    # --- joins between consecutive segments k, k+1 of one stroke
    jk = np.nonzero(seg_j[1:] == seg_j[:-1] + 1)[0]
    t1, t2 = tan[jk], tan[jk + 1]
    cross = t1[:, 0] * t2[:, 1] - t1[:, 1] * t2[:, 0]
    dot = np.clip(np.einsum("ij,ij->i", t1, t2), -1.0, 1.0)
    turns = (np.abs(cross) > 1e-7) | (dot < 0)
    jk, t1, t2, cross, dot = jk[turns], t1[turns], t2[turns], cross[turns], dot[turns]
    sig = np.where(cross >= 0, 1.0, -1.0)  # +1: turns toward +n (the +n side is inner)
    n1, n2 = nrm[jk], nrm[jk + 1]
    Pj = p[seg_j[jk] + 1]
    dj = half[seg_j[jk] + 1]
    one_c = 1.0 + dot
    safe = np.maximum(one_c, 1e-12)  # hairpins (1 + cos theta ~ 0) use neither I nor the miter
    bis = (n1 + n2) / safe[:, None]  # (n1 + n2) / (1 + cos theta): the miter offset per unit half width
    retreat = dj * np.abs(cross) / safe  # d tan(theta / 2): how far I falls back along each segment
    # the inner vertex I may fall back along a segment as long as the retreats on the same side
    # of it (from its two ends) fit in it; where they do not, the larger retreat gives up (a few
    # vectorized passes). Retreats on opposite sides (an S bend) never meet.
    inner_ok = (one_c > 1e-9) & (retreat <= np.minimum(seg_len[jk], seg_len[jk + 1]))

    def overfull(ok):
        r_start, r_end = np.zeros(K), np.zeros(K)  # retreat at each segment's start / end
        s_start, s_end = np.zeros(K), np.zeros(K)  # and the side it is on
        r_end[jk[ok]], s_end[jk[ok]] = retreat[ok], sig[ok]
        r_start[jk[ok] + 1], s_start[jk[ok] + 1] = retreat[ok], sig[ok]
        return (s_start == s_end) & (r_start + r_end > seg_len * (1 - 1e-9)), r_start, r_end

    for _ in range(4):
        over, r_start, r_end = overfull(inner_ok)
        if not over.any():
            break
        drop_end = over[jk] & (retreat >= r_start[jk])  # the join ends an over-full segment
        drop_start = over[jk + 1] & (retreat >= r_end[jk + 1])  # the join starts one
        inner_ok &= ~(drop_end | drop_start)
    else:  # still over-full after the passes: every join touching such a segment gives up
        over = overfull(inner_ok)[0]
        inner_ok &= ~(over[jk] | over[jk + 1])
    plus_inner = sig > 0  # the turn is toward +n: the +n side (the right-hand one) is inner
    ki = jk[inner_ok]
    I = Pj[inner_ok] + (sig * dj)[inner_ok, None] * bis[inner_ok]
    vpix[ki, np.where(plus_inner[inner_ok], 3, 5)] = I
    vpix[ki + 1, np.where(plus_inner[inner_ok], 0, 2)] = I
    miter_ok = (one_c / 2.0 >= 1.0 / o.miter_limit ** 2) & (one_c > 1e-9)
    vpix[jk, 6] = np.where(miter_ok[:, None], Pj - (sig * dj)[:, None] * bis,
                           Pj - (0.5 * sig * dj)[:, None] * (n1 + n2))
    vuv[jk, 6, 1] = np.where(plus_inner, 0.0, 1.0)  # the outer side's v
    A = 7 * jk + np.where(plus_inner, 5, 3)
    B = 7 * (jk + 1) + np.where(plus_inner, 2, 0)
    C = 7 * jk + 4
    Mi = 7 * jk + 6
    tris[jk, 4] = np.where(plus_inner[:, None], np.stack([C, A, Mi], 1), np.stack([C, Mi, A], 1))
    tris[jk, 5] = np.where(plus_inner[:, None], np.stack([C, Mi, B], 1), np.stack([C, B, Mi], 1))

    # --- drop missing and zero-area triangles, then the vertices no triangle uses
    pix = vpix.reshape(-1, 2)
    tris = tris.reshape(-1, 3)
    t_stroke = np.repeat(sk, 6)
    # only join triangles and quads whose inner vertices moved can have zero area (hairpins,
    # inner points meeting): test those, drop the ones with nothing in them
    maybe = np.zeros((K, 6), bool)
    maybe[jk, 4:] = True
    maybe[ki, :4] = True
    maybe[ki + 1, :4] = True
    for k in shared:  # (a short end segment whose end edge turned)
        maybe[k, :4] = True
    maybe = maybe.ravel()
    mt = tris[maybe]
    a, b, c = pix[mt[:, 0]], pix[mt[:, 1]], pix[mt[:, 2]]
    area2 = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    keep = tris[:, 0] >= 0
    keep[maybe] &= area2 > 1e-10
    tris, t_stroke = tris[keep], t_stroke[keep]
    used = np.zeros(len(pix), bool)
    used[tris.ravel()] = True
    remap = np.cumsum(used) - 1
    tris = remap[tris][:, [0, 2, 1]]  # pixel y points down: reverse to be CCW seen from the camera
    pix = pix[used]
    uv = vuv.reshape(-1, 2)[used]
    vpt = pt.ravel()[used]
    v_stroke = sid[vpt]
    vo = np.searchsorted(v_stroke, np.arange(n_s + 1), side="left").astype(np.int64)
    to = np.searchsorted(t_stroke, np.arange(n_s + 1), side="left").astype(np.int64)

    if o.space == "image":
        pos = np.stack([pix[:, 0], cam.height - pix[:, 1], np.zeros(len(pix))], 1)
    else:
        zv = arr["z"][vpt]
        depth = zv if cam.is_ortho else 1.0 / zv
        if surface_depth is not None and len(pix):
            # Every vertex hung on one stroke point (a row across the ribbon, its joins) takes the
            # nearest depth seen at any of them: a flat row. Vertices each on the surface would
            # not do: the surface is convex there, and the chord between the silhouette and the
            # inner vertex runs behind it (by ~0.4% of the depth at 1.5 px on a sphere).
            row = np.full(len(arr["z"]), np.inf)
            np.minimum.at(row, vpt, surface_depth(cam, pix))
            depth = np.minimum(depth, row[vpt])
        pos = unproject(cam, pix, depth, o.pull)
    lvl = np.stack([strokes.level[v_stroke], strokes.level_weight[v_stroke]], 1) if len(v_stroke) else np.zeros((0, 2))
    return RibbonMesh(positions=pos, pixels=pix, uv=uv, level_uv=lvl, arc=s[vpt], u_raw=u[vpt], indices=tris,
                      vertex_offsets=vo, triangle_offsets=to, kind=strokes.kind, ids=strokes.ids,
                      level=np.asarray(strokes.level, float), level_weight=np.asarray(strokes.level_weight, float),
                      space=o.space)


def unproject(camera: Camera, pixels: np.ndarray, depth: np.ndarray, pull: float = 0.0) -> np.ndarray:
    """World points (V, 3) seen at `pixels` (V, 2) at view depth `depth` (V,) (distance along fwd),
    moved toward the camera along their own view ray by the fraction `pull` of their depth (the pixel
    does not change), orthographic cameras too (by `pull` times the eye-target distance, a vertex
    near the eye went behind the camera plane)."""
    right, up, fwd = camera.basis
    f = camera.focal_px
    eye = np.asarray(camera.eye)
    x = (pixels[:, 0] - camera.width / 2.0) / f  # in-plane offsets per unit depth (perspective)
    y = (camera.height / 2.0 - pixels[:, 1]) / f  # or in world units (orthographic)
    if camera.is_ortho:
        z = depth * (1.0 - pull)
        if camera.is_oblique:  # the point drawn at (x, y) at depth z lies kx z, ky z back in the plane
            kx, ky = camera.shear
            x, y = x - kx * z, y - ky * z
    else:
        z = depth * (1.0 - pull)
        x, y = x * z, y * z
    return eye + x[:, None] * right + y[:, None] * up + z[:, None] * fwd
