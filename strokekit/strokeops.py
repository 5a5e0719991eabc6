"""Operations on the strokes of one frame: split at a maximum length, drop short strokes, drop
zig-zag spurs that retrace a longer stroke, simplify. All vectorized over points."""

from __future__ import annotations

import numpy as np
from dataclasses import replace

from .model import Strokes


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
    starts = np.sort(np.r_[strokes.offsets[:-1], brk + np.arange(len(brk))])
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


def resample(strokes: Strokes, step_px: float) -> tuple[np.ndarray, np.ndarray]:
    """Points every ~`step_px` along all strokes (stroke vertices included): (M, 2) points and the
    (M,) stroke index of each."""
    if len(strokes.points) == 0:
        return np.zeros((0, 2)), np.zeros(0, np.int64)
    seg = strokes.segment_lengths
    sop = strokes.stroke_of_point
    # Segment i runs from point i-1 to point i (for non-first points).
    seg_idx = np.flatnonzero(seg > 0)
    n = np.ceil(seg[seg_idx] / step_px).astype(np.int64)
    rep = np.repeat(seg_idx, n)
    k = np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)  # (cumsum - n: safe when no segment has length)
    t = (k / np.repeat(n, n))[:, None]
    pts = strokes.points[rep - 1] * (1 - t) + strokes.points[rep] * t
    last = strokes.offsets[1:] - 1
    return np.concatenate([pts, strokes.points[last]]), np.concatenate([sop[rep], sop[last]])


def drop_retraced(strokes: Strokes, tol_px: float = 0.5) -> Strokes:
    """Drop strokes that lie entirely within `tol_px` of a longer (or equally long, earlier)
    stroke of the same kind: the back-and-forth spurs of mesh contours (seed 000 Fig 3.5/3.6) that
    would otherwise draw the same line twice.

    Strokes are resampled every `tol_px`; a sample is covered when one of its nearest samples
    (k-nearest query, within tol) belongs to a higher-ranked stroke of the same kind. Only strokes
    whose first, middle and last samples are covered are checked in full: most strokes are
    rejected by three queries."""
    if len(strokes) < 2:
        return strokes
    from scipy.spatial import cKDTree

    pts, owner, counts = _resample_grouped(strokes, tol_px)
    tree = cKDTree(pts, balanced_tree=False, compact_nodes=False)  # built every frame: cheap build wins
    n = len(strokes)
    rank = np.empty(n, np.int64)
    rank[np.lexsort((np.arange(n), -strokes.lengths))] = np.arange(n)
    kind = strokes.kind

    def covered(sample_idx: np.ndarray) -> np.ndarray:
        k = min(12, len(pts))
        _, nb = tree.query(pts[sample_idx], k=k, distance_upper_bound=tol_px * (1 + 1e-9))
        nb = nb.reshape(len(sample_idx), k)
        valid = nb < len(pts)
        other = owner[np.where(valid, nb, 0)]
        me = owner[sample_idx][:, None]
        ok = valid & (other != me) & (kind[other] == kind[me]) & (rank[other] < rank[me])
        return ok.any(axis=1)

    starts = np.cumsum(counts) - counts
    ends = starts + counts - 1
    probe = np.stack([starts, (starts + ends) // 2, ends], axis=1).ravel()
    probe_cov = covered(probe)
    candidate = probe_cov.reshape(n, 3).all(axis=1)
    if not candidate.any():
        return strokes
    # A sample's answer does not depend on what else is asked: the probes are not asked again.
    cov = np.zeros(len(pts), bool)
    known = np.zeros(len(pts), bool)
    cov[probe], known[probe] = probe_cov, True
    in_candidate = candidate[owner]
    rest = np.flatnonzero(in_candidate & ~known)
    if len(rest):
        cov[rest] = covered(rest)
    sample_idx = np.flatnonzero(in_candidate)
    n_cov = np.bincount(owner[sample_idx], weights=cov[sample_idx], minlength=n)
    redundant = candidate & (n_cov == counts)
    if not redundant.any():
        return strokes
    return strokes.select(~redundant)


def _resample_grouped(strokes: Strokes, step_px: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """resample(strokes, step_px) with the samples grouped by stroke, in order along it (the
    order a stable sort by stroke gives: each stroke's samples, then its last point), and the
    number of samples of each stroke."""
    seg = strokes.segment_lengths
    sop = strokes.stroke_of_point
    S = len(strokes)
    seg_idx = np.flatnonzero(seg > 0)
    n = np.ceil(seg[seg_idx] / step_px).astype(np.int64)
    rep = np.repeat(seg_idx, n)
    k = np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)
    t = (k / np.repeat(n, n))[:, None]
    P = strokes.points
    inner = np.take(P, rep - 1, axis=0) * (1 - t) + np.take(P, rep, axis=0) * t
    owner_inner = sop[rep]
    counts = np.bincount(owner_inner, minlength=S) + 1
    pts = np.empty((len(rep) + S, 2))
    pts[np.arange(len(rep)) + owner_inner] = inner
    pts[np.cumsum(counts) - 1] = P[strokes.offsets[1:] - 1]
    return pts, np.repeat(np.arange(S), counts), counts


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
