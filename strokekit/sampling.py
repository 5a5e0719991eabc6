"""Samples along strokes, the one resampler of the stages, the metrics and the writers: lengths cut
into equal pieces (`split_lengths`), the place of an arc length on a stroke (`locate`), strokes
resampled by arc length with u and surface points (`resample_strokes`: tracking, brush paths,
coherence), points along every segment (`segment_samples`: distances between drawings), and
samples of one frame matched to another's (`match_samples`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from strokekit.model import Strokes, bracket, row_norm, uclip

if TYPE_CHECKING:  # (scipy loads where samples are matched: the writers' import stays light)
    from scipy.spatial import cKDTree

#: A sample's match in the other frame lies within this radius (px) and its tangent agrees with
#: the sample's: |t . t'| at least MIN_TANGENT_DOT (the coherence metrics' rule).
MATCH_RADIUS_PX = 6.0
MIN_TANGENT_DOT = 0.65


def split_lengths(lengths: np.ndarray, step_px: float, *, min_pieces: int = 0,
                  slack: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cut each of `lengths` (L,) px into n = max(min_pieces, ceil(length / step_px - slack))
    equal pieces. Returns owner (M,) the index of the length each piece cuts, k (M,) the piece's
    rank within it (0..n-1) and n (L,) the piece counts. A piece k of length i spans the fractions
    [k / n[i], (k + 1) / n[i]] of it."""
    n = np.ceil(lengths / step_px - slack) if slack else np.ceil(lengths / step_px)
    if min_pieces:
        n = np.maximum(min_pieces, n)
    n = n.astype(np.int64)
    owner = np.arange(len(n)).repeat(n)
    cn = n.cumsum()
    k = np.arange(cn[-1] if len(cn) else 0) - (cn - n).repeat(n)
    return owner, k, n


def segment_samples(points: np.ndarray, offsets: np.ndarray, step_px: float, *,
                    middles: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points along polylines (points (N, 2), polyline p = points[offsets[p]:offsets[p + 1]]) at
    most `step_px` apart: the segment from each point to the next cut into ceil(length / step_px)
    equal pieces (at least one), a sample at the start of each piece, so at every point, in order
    along each polyline. With `middles`, a sample at the middle of each piece of positive length
    instead. Returns the positions (M, 2), the polyline of each (M,) and the length of the piece
    each sample starts or stands for (M,) (0 at a polyline's last point). Distances to the
    samples are exact to step_px / 2; P0 + t (P1 - P0) keeps exact a coordinate the segment
    does not change."""
    P = np.asarray(points, float)
    polyline = np.arange(len(offsets) - 1).repeat(np.diff(offsets))
    d = np.zeros((len(P), 2))
    if len(P) > 1:
        d[:-1] = P[1:] - P[:-1]
    d[np.asarray(offsets[1:], np.int64) - 1] = 0.0  # (no segment from a polyline's last point)
    seg = row_norm(d)
    start = np.flatnonzero(seg > 0) if middles else np.arange(len(P))
    owner, k, n = split_lengths(seg[start], step_px, min_pieces=0 if middles else 1)
    t = (k + 0.5) / n[owner] if middles else k / n[owner]
    rep = start[owner]
    return P[rep] + d[rep] * t[:, None], polyline[rep], (seg[start] / n)[owner]


@dataclass(frozen=True, eq=False)
class Samples:
    """Strokes resampled at ~`step` px of arc length (midpoints of equal pieces of each stroke).

    p (M, 2) px; X (M, 3) world; u (M,) periods; t (M, 2) unit screen tangents; ids (M,) stroke ids;
    stroke (M,) stroke index; s (M,) arc length from the stroke start, px; w (M,) length each
    sample stands for, px (sums to the stroke length)."""

    p: np.ndarray
    X: np.ndarray
    u: np.ndarray
    t: np.ndarray
    ids: np.ndarray
    stroke: np.ndarray
    s: np.ndarray
    w: np.ndarray

    def __len__(self) -> int:
        return len(self.p)


def surface_between(strokes: Strokes, i: np.ndarray, j: np.ndarray, a: np.ndarray,
                    values: np.ndarray | None = None) -> np.ndarray:
    """World points under the screen points p_i + a (p_j - p_i) (a (K,) in [0, 1]): the surface
    points are interpolated perspective-correctly (1/z is linear on screen), so that a point in
    the middle of a long receding segment is the world point actually drawn there. `values`
    (N, 3): interpolate these per-point values instead, with the same weights (the surface points
    moved with their objects to another frame, model.carry_points)."""
    X = strokes.surface
    cam = strokes.camera
    a = np.asarray(a, float)
    # Gathered once for the depths and the interpolation; take(axis=0): numpy's fancy indexing of
    # (N, 3) rows is several times slower (same values).
    Xi, Xj = X.take(i, axis=0), X.take(j, axis=0)
    if cam is not None and not cam.is_ortho and len(i):
        fwd, eye = cam.basis[2], cam.eye_array
        zi, zj = (Xi - eye) @ fwd, (Xj - eye) @ fwd
        ok = (zi > 0) & (zj > 0)
        if ok.all():  # the usual case: the np.where below pass zi, zj through
            den = (1 - a) * zj + a * zi
            dp = den > 0
            a = a * zi / den if dp.all() else np.where(dp, a * zi / np.where(dp, den, 1.0), a)
        else:
            zi = np.where(ok, zi, 1.0)
            den = (1 - a) * np.where(ok, zj, 1.0) + a * zi
            a = np.where(ok & (den > 0), a * zi / np.where(den > 0, den, 1.0), a)
    if values is not None:
        Xi, Xj = values.take(i, axis=0), values.take(j, axis=0)
    return Xi * (1 - a)[:, None] + Xj * a[:, None]


def locate(strokes: Strokes, stroke: np.ndarray, s: np.ndarray, side: str = "right"
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where arc length s (px) of strokes `stroke` lies: (i, j, a), the segment from point i to
    point j and the fraction a in [0, 1] of the way along it (a one-point stroke: i = j, a = 0).
    An s past a stroke's ends is held at them. side "right": a point between two segments
    belongs to the one after it; "left": to the one before (searchsorted's sides)."""
    base, G = strokes.global_arc
    offsets = strokes.offsets
    g = s + base[stroke]
    first = offsets[:-1][stroke]
    last = offsets[1:][stroke] - 1
    i, j = bracket(G, G.searchsorted(g, side=side), first, last)
    single = last == first
    if single.any():
        j = np.where(single, first, j)
        i = np.where(single, first, i)
    Gi = G[i]
    d = G[j] - Gi
    dp = d > 0
    a = (g - Gi) / d if dp.all() else np.where(dp, (g - Gi) / np.where(dp, d, 1.0), 0.0)
    return i, j, uclip(a, 0.0, 1.0)


def resample_strokes(strokes: Strokes, step_px: float = 1.0, with_surface: bool = True,
                     surface: np.ndarray | None = None) -> Samples:
    """Resample every stroke into pieces of at most `step_px` px; one sample at the middle of each
    piece, with u, X and position interpolated linearly along the polyline (vectorized).
    with_surface=False leaves X at zero (screen-only uses, cheaper). `surface` (N, 3): X from
    these per-point values (surface_between's `values`)."""
    if len(strokes) == 0 or len(strokes.points) == 0:
        z = np.zeros(0)
        zi = np.zeros(0, np.int64)
        return Samples(np.zeros((0, 2)), np.zeros((0, 3)), z, np.zeros((0, 2)), zi, zi, z, z)
    L = strokes.lengths
    stroke, k, n = split_lengths(L, step_px, min_pieces=1, slack=1e-9)
    w = (L / n)[stroke]
    s = (k + 0.5) * w
    i, j, a = locate(strokes, stroke, s)
    P, U = strokes.points, strokes.u
    Xs = surface_between(strokes, i, j, a, surface) if with_surface else np.zeros((len(i), 3))
    u = U[i] * (1 - a) + U[j] * a
    Pi, Pj = P.take(i, axis=0), P.take(j, axis=0)  # once for the position and the tangent (take: see above)
    t = Pj - Pi
    tn = row_norm(t)  # np.linalg.norm(t, axis=1) without its overhead
    pos = tn > 0
    t = t / tn[:, None] if pos.all() else np.where(pos[:, None], t / np.where(pos, tn, 1.0)[:, None], 0.0)
    p = Pi * (1 - a)[:, None] + Pj * a[:, None]
    return Samples(p=p, X=Xs, u=u, t=t, ids=strokes.ids[stroke], stroke=stroke, s=s, w=w)


def match_samples(src: Samples, camera, dst: Samples, dst_tree: cKDTree | None = None, *,
                  radius_px: float = MATCH_RADIUS_PX, min_tangent_dot: float = MIN_TANGENT_DOT,
                  k: int = 8, return_projected: bool = False, piece_distance: bool = False,
                  exact: bool = False):
    """For every sample of `src`: the index of its match in `dst` (or -1). src.X is projected
    with `camera` (dst's camera); the match is the nearest dst sample within `radius_px` px
    whose tangent agrees with the src tangent (|t.t'| >= min_tangent_dot). With
    return_projected, also the (M, 2) projected pixel positions.
    piece_distance (for sparse dst samples, as the tracker's): among the k nearest agreeing
    samples, the one whose piece of line (length w along t, centred on p) passes nearest wins,
    instead of the one whose centre is nearest: where lines run 1-3 px apart (shingled mesh
    contours) the nearest centre of samples 3-4 px apart is often on the wrong line, the line
    the 1 px samples of the metrics pick is not. The metrics use the plain rule.
    exact (the metrics): where all k nearest samples are within reach and none agrees,
    every sample within reach is examined, so the nearest agreeing one is never missed in
    crowded places (the tracker's votes are content with the k nearest)."""
    out = np.full(len(src), -1, np.int64)
    if len(src) == 0 or len(dst) == 0:
        return (out, np.full((len(src), 2), np.nan)) if return_projected else out
    q, z = camera.project(src.X)
    # (Columns combined by hand: numpy's reductions along a short trailing axis cost more.)
    fin = np.isfinite(q)
    ok = fin[:, 0] & fin[:, 1] & ((z > 0) | camera.is_ortho)
    if not ok.any():
        return (out, q) if return_projected else out
    tree = dst_tree
    if tree is None:
        from scipy.spatial import cKDTree

        tree = cKDTree(dst.p)
    kk = min(k, len(dst))
    every = ok.all()  # the usual case: no copies, no scatter
    qq = q if every else q[ok]
    st = src.t if every else src.t[ok]
    dist, idx = tree.query(qq, k=kk, distance_upper_bound=radius_px)
    n = len(qq)
    if piece_distance:
        # Neighbour by neighbour: (kk, n) planes, so that every operation below runs along rows
        # of n (the (n, kk) layout makes numpy loop n times over rows of kk: several times
        # slower). Same operations on the same values, elementwise.
        dist = dist.reshape(n, kk).T.copy()
        valid = dist < np.inf  # (the tree marks "not found" with inf)
        every_valid = valid.all()
        idx = idx.reshape(n, kk).T
        safe = idx.copy() if every_valid else np.where(valid, idx, 0)
        # One gather of the planes t_x, t_y, p_x, p_y, w/2 instead of three gathers: (5, kk, n),
        # each plane contiguous for the arithmetic below.
        planes = np.empty((5, len(dst)))
        planes[0:2] = dst.t.T
        planes[2:4] = dst.p.T
        np.multiply(dst.w, 0.5, out=planes[4])
        D = planes.take(safe, axis=1)
        T0, T1 = D[0], D[1]
        # (In place where a temporary can take the result: the same operations, fewer arrays.)
        dots = T0 * st[:, 0]
        dots += T1 * st[:, 1]
        good = np.abs(dots, out=dots) >= min_tangent_dot
        if not every_valid:
            good &= valid
        # Squared distance to the piece: across the line, plus beyond the piece's ends along it.
        # (Where no neighbour was found dist is inf and so is the cost; `good` masks it anyway.)
        along = qq[:, 0] - D[2]
        along *= T0
        a1 = qq[:, 1] - D[3]
        a1 *= T1
        along += a1
        beyond = np.abs(along)
        beyond -= D[4]
        np.maximum(beyond, 0.0, out=beyond)
        cost = dist * dist
        cost -= np.multiply(along, along, out=a1)
        np.maximum(cost, 0.0, out=cost)
        cost += np.multiply(beyond, beyond, out=beyond)
        # Per query the first neighbour of least cost among the good ones (np.argmin's rule),
        # by rows: a strict < keeps the earlier neighbour on ties.
        has = good[0].copy()
        best = np.where(has, cost[0], np.inf)
        first = np.zeros(n, np.int64)
        for c in range(1, kk):
            better = good[c] & (cost[c] < best)
            first[better] = c
            best = np.where(better, cost[c], best)
            has |= good[c]
        m = np.where(has, safe.ravel()[first * n + np.arange(n)], -1)  # safe[first, col], flat
    else:
        dist = dist.reshape(n, kk)
        idx = idx.reshape(n, kk)
        valid = np.isfinite(dist)
        safe = np.where(valid, idx, 0)
        T = dst.t[safe]
        dots = np.abs(T[..., 0] * st[:, None, 0] + T[..., 1] * st[:, None, 1])
        good = valid & (dots >= min_tangent_dot)
        has = good[:, 0].copy()  # good.any(axis=1), by columns (cheaper, as above)
        for c in range(1, kk):
            has |= good[:, c]
        # Neighbours come sorted by distance: the first good one is the nearest agreeing sample.
        first = np.argmax(good, axis=1)
        m = np.where(has, safe.ravel()[np.arange(n) * kk + first], -1)  # safe[row, first], flat (cheaper)
    if exact and not piece_distance:
        redo = np.flatnonzero(~has & valid[:, -1])
        if len(redo):
            m[redo] = _nearest_agreeing(tree, qq[redo], st[redo], dst.t, radius_px,
                                        min_tangent_dot)
    if every:
        out = m
    else:
        out[np.flatnonzero(ok)] = m
    return (out, q) if return_projected else out


def _nearest_agreeing(tree: cKDTree, q: np.ndarray, t: np.ndarray, dst_t: np.ndarray, radius_px: float,
                      min_tangent_dot: float) -> np.ndarray:
    """(N,) for points q (N, 2) with tangents t: the nearest sample of `tree` within radius_px whose
    tangent (dst_t) agrees, among all of them, or -1."""
    near = tree.query_ball_point(q, radius_px)
    counts = np.fromiter((len(x) for x in near), np.int64, len(near))
    out = np.full(len(q), -1, np.int64)
    if counts.sum() == 0:
        return out
    cand = np.fromiter((j for x in near for j in x), np.int64, int(counts.sum()))
    row = np.repeat(np.arange(len(q)), counts)
    d = tree.data[cand] - q[row]
    dist2 = np.einsum("ij,ij->i", d, d)
    good = np.abs(np.einsum("ij,ij->i", dst_t[cand], t[row])) >= min_tangent_dot
    row, cand, dist2 = row[good], cand[good], dist2[good]
    o = np.lexsort((cand, dist2, row))  # per row the nearest first (ties: lower index)
    first = o[np.r_[True, row[o][1:] != row[o][:-1]]] if len(o) else o
    out[row[first]] = cand[first]
    return out
