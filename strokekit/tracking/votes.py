"""Votes carried from the previous frame: ids assigned by matched length (`assign_ids`), chains
cut where the carried ids change (`segment_by_votes`), boundaries snapped to the previous
strokes' ends. The labels, runs, id assignment and u trend are compiled (`votes_kernels`); the
tracker and the brush paths share them."""

from __future__ import annotations

import numpy as np

from strokekit.lines.strokeops import join_arrays
from strokekit.model import Strokes, row_norm
from strokekit.numba_cache import LazyKernels
from strokekit.sampling import Samples, match_samples

kernels = LazyKernels("strokekit.tracking.votes_kernels").kernels


def u_trend(run: np.ndarray, vid: np.ndarray, label: np.ndarray, pos: np.ndarray, u: np.ndarray,
            R: int) -> np.ndarray:
    """(R,) px of every run along which the carried u increases, less the px along which it
    decreases: the votes that carry the run's own id (`label`), in order of their position `pos`
    (px along the new stroke), each step counted by its length with the sign of its du. A step
    across the seam of an old loop (u jumps back by the loop) counts for its length only."""
    keep = np.flatnonzero(vid == label.take(run))
    if len(keep) < 2:
        return np.zeros(R)
    pk = pos.take(keep)
    return kernels().u_trend(np.asarray(run.take(keep), np.int64), pk - pk.min(), u.take(keep), R)


def unwrap_loop_votes(prev: Strokes, u: np.ndarray, vid: np.ndarray, s: np.ndarray, group: np.ndarray,
                       w: np.ndarray, P: float, min_loop_spacing_px: float) -> np.ndarray:
    """Votes u (V,) made continuous across the seams of the previous frame's closed strokes.

    A closed stroke's u runs from u0 at its start to u0 + U at its end, the same point (U: its
    length in periods), so its votes jump by U where the old seam lies. A new stroke that runs
    across that point (an open piece of the old loop, or a loop the chaining started elsewhere
    and turn_loops_to_seams could not turn) would fit u through the jump and fold it backwards.
    Within each vote group (`group`: a new stroke and the carried id `vid`), votes sorted by
    their arc length `s` (px) along the new stroke; a step between two that arc length does not
    explain (du - ds / P, a whole number of U away from 0) is undone, and the group keeps the
    offset of most of its weight `w`, so the votes away from the seam keep their u."""
    if len(u) == 0 or len(prev) == 0:
        return u
    first, last = prev.offsets[:-1], prev.offsets[1:] - 1
    L = prev.lengths
    closed = (L > 0) & (row_norm(prev.points.take(first, axis=0) - prev.points.take(last, axis=0)) < 1e-6)
    if not closed.any():
        return u
    # U per carried id (ids are unique per stroke); only loops of at least 4 vote spacings
    # (`min_loop_spacing_px`), whose jump stands out from the noise of neighbouring votes.
    span = prev.u.take(last) - prev.u.take(first)
    loop = closed & (L >= 4.0 * min_loop_spacing_px)
    ids_sorted = np.argsort(prev.ids, kind="stable")
    k = np.searchsorted(prev.ids, vid, sorter=ids_sorted)
    src = ids_sorted[np.minimum(k, len(ids_sorted) - 1)]
    U = np.where((prev.ids[src] == vid) & loop[src], span[src], 0.0)
    if not (U > 0).any():
        return u
    o = np.lexsort((s, group))
    gq, sq, uq, Uq = group[o], s[o], u[o], U[o]
    same = gq[1:] == gq[:-1]
    step = np.diff(uq) - np.diff(sq) / P
    turns = np.where(same & (Uq[1:] > 0), np.round(step / np.where(Uq[1:] > 0, Uq[1:], 1.0)), 0.0)
    if not turns.any():
        return u
    # Whole loops added so far within the group (a cumulative sum restarted at each group).
    c = join_arrays(0.0, np.cumsum(turns))
    start = join_arrays(True, ~same)
    c -= c[np.maximum.accumulate(np.where(start, np.arange(len(c)), 0))]
    # The offset holding most of the group's weight stays (ties: the lower one).
    ci = c.astype(np.int64)
    base = ci.min()
    n_off = int(ci.max() - base) + 1
    ukey, kinv = unique_inverse(gq.astype(np.int64) * n_off + (ci - base))
    kgroup = ukey // n_off
    keep = first_max_per_group(kgroup, np.bincount(kinv, weights=w[o]))
    keep_c = np.zeros(int(gq.max()) + 1, np.int64)
    keep_c[kgroup[keep]] = ukey[keep] % n_off + base
    out = u.copy()
    out[o] = uq - (ci - keep_c[gq]) * Uq
    return out


def unique_inverse(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """np.unique(x, return_inverse=True) of a 1-D integer array (same sort, same results) without
    np.unique's generic wrapping (the tracker makes several a frame)."""
    perm = x.argsort(kind="stable")  # (any order of equal keys gives the same result; timsort is
    aux = x[perm]                    # cheaper on these partly ordered keys)
    mask = np.empty(len(aux), bool)
    mask[:1] = True
    np.not_equal(aux[1:], aux[:-1], out=mask[1:])
    inv = np.empty(len(aux), np.intp)
    inv[perm] = mask.cumsum() - 1
    return aux[mask], inv


def is_in(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """np.isin(x, y) of integer arrays (the same mask) by a sorted search, without np.isin's
    generic path (the brush paths ask several a frame, of a few hundred ids)."""
    y = np.sort(np.ravel(y))
    if len(y) == 0:
        return np.zeros(np.shape(x), bool)
    return y[np.minimum(np.searchsorted(y, x), len(y) - 1)] == x


def first_max_per_group(group: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """For entries sorted by `group` (runs of equal values, non-empty): the index of the first
    entry of each group holding the group's maximum weight (ties: the earliest), in group order.
    The sorted-input form of a (group, -weight, position) lexsort, without the sort."""
    new = join_arrays(True, group[1:] != group[:-1])
    top = np.maximum.reduceat(weight, np.flatnonzero(new))[np.cumsum(new) - 1]
    cand = np.flatnonzero(weight == top)
    return cand[join_arrays(True, group[cand][1:] != group[cand][:-1])]


def assign_ids(n_strokes: int, cand_stroke: np.ndarray, cand_id: np.ndarray, cand_w: np.ndarray,
               next_id: int, min_w: float = 0.0) -> tuple[np.ndarray, int]:
    """Greedy one-to-one assignment of previous ids to new strokes by matched length: the
    heaviest (stroke, id) pair first (weights rounded to 9 decimals; ties: lower stroke index,
    then lower id); each id and each stroke used once. Strokes left without an id get fresh ids
    next_id, next_id+1, ... in stroke order. Returns (ids (S,), new next_id)."""
    keep = cand_w >= max(min_w, 1e-12)
    cs, ci, cw = cand_stroke[keep].astype(np.int64), cand_id[keep].astype(np.int64), cand_w[keep]
    order = np.lexsort((ci, cs, -np.round(cw, 9)))
    ids, next_id = kernels().greedy_ids(order, cs, ci, n_strokes, next_id)
    return ids, int(next_id)


def end_samples(prev: Strokes) -> Samples:
    """Both ends of every stroke of `prev` (starts, then ends) as samples: surface point, tangent
    into the stroke, id (for snap_boundaries)."""
    first, last = prev.offsets[:-1], prev.offsets[1:] - 1
    P, X = prev.points, prev.surface
    e_pt = join_arrays(first, last)
    e_nb = join_arrays(np.minimum(first + 1, last), np.maximum(last - 1, first))
    t = P.take(e_nb, axis=0) - P.take(e_pt, axis=0)
    t = t / np.maximum(row_norm(t), 1e-12)[:, None]
    n = len(e_pt)
    return Samples(p=P.take(e_pt, axis=0), X=X.take(e_pt, axis=0), u=np.zeros(n), t=t, ids=join_arrays(prev.ids, prev.ids),
                   stroke=np.zeros(n, np.int64), s=np.zeros(n), w=np.ones(n))


def snap_boundaries(prev: Strokes, camera, dense: Samples, r_stroke, r_s0, r_s1, r_label, radius_px: float,
                    min_tangent_dot: float, tol_px: float, dense_tree=None, ends_match=None):
    """Move every cut between two runs of one stroke (labels A | B) to where an end of the previous
    frame's stroke A or B projects on the new stroke (both ends found: their mean), when that is
    within `tol_px` of the cut. The end points are matched like the votes (projected with
    `camera`, nearest dense sample within `radius_px` with agreeing tangent, refined along its
    tangent). `ends_match`: (end_samples(prev), match, projected) when the caller already matched
    them against `dense` (as match_samples(..., k=4, return_projected=True) would).
    Returns new (s0, s1) per run; runs keep at least 1e-3 px."""
    inner = np.flatnonzero((r_stroke[1:] == r_stroke[:-1]) & (r_label[1:] >= 0) & (r_label[:-1] >= 0))
    if len(inner) == 0 or len(prev) == 0 or len(dense) == 0:
        return r_s0, r_s1
    if ends_match is not None:
        ends, m, q = ends_match
    else:
        ends = end_samples(prev)
        m, q = match_samples(ends, camera, dense, dense_tree, radius_px=radius_px, min_tangent_dot=min_tangent_dot,
                             k=4, return_projected=True)
    hit = np.flatnonzero(m >= 0)
    if len(hit) == 0:
        return r_s0, r_s1
    mh = m[hit]
    es = dense.s[mh] + np.clip(np.einsum("ij,ij->i", q.take(hit, axis=0) - dense.p.take(mh, axis=0), dense.t.take(mh, axis=0)),
                               -0.5 * dense.w[mh], 0.5 * dense.w[mh])
    est, eid = dense.stroke[mh], ends.ids[hit]
    M = int(max(eid.max(), r_label.max())) + 1
    ekey = est.astype(np.int64) * M + eid
    o = np.argsort(ekey, kind="stable")
    ekey, es = ekey[o], es[o]
    cut = r_s1[inner]
    # Both labels of every cut searched at once (keys of the left run, then of the right run).
    n = len(inner)
    sk = r_stroke[inner].astype(np.int64) * M
    key = join_arrays(sk + r_label[inner], sk + r_label[inner + 1])
    lo = np.searchsorted(ekey, key, "left")
    hi = np.searchsorted(ekey, key, "right")
    cut2 = join_arrays(cut, cut)
    val, hit2 = [], []
    for k in range(2):  # an old stroke has two ends: at most two candidates per key
        j = lo + k
        ok = j < hi
        jj = np.minimum(j, len(es) - 1)
        ok &= np.abs(es[jj] - cut2) <= tol_px
        val.append(np.where(ok, es[jj], 0.0))
        hit2.append(ok)
    # Summed in the order of one label at a time, candidate 0 then 1 (es >= +0, so the sum from
    # zero starts exactly at the first term).
    acc = ((val[0][:n] + val[1][:n]) + val[0][n:]) + val[1][n:]
    cnt = ((hit2[0][:n].astype(float) + hit2[1][:n]) + hit2[0][n:]) + hit2[1][n:]
    new = np.where(cnt > 0, acc / np.maximum(cnt, 1), cut)
    # Keep both runs non-empty.
    new = np.clip(new, r_s0[inner] + 1e-3, r_s1[inner + 1] - 1e-3)
    new = np.where(r_s0[inner] + 1e-3 < r_s1[inner + 1] - 1e-3, new, cut)
    s0, s1 = r_s0.copy(), r_s1.copy()
    s1[inner] = new
    s0[inner + 1] = new
    return s0, s1


def sample_labels(D: int, vm: np.ndarray, vid: np.ndarray, w: np.ndarray) -> np.ndarray:
    """(D,) the carried id of every one of D samples (-1: no vote on it): the id of most vote
    weight (votes: vm (V,) the sample each lands on, vid (V,) its id, w (V,) its weight; ties:
    the lower id). Summed, not the single heaviest vote: where parallel contour pieces run 1-3 px
    apart, a sample gets votes of its own line and a stray one of the neighbour line. (Sums
    rounded to 9 decimals: their last bits depend on the order of the votes, a tie must not.)"""
    if len(vm) == 0:
        return np.full(D, -1, np.int64)
    M = int(vid.max()) + 1
    key = np.asarray(vm, np.int64) * M + vid
    return kernels().vote_labels(D, key.argsort(kind="stable"), key, M, np.asarray(w, float))


def segment_by_votes(dense: Samples, lengths: np.ndarray, vm: np.ndarray, vid: np.ndarray, w: np.ndarray,
                     min_segment_px: float):
    """Cut the strokes sampled by `dense` (in stroke order; lengths (S,) px) into runs of the same
    carried id. vm (V,) dense sample hit by each vote, vid (V,) its carried id, w (V,) its weight.
    A sample is labelled with the id of most vote weight on it (sample_labels); samples without a
    vote take the label of the nearest voted sample of their stroke; runs shorter than
    `min_segment_px` (except the longest of a stroke) are absorbed by neighbours.
    Returns run (D,) run of each dense sample, and per run: stroke, s0, s1 (px), label (carried
    id, -1 where the stroke had no vote)."""
    return kernels().segment_runs(sample_labels(len(dense), vm, vid, w), dense.stroke, dense.s, dense.w,
                                  np.asarray(lengths, float), float(min_segment_px))
