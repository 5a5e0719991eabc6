"""Operations on the strokes of one frame: split at a maximum length, drop short strokes, drop
zig-zag spurs that retrace a longer stroke, drop contour pieces that double a longer stroke, cut
pieces out of strokes, simplify. All vectorized over points."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from strokekit.lines.kernels import kernels
from strokekit.model import KIND_INDEX, Strokes, bracket, kind_of, uclip
from strokekit.sampling import resample_strokes, surface_between


def split_max_length(strokes: Strokes, max_length_px: float) -> Strokes:
    """Split every stroke into pieces of at most about `max_length_px` px, at its points
    (the point where one piece ends starts the next)."""
    if max_length_px <= 0 or len(strokes) == 0:
        return strokes
    arc = strokes.arc_length
    piece = np.floor(arc / max_length_px).astype(np.int64)
    sop = strokes.stroke_of_point
    # A point starts a new piece when its piece number differs from its predecessor's within a stroke.
    new = np.zeros(len(arc), bool)
    new[1:] = (piece[1:] != piece[:-1]) & (sop[1:] == sop[:-1])
    # Duplicate the point before each break so both pieces share it.
    brk = np.flatnonzero(new)
    if len(brk) == 0:
        return strokes
    src = np.insert(np.arange(len(arc)), brk, brk - 1)
    # Every start moves down by the points inserted before it (a break is never a stroke's first point).
    first = strokes.offsets[:-1]
    starts = np.sort(np.r_[first + np.searchsorted(brk, first), brk + np.arange(len(brk))])
    stroke_src = np.r_[np.arange(len(strokes)), sop[brk]]
    stroke_src = np.sort(stroke_src, kind="stable")
    offsets = np.r_[starts, len(src)].astype(np.int64)
    out = replace(strokes, points=strokes.points[src], surface=strokes.surface[src], face=strokes.face[src],
                  u=strokes.u[src], offsets=offsets, kind=strokes.kind[stroke_src],
                  ids=np.arange(len(starts), dtype=np.int64), level=strokes.level[stroke_src],
                  level_weight=strokes.level_weight[stroke_src])
    return replace(out, u=out.arc_length / out.period_px)


def drop_short(strokes: Strokes, min_length_px: float) -> Strokes:
    """Remove strokes shorter than `min_length_px` px."""
    if min_length_px <= 0 or len(strokes) == 0:
        return strokes
    return strokes.select(strokes.lengths >= min_length_px)


def simplify(strokes: Strokes, tol_px: float) -> Strokes:
    """Douglas-Peucker simplification of each stroke within `tol_px` (shapely); 0 keeps all points."""
    if tol_px <= 0 or len(strokes) == 0:
        return strokes
    import shapely

    keep = np.zeros(len(strokes.points), bool)
    keep[strokes.offsets[:-1]] = True
    keep[strokes.offsets[1:] - 1] = True
    lines = shapely.linestrings(strokes.points, indices=strokes.stroke_of_point)
    simp = shapely.simplify(lines, tol_px, preserve_topology=False)
    # Keep the original points that survive (shapely keeps a subset of each line's own vertices,
    # coordinates unchanged). Match on (stroke, x, y) exactly: strokes share positions where they
    # meet, so a nearest-point match could keep another stroke's point and drop this one's.
    coords, idx = shapely.get_coordinates(simp, return_index=True)
    n = len(strokes.points)
    st = np.r_[strokes.stroke_of_point, idx]
    x, y = np.r_[strokes.points[:, 0], coords[:, 0]], np.r_[strokes.points[:, 1], coords[:, 1]]
    is_out = np.r_[np.zeros(n, bool), np.ones(len(idx), bool)]
    # Sort by (stroke, x, y), originals before outputs (stable: the first original of a group
    # comes first); each output then takes the original point at the head of its group.
    order = np.lexsort((is_out, y, x, st))
    new_group = np.r_[True, (np.diff(st[order]) != 0) | (np.diff(x[order]) != 0) | (np.diff(y[order]) != 0)]
    head = order[np.flatnonzero(new_group)[np.cumsum(new_group) - 1]]
    matched = head[is_out[order]]
    keep[matched[matched < n]] = True
    counts = np.bincount(strokes.stroke_of_point[keep], minlength=len(strokes))
    out = replace(strokes, points=strokes.points[keep], surface=strokes.surface[keep], face=strokes.face[keep],
                  u=strokes.u[keep], offsets=np.r_[0, np.cumsum(counts)].astype(np.int64))
    return out


# --- pieces of strokes, doubled contours (the per-frame pass and the tracker use them) ---------

#: Kinds whose strokes can double each other (see drop_doubled).
CONTOUR_KINDS = ("silhouette", "smooth_contour")


def join_arrays(*parts) -> np.ndarray:
    """np.r_ for scalars and arrays along the first axis, without np.r_'s overhead (the tracker
    makes dozens of these per frame on small arrays)."""
    for p in parts:
        if type(p) is not np.ndarray or not p.ndim:
            return np.concatenate([p if type(p) is np.ndarray and p.ndim else (p,) for p in parts])
    return np.concatenate(parts)  # (all arrays: as they are)


def query_tree(points: np.ndarray):
    """A k-d tree built for one query pass: unbalanced, not compacted (builds faster on a
    frame's samples; queries are exact either way)."""
    from scipy.spatial import cKDTree

    return cKDTree(points, balanced_tree=False, compact_nodes=False)


# --- stroke surgery --------------------------------------------------------------------------

def cut_pieces(strokes: Strokes, stroke: np.ndarray, s0: np.ndarray, s1: np.ndarray,
               reverse: np.ndarray | None = None) -> Strokes:
    """Pieces of strokes: piece k is stroke[k] between arc lengths s0[k] < s1[k] (px), new end
    points interpolated (position, surface point; face of the nearer point), reversed where
    `reverse` is true. u is arc length / P, ids 0..K-1, kind, level and weight of the source.
    Vectorized over all pieces."""
    stroke = np.asarray(stroke, np.int64)
    K = len(stroke)
    if K == 0:
        return Strokes.empty(strokes.camera, strokes.frame, strokes.period_px)
    rev = np.zeros(K, bool) if reverse is None else np.asarray(reverse, bool)
    offsets = strokes.offsets
    base, G = strokes.global_arc
    bs = base[stroke]
    g0 = bs + np.asarray(s0, float)
    g1 = bs + np.asarray(s1, float)
    first = offsets[:-1][stroke]
    last = offsets[1:][stroke] - 1
    # Interior original points: G strictly inside (g0, g1).
    r0 = G.searchsorted(g0, side="right")  # also where at(g0) starts its search
    lo = np.maximum(r0, first)
    hi = np.minimum(G.searchsorted(g1, side="left"), last + 1)
    n_in = np.maximum(hi - lo, 0)

    def at(g, r, first, last):
        i, j = bracket(G, r, first, last)
        Gi = G[i]
        d = G[j] - Gi
        dp = d > 0
        a = uclip((g - Gi) / d if dp.all() else np.where(dp, (g - Gi) / np.where(dp, d, 1.0), 0.0), 0, 1)
        p = strokes.points.take(i, axis=0) * (1 - a)[:, None] + strokes.points.take(j, axis=0) * a[:, None]
        X = surface_between(strokes, i, j, a)
        f = np.where(a < 0.5, strokes.face[i], strokes.face[j])
        return p, X, f

    if K >= 2:
        # Both ends in one pass (half the calls). Not for K = 1: numpy projects a single point
        # (a 1-row matrix product) with other rounding than rows of a longer batch.
        p, X, f = at(np.concatenate((g0, g1)), np.concatenate((r0, G.searchsorted(g1, side="right"))),
                     np.concatenate((first, first)), np.concatenate((last, last)))
        pa, Xa, fa, pb, Xb, fb = p[:K], X[:K], f[:K], p[K:], X[K:], f[K:]
    else:
        pa, Xa, fa = at(g0, r0, first, last)
        pb, Xb, fb = at(g1, np.searchsorted(G, g1, side="right"), first, last)
    counts = n_in + 2
    offsets = np.concatenate(((0,), counts.cumsum())).astype(np.int64)
    N = int(offsets[-1])
    start = offsets[:-1]
    # Gathered once, in the final order: position t of piece k (start s, c points) shows point
    # t of the piece, or point s + c - 1 - (t - s) of it where the piece is reversed; point
    # p of the piece is original point lo - 1 + (p - s) (interior ones; its two ends are the
    # interpolated pa, pb, set below: mode="clip" keeps the indices of those two slots in range).
    t = np.arange(N)
    if rev.any():
        order = np.where(rev.repeat(counts), (2 * start + counts - 1).repeat(counts) - t, t)
    else:
        order = t
    src = order + (lo - 1 - start).repeat(counts)
    # take(axis=0) for row gathers: numpy's fancy indexing of (N, 2) / (N, 3) rows is slower
    # on arrays of a frame's size (same values).
    points = strokes.points.take(src, axis=0, mode="clip")
    surface = strokes.surface.take(src, axis=0, mode="clip")
    face = strokes.face.take(src, mode="clip")
    head, tail = start, offsets[1:] - 1
    r2 = rev[:, None]
    points[head], surface[head], face[head] = np.where(r2, pb, pa), np.where(r2, Xb, Xa), np.where(rev, fb, fa)
    points[tail], surface[tail], face[tail] = np.where(r2, pa, pb), np.where(r2, Xa, Xb), np.where(rev, fa, fb)
    out = Strokes(points=points, surface=surface, face=face, offsets=offsets, kind=strokes.kind[stroke],
                  ids=np.arange(K, dtype=np.int64), u=None, level=strokes.level[stroke],
                  level_weight=strokes.level_weight[stroke], camera=strokes.camera, frame=strokes.frame,
                  period_px=strokes.period_px)
    return out.replace(u=out.arc_length / out.period_px)


def drop_doubled(strokes: Strokes, radius_px: float, min_piece_px: float = 1.0, step_px: float = 1.0,
                 kinds: tuple[str, ...] = CONTOUR_KINDS) -> Strokes:
    """Cut out the parts of strokes that double a longer stroke (see drop_overlaps)."""
    return drop_overlaps(strokes, retraced_px=0.0, doubled_px=radius_px, min_piece_px=min_piece_px,
                         step_px=step_px, kinds=kinds)


def drop_overlaps(strokes: Strokes, retraced_px: float = 0.5, doubled_px: float = 1.0, *,
                  min_piece_px: float = 1.0, step_px: float = 1.0,
                  kinds: tuple[str, ...] = CONTOUR_KINDS, compiled: bool = False) -> Strokes:
    """The strokes without what draws a line twice, in one pass over one set of samples (every
    `step_px` along each stroke, one k-d tree, one query of the close sample pairs).

    1. Retraced strokes (`retraced_px` > 0): a stroke that lies entirely within `retraced_px` of
       a longer stroke (ties: lower index) of the same kind is dropped whole: the back-and-forth
       spurs of mesh contours, the edges of coincident copies of a mesh.
       A stroke's samples are half a step from any of its points, so "within" is tested as a
       sample within hypot(retraced_px, step_px / 2) of a sample of the longer stroke.
    2. Doubled parts (`doubled_px` > 0), among the strokes left: a part of a stroke is dropped
       where a longer stroke runs beside it, within `doubled_px` across, tangents agreeing
       (|t.t'| >= 0.65), level along it (the neighbour sample is within 0.75 px of it along the
       tangent, so a stroke that merely continues another one at a shared end keeps its ends).
       Mesh contours of fine meshes come out shingled: short pieces that overlap their
       neighbours side by side for a pixel or two. Only strokes of one of `kinds` (contours: they
       slide over the surface and are extracted piecewise) are compared, each with strokes of its
       own kind: creases and borders are mesh edges, never shingled, and two of them close
       together are two lines. Pieces shorter than `min_piece_px` left over are dropped; cuts
       fall within half a step (coarser steps cost M1: the healing of the pieces left needs
       precise ends). When something is cut, ids are renumbered and u = arc length / P.

    `compiled`: the close pairs from the compiled grid search of `lines.compiled` (the same
    pairs, for runs that load numba anyway: hidden-line drawings, several times the strokes),
    else from a k-d tree."""
    if len(strokes) < 2 or (retraced_px <= 0 and doubled_px <= 0):
        return strokes
    smp = resample_strokes(strokes, step_px, with_surface=False)
    S = len(strokes)
    L = strokes.lengths
    rank = np.empty(S, np.int64)
    rank[np.argsort(-L, kind="stable")] = np.arange(S)  # 0: the longest (ties: lower index)
    reach = float(np.hypot(retraced_px, 0.5 * step_px)) if retraced_px > 0 else 0.0
    # All sample pairs closer than the larger radius; only pairs of two strokes of one kind matter.
    st = smp.stroke
    sk = strokes.kind[st]
    if compiled and doubled_px <= 0 and retraced_px > 0:
        # Only retraced strokes: every pair lies within reach (the kernel's test is the one
        # below), so each marks its sample on the shorter stroke.
        i, j = kernels().close_pairs(smp.p, st, sk, reach)
        near = np.zeros(len(smp), bool)
        near[np.where(rank[st[i]] < rank[st[j]], j, i)] = True
        gone = np.bincount(st, weights=near, minlength=S) == np.bincount(st, minlength=S)
        return strokes.select(~gone) if gone.any() else strokes
    if compiled:  # (the same pairs; most pairs within reach are neighbours on one stroke)
        pr = np.stack(kernels().close_pairs(smp.p, st, sk, max(reach, doubled_px)), axis=1)
    else:
        pr = query_tree(smp.p).query_pairs(max(reach, doubled_px), output_type="ndarray")
        pr = pr[(st[pr[:, 0]] != st[pr[:, 1]]) & (sk[pr[:, 0]] == sk[pr[:, 1]])]
    # Orient each pair (sample, sample of the longer stroke beside it).
    a, b = pr[:, 0], pr[:, 1]
    swap = rank[st[a]] < rank[st[b]]
    a, b = np.where(swap, b, a), np.where(swap, a, b)
    dp = smp.p.take(b, axis=0) - smp.p.take(a, axis=0)
    d2 = np.einsum("ij,ij->i", dp, dp)
    gone = np.zeros(S, bool)
    if retraced_px > 0:
        near = np.zeros(len(smp), bool)
        near[a[d2 <= reach * reach]] = True
        counts = np.bincount(st, minlength=S)
        gone = np.bincount(st, weights=near, minlength=S) == counts
    covered = gone[st]
    if doubled_px > 0:
        ok = ~gone[st[a]] & ~gone[st[b]] & (d2 <= doubled_px * doubled_px)
        ok &= np.isin(kind_of(sk[a]), [KIND_INDEX[k] for k in kinds])  # (of any occlusion level)
        along = np.abs(np.einsum("ij,ij->i", dp, smp.t[a]))
        ok &= along <= 0.5 * (smp.w[a] + smp.w[b]) - 0.25  # beside, not one stroke continuing the other
        ok &= np.abs(np.einsum("ij,ij->i", smp.t[b], smp.t[a])) >= 0.65
        doubled = np.zeros(len(smp), bool)
        doubled[a[ok]] = True
        if doubled.any():
            return _cut_uncovered(strokes, smp, covered | doubled, min_piece_px)
    return strokes.select(~gone) if gone.any() else strokes


def _cut_uncovered(strokes: Strokes, smp, covered: np.ndarray, min_piece_px: float) -> Strokes:
    """The pieces of strokes between their covered samples (drop_overlaps)."""
    L = strokes.lengths
    keep = ~covered
    D = len(smp)
    start = join_arrays(True, (keep[1:] != keep[:-1]) | (smp.stroke[1:] != smp.stroke[:-1]))
    first = np.flatnonzero(start)
    last = join_arrays(first[1:] - 1, D - 1)
    st = smp.stroke[first]
    head = join_arrays(True, st[1:] != st[:-1])
    tail = join_arrays(st[1:] != st[:-1], True)
    s0 = np.where(head, 0.0, smp.s[first] - 0.5 * smp.w[first])
    s1 = np.where(tail, L[st], smp.s[last] + 0.5 * smp.w[last])
    # Leftovers under min_piece_px go; a whole stroke (nothing of it covered) always stays.
    sel = keep[first] & ((s1 - s0 >= min_piece_px) | (head & tail))
    return cut_pieces(strokes, st[sel], s0[sel], s1[sel])
