"""The numpy forms of the compiled steps the tracker and the brush paths share: the oracles the
tests hold the kernels against, to the bit (the code the kernels replaced). Not used by the
library."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from strokekit.lines.strokeops import join_arrays
from strokekit.model import Strokes, bracket, row_norm, uclip
from strokekit.sampling import Samples, surface_between
from strokekit.tracking.joins import GatheredPaths, _close_pair_arrays, _straightest_order
from strokekit.tracking.options import TrackingOptions
from strokekit.tracking.ufit import solve_banded
from strokekit.tracking.votes import first_max_per_group, unique_inverse, unwrap_loop_votes


def drop_hairpins(strokes: Strokes, angle_deg: float, max_px: float, at: np.ndarray | None = None,
                  return_kept: bool = False):
    """Strokes less the points where the line turns by more than `angle_deg` beside a segment of
    at most `max_px` (px): the sub-pixel back-and-forth where two strands that overlap at their
    ends were joined (one ends 0.1 px past where the next begins; a ribbon folds there). The
    chaining splits at such turns, so only joints have them: `at` (point indices), when given,
    are the only points looked at (the joints and their neighbours). Ends are kept; of two
    neighbouring such points the first goes, then the rest are looked at again. The same object
    when there is nothing to drop. return_kept: also the (N,) mask of the points kept."""
    cos_max = np.cos(np.radians(angle_deg))
    P = strokes.points
    n = len(P)
    if n < 3 or max_px <= 0:
        return (strokes, np.ones(n, bool)) if return_kept else strokes
    ends, i = hairpin_candidates(strokes, at)
    alive = np.ones(n, bool)
    live = None  # indices of the points still there, once some are dropped
    for _ in range(8):
        if len(i) == 0:
            break
        # Neighbours among the points still there (ends are never dropped: they stay in-stroke).
        if live is None:  # (none dropped yet: the neighbours are the next points)
            k, prv, nxt = i, P[i - 1], P[i + 1]
        else:
            k = np.searchsorted(live, i)
            prv, nxt = P[live[k - 1]], P[live[k + 1]]
        Pi = P[i]
        a, b = Pi - prv, nxt - Pi
        la, lb, dot = np.einsum("ij,ij->i", a, a), np.einsum("ij,ij->i", b, b), np.einsum("ij,ij->i", a, b)
        bad = (np.minimum(la, lb) <= max_px * max_px) & (la > 0) & (lb > 0) & (dot < cos_max * np.sqrt(la * lb))
        if not bad.any():
            break
        # Of neighbouring candidates (next to each other among the live points) the first goes.
        kc = k[bad]
        first = join_arrays(True, np.diff(kc) > 1)
        cand, kc = i[bad][first], kc[first]
        # The fold can move to a neighbour of a dropped point: look at those too.
        if live is None:
            near = np.concatenate([cand - 1, cand + 1])
        else:
            near = np.concatenate([live[kc - 1], live[np.minimum(kc + 1, len(live) - 1)]])
        alive[cand] = False
        live = np.flatnonzero(alive)
        i = sorted_unique(np.concatenate([i[alive[i]], near[alive[near] & ~ends[near]]]))
    out = strokes if alive.all() else keep_points(strokes, alive)
    return (out, alive) if return_kept else out


def hairpin_candidates(strokes: Strokes, at: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """drop_hairpins' (N,) stroke ends and the sorted interior points it looks at (all, or those
    of `at`)."""
    n = len(strokes.points)
    ends = np.zeros(n, bool)
    full = np.flatnonzero(np.diff(strokes.offsets) > 0)  # (an empty stroke has no ends)
    ends[strokes.offsets[:-1][full]] = True
    ends[strokes.offsets[1:][full] - 1] = True
    i = np.arange(1, n - 1) if at is None else sorted_unique(np.asarray(at, np.int64))
    i = i[(i > 0) & (i < n - 1)]
    return ends, i[~ends[i]]  # interior points only (never a stroke's first or last)


def keep_points(strokes: Strokes, alive: np.ndarray) -> Strokes:
    """The strokes with only their points where `alive` (N,) is true (every stroke keeps one)."""
    gone = np.flatnonzero(~alive)
    counts = np.diff(strokes.offsets) - np.bincount(np.searchsorted(strokes.offsets, gone, side="right") - 1,
                                                    minlength=len(strokes))
    kept = np.flatnonzero(alive)  # (take: a boolean mask over (N, 2) rows is ~4x slower, same values)
    return replace(strokes, points=strokes.points.take(kept, axis=0), surface=strokes.surface.take(kept, axis=0),
                   face=strokes.face.take(kept), u=None if strokes.u is None else strokes.u.take(kept),
                   offsets=np.r_[0, np.cumsum(counts)].astype(np.int64))


def sorted_unique(x: np.ndarray) -> np.ndarray:
    """np.unique of a small 1-D integer array by a sort (numpy's hash-based unique costs ~15 us)."""
    x = np.sort(x)
    return x[join_arrays(True, x[1:] != x[:-1])] if len(x) else x


def u_trend(run: np.ndarray, vid: np.ndarray, label: np.ndarray, pos: np.ndarray, u: np.ndarray,
             R: int) -> np.ndarray:
    """(R,) px of every run along which the carried u increases, less the px along which it
    decreases: the votes that carry the run's own id (`label`), in order of their position `pos`
    (px along the new stroke), each step counted by its length with the sign of its du. A step
    across the seam of an old loop (u jumps back by the loop) counts for its length only."""
    keep = np.flatnonzero(vid == label.take(run))
    if len(keep) < 2:
        return np.zeros(R)
    rk, pk = run.take(keep), pos.take(keep)
    pk = pk - pk.min()
    o = np.argsort(rk * (pk.max() + 1.0) + pk, kind="stable")  # by run, then position
    rq = rk.take(o)
    same = rq[1:] == rq[:-1]
    step = np.where(same, np.sign(np.diff(u.take(keep).take(o))) * np.diff(pk.take(o)), 0.0)
    return np.bincount(rq[1:], weights=step, minlength=R)


def _segment_sums(idx: np.ndarray, n: int, *weights) -> list[np.ndarray]:
    return [np.bincount(idx, weights=w, minlength=n) for w in weights]


def assign_ids(n_strokes: int, cand_stroke: np.ndarray, cand_id: np.ndarray, cand_w: np.ndarray,
               next_id: int, min_w: float = 0.0) -> tuple[np.ndarray, int]:
    """Greedy one-to-one assignment of previous ids to new strokes by matched length: the
    heaviest (stroke, id) pair first (ties: lower stroke index, then lower id); each id and each
    stroke used once. Strokes left without an id get fresh ids next_id, next_id+1, ... in stroke
    order. Returns (ids (S,), new next_id)."""
    ids = np.full(n_strokes, -1, np.int64)
    keep = cand_w >= max(min_w, 1e-12)
    cs, ci, cw = cand_stroke[keep], cand_id[keep], cand_w[keep]
    # Rank of every pair in the greedy order (heaviest first; ties: lower stroke, lower id).
    order = np.lexsort((ci, cs, -np.round(cw, 9)))
    rank = np.empty(len(order), np.int64)
    rank[order] = np.arange(len(order))
    alive = np.ones(len(cs), bool)
    # Ids as 0..n_ids-1 (so that both sides index flat arrays).
    _, cinv = unique_inverse(ci)
    n_ids = int(cinv.max()) + 1 if len(cinv) else 0
    used_s = np.zeros(n_strokes, bool)
    used_i = np.zeros(n_ids, bool)
    big = int(np.iinfo(np.int64).max)
    # Pairs that come first for both their stroke and their id are exactly the ones the greedy
    # pass takes; take them all, drop what they exclude, repeat (a few rounds, all vectorized).
    while alive.any():
        idx = np.flatnonzero(alive)
        ri, si, ii = rank[idx], cs[idx], cinv[idx]
        best_s = np.full(n_strokes, big)
        np.minimum.at(best_s, si, ri)
        best_i = np.full(n_ids, big)
        np.minimum.at(best_i, ii, ri)
        take = idx[(best_s[si] == ri) & (best_i[ii] == ri)]
        ids[cs[take]] = ci[take]
        used_s[cs[take]] = True
        used_i[cinv[take]] = True
        alive &= ~used_s[cs] & ~used_i[cinv]
    fresh = np.flatnonzero(ids < 0)
    ids[fresh] = next_id + np.arange(len(fresh))
    return ids, next_id + len(fresh)


def sample_labels(D: int, vm: np.ndarray, vid: np.ndarray, w: np.ndarray) -> np.ndarray:
    """(D,) the carried id of every one of D samples (-1: no vote on it): the id of most vote
    weight (votes: vm (V,) the sample each lands on, vid (V,) its id, w (V,) its weight)."""
    label = np.full(D, -1, np.int64)
    if len(vm):
        # The id with the most vote weight on a sample wins it (ties: the lower id). Summed, not
        # the single heaviest vote: where parallel contour pieces run 1-3 px apart, a sample gets
        # votes of its own line and a stray one of the neighbour line.
        M = int(vid.max()) + 1
        key, inv = unique_inverse(vm.astype(np.int64) * M + vid)
        # Rounded: a sum's last bits depend on the order of the votes, a tie must not.
        kw = np.round(np.bincount(inv.ravel(), weights=w), 9)
        ks, ki = key // M, key % M
        # Per sample the most weight, ties to the lower id: keys come sorted by (sample, id), so
        # that is the first key of its sample holding the sample's maximum (no sort needed; a
        # 3-key lexsort of ~1000 keys cost ~50 us).
        win = first_max_per_group(ks, kw)
        label[ks[win]] = ki[win]
    return label


def segment_by_votes(dense: Samples, lengths: np.ndarray, vm: np.ndarray, vid: np.ndarray, w: np.ndarray,
                     min_segment_px: float):
    """Cut the strokes sampled by `dense` (1 px samples, in stroke order; lengths (S,) px) into runs of the same
    carried id. vm (V,) dense sample hit by each vote, vid (V,) its carried id, w (V,) its weight.
    A sample is labelled with the id of most vote weight on it; samples without a vote take the
    label of the nearest voted sample of their stroke; runs shorter than `min_segment_px` (except
    the longest of a stroke) are absorbed by neighbours.
    Returns run (D,) run of each dense sample, and per run: stroke, s0, s1 (px), label (carried
    id, -1 where the stroke had no vote)."""
    D = len(dense)
    label = sample_labels(D, vm, vid, w)
    idx = np.arange(D)
    stroke, s = dense.stroke, dense.s

    def fill(lab):
        known = lab >= 0
        f = np.maximum.accumulate(np.where(known, idx, -1))
        b = np.minimum.accumulate(np.where(known, idx, D)[::-1])[::-1]
        f0, b0 = np.maximum(f, 0), np.minimum(b, D - 1)  # clamped once, used thrice
        fok = (f >= 0) & (stroke[f0] == stroke)
        bok = (b < D) & (stroke[b0] == stroke)
        df = np.where(fok, s - s[f0], np.inf)
        db = np.where(bok, s[b0] - s, np.inf)
        out = np.where(df <= db, lab[f0], lab[b0])
        return np.where(fok | bok, out, -1)

    def runs(lab):
        start = join_arrays(True, (lab[1:] != lab[:-1]) | (stroke[1:] != stroke[:-1])) if D else np.zeros(0, bool)
        r = np.cumsum(start) - 1
        return r, np.bincount(r, weights=dense.w) if D else np.zeros(0)

    lab = fill(label)
    done = None  # (r, rl) of the final labels when the loop already has them
    for _ in range(4):
        r, rl = runs(lab)
        if len(rl) == 0:
            break
        rfirst = np.flatnonzero(join_arrays(True, r[1:] != r[:-1]))
        rs = stroke[rfirst]
        longest = np.zeros(len(rl), bool)
        o = np.lexsort((-rl, rs))
        longest[o[join_arrays(True, rs[o][1:] != rs[o][:-1])]] = True
        short = (rl < min_segment_px) & ~longest & (lab[rfirst] >= 0)
        if not short.any():
            done = r, rl
            break
        lab = fill(np.where(short[r], -1, lab))
    r, rl = done if done is not None else runs(lab)
    first = np.flatnonzero(join_arrays(True, r[1:] != r[:-1])) if D else np.zeros(0, np.int64)
    last = join_arrays(first[1:] - 1, D - 1) if D else np.zeros(0, np.int64)
    rs = stroke[first]
    head = join_arrays(True, rs[1:] != rs[:-1]) if D else np.zeros(0, bool)
    tail = join_arrays(rs[1:] != rs[:-1], True) if D else np.zeros(0, bool)
    # Runs meet halfway between their samples; strokes are covered from 0 to their length.
    s0 = np.where(head, 0.0, 0.5 * (s[first] + s[np.maximum(first - 1, 0)]))
    s1 = np.where(tail, lengths[rs], 0.5 * (s[last] + s[np.minimum(last + 1, D - 1)]))
    return r, rs, s0, s1, lab[first]


class PiecewiseU:
    """u along every stroke as a piecewise-linear function of arc length, knots every ~`knot_px`
    px (n_s = ceil(L_s / knot_px) equal intervals per stroke), solved for all strokes at once as
    one sparse least-squares problem (block diagonal)."""

    def __init__(self, lengths: np.ndarray, knot_px: float):
        self.L = np.asarray(lengths, float)
        self.n = np.maximum(1, np.ceil(self.L / knot_px - 1e-9)).astype(np.int64)
        self.h = self.L / self.n
        self.base = join_arrays(0, np.cumsum(self.n + 1)).astype(np.int64)  # first knot of each stroke

    def inner_knot_stroke(self) -> np.ndarray:
        return np.repeat(np.arange(len(self.L)), self.n - 1)

    def inner_knot_s(self) -> np.ndarray:
        st = self.inner_knot_stroke()
        j = np.arange(len(st)) - np.repeat(join_arrays(0, np.cumsum(self.n - 1)[:-1]), self.n - 1) + 1
        return j * self.h[st]

    def _interval(self, st, s):
        # Cached for the last (st, s) pair: the fit and the evaluation at the votes share it.
        c = self.__dict__.get("_iv")
        if c is not None and c[0] is st and c[1] is s:
            return c[2], c[3]
        h = self.h[st]
        hp = h > 0
        x = np.where(hp, s / np.where(hp, h, 1.0), 0.0)
        j = uclip(np.floor(x), 0, self.n[st] - 1).astype(np.int64)
        k, a = self.base[st] + j, uclip(x - j, 0.0, 1.0)
        self._iv = (st, s, k, a)
        return k, a

    def eval(self, knots: np.ndarray, st: np.ndarray, s: np.ndarray) -> np.ndarray:
        k, a = self._interval(st, s)
        return knots[k] * (1 - a) + knots[k + 1] * a

    @staticmethod
    def _terms(nk, cols, vals, y, rows):
        """Normal-equation terms of residuals sum_a vals[a] x[cols[a]] - y (weights already in
        vals and y), appended to rows[band row] (rows[3]: the right-hand side) in the order they
        are added; y None: a zero right-hand side (its terms are +0.0 everywhere: adding them
        changes nothing, they are left out)."""
        m = len(cols)
        for a_ in range(m):
            rows[0].append(np.bincount(cols[a_], vals[a_] * vals[a_], minlength=nk))
            if y is not None:
                rows[3].append(np.bincount(cols[a_], vals[a_] * y, minlength=nk))
            for b_ in range(a_ + 1, m):
                rows[b_ - a_].append(np.bincount(cols[a_], vals[a_] * vals[b_], minlength=nk))
        return rows

    #: Terms the votes add to each band row (0, 1, 2) and to the right-hand side (3), first.
    _VOTE_TERMS = (2, 1, 0, 2)

    def _fixed_terms(self, prior_a, prior_b, b0, stretch_weight, bend_weight):
        """The terms that do not depend on the votes (stretch, bend, anchor), cached for the
        same arguments (the tracker fits twice with the same prior, dropping outliers): per band
        row and right-hand side a (vote terms + fixed terms, nk) buffer whose first rows the
        fit fills with its vote terms (see fit)."""
        key = (prior_a, prior_b, b0, stretch_weight, bend_weight)
        c = self.__dict__.get("_fixed")
        if c is not None and all(x is y or (not isinstance(x, np.ndarray) and x == y) for x, y in zip(c[0], key)):
            return c[1]
        nk = int(self.base[-1])
        S = len(self.L)
        # Each term adds at distinct knots (the intervals, inner knots and knots are distinct):
        # its np.bincount is its values set at those knots over zeros (the one difference, a
        # -0.0 product, adds to a sum that never is -0.0, as it starts with a vote term:
        # nothing changes). Written straight into the buffers, in _terms' order:
        # row 0: stretch aa, bb, bend aa, bb, cc, anchor; row 1: stretch ab, bend ab, bc;
        # row 2: bend ac; right-hand side: stretch ay, by, anchor (bend: zero, left out).
        nv0, nv1, nv2, nv3 = self._VOTE_TERMS
        b0_, b1_, b2_, b3_ = (np.zeros((nv0 + 6, nk)), np.zeros((nv1 + 3, nk)), np.zeros((nv2 + 1, nk)),
                              np.zeros((nv3 + 3, nk)))
        # stretch, per interval
        js = np.arange(S).repeat(self.n)
        cn = self.n.cumsum()
        kk = self.base[js] + (np.arange(cn[-1] if S else 0) - (cn - self.n).repeat(self.n))
        hs = self.h[js]
        hh = np.maximum(hs, 1.0)
        ws = np.sqrt(stretch_weight / hh)
        va, vb, y = -ws, ws, ws * hs * b0
        b0_[nv0, kk] = va * va
        b3_[nv3, kk] = va * y
        b1_[nv1, kk] = va * vb
        b0_[nv0 + 1, kk + 1] = vb * vb
        b3_[nv3 + 1, kk + 1] = vb * y
        # bend, per inner knot (strokes with >= 2 intervals)
        inner = np.flatnonzero(self.n[js] >= 2)
        jb = kk[inner]
        last_interval = jb + 1 >= self.base[js[inner]] + self.n[js[inner]]
        jb, sb = jb[~last_interval], js[inner][~last_interval]
        wb = np.sqrt(bend_weight * np.maximum(self.L[sb], 1.0))
        va, vb, vc = wb, -2 * wb, wb
        b0_[nv0 + 2, jb] = va * va
        b1_[nv1 + 1, jb] = va * vb
        b2_[nv2, jb] = va * vc
        b0_[nv0 + 3, jb + 1] = vb * vb
        b1_[nv1 + 2, jb + 1] = vb * vc
        b0_[nv0 + 4, jb + 2] = vc * vc
        # weak anchor to the line fit
        ks = np.arange(S).repeat(self.n + 1)
        sk = (np.arange(nk) - self.base[ks]) * self.h[ks]
        we = np.full(nk, 1e-3)
        b0_[nv0 + 5] = we * we
        b3_[nv3 + 2] = we * (1e-3 * (prior_a[ks] + prior_b[ks] * sk))
        bufs = [b0_, b1_, b2_, b3_]
        self._fixed = (key, bufs)
        return bufs

    def fit(self, st, s, u, w, prior_a, prior_b, b0, stretch_weight, bend_weight, band_terms=None) -> np.ndarray:
        """Knot values minimizing sum w (u(s) - u)^2 (votes) + stretch_weight / h (du - h b0)^2
        per interval (slope close to the nominal b0 = 1/P) +
        bend_weight L (second difference)^2 per inner knot (even stretch) + 1e-6 (knot - prior)^2
        (the line fit a + b s; fixes strokes without votes). `band_terms(k, a, w, u, f0, f1, f2,
        f3) -> (band, rhs)`: the normal equations summed by another implementation of the steps
        below (the brush path stage's compiled one; f_r: the fixed terms' rows)."""
        nk = int(self.base[-1])
        # Normal equations accumulated straight into the 3 lower bands of a symmetric banded
        # matrix (every residual touches at most 3 consecutive knots of one stroke), in a fixed
        # order: votes, stretch, bend, anchor. Each band row is the sum of its terms in that
        # order: the terms stacked in one buffer and summed along it (np.add.reduce over the
        # first axis adds the rows one after the other, elementwise: the same sums as adding
        # the terms one by one into zeros, whose first addition is exact).
        k, a = self._interval(st, s)
        bufs = self._fixed_terms(prior_a, prior_b, b0, stretch_weight, bend_weight)
        if band_terms is not None and nk > 0:
            band, rhs = band_terms(k, a, w, u, *(b[n:] for b, n in zip(bufs, self._VOTE_TERMS)))
        else:
            sw = np.sqrt(w)
            votes = self._terms(nk, [k, k + 1], [sw * (1 - a), sw * a], sw * u, ([], [], [], []))
            band = np.empty((3, nk))
            for r in range(3):  # (every buffer holds 1+ terms: each term is added for every stroke)
                np.add.reduce(_fill_rows(bufs[r], votes[r]), axis=0, out=band[r])
            rhs = np.add.reduce(_fill_rows(bufs[3], votes[3]), axis=0)
        band[1, -1:] = 0.0
        band[2, -2:] = 0.0
        if nk == 0:
            from scipy.linalg import solveh_banded

            return solveh_banded(band, rhs, lower=True, check_finite=False)
        return solve_banded(band, rhs)


def _fill_rows(buf: np.ndarray, rows: list) -> np.ndarray:
    """buf with its first len(rows) rows set to `rows`."""
    for i, t in enumerate(rows):
        buf[i] = t
    return buf


def fit_u(prev: Strokes, cur: Strokes, st: np.ndarray, s: np.ndarray, u: np.ndarray, vid: np.ndarray,
          w: np.ndarray, o: TrackingOptions, compiled=None):
    """u along the strokes `cur` fitted to the votes carried from `prev`: vote k lands on stroke
    st[k] at arc length s[k] (px) with u[k] (periods), carried id vid[k] and weight w[k]. Per
    stroke the votes of its primary id (most weight) set the fit, those of other ids join it
    shifted by whole periods; u is piecewise linear (knots every o.knot_spacing_px, inserted as
    points) or linear, outliers (o.outlier_px) dropped and the fit redone. Returns (cur with the
    knots inserted, u at its points, the slope du/ds per stroke, and the vote groups (stroke,
    id, inlier weight) that assign_ids takes). `compiled`: other implementations of the linear fit
    (`line_fit`), of the piecewise fit's sums (`band_terms`, see PiecewiseU.fit) and of
    insert_points (`insert_points`): the brush path stage's compiled ones."""
    P = cur.period_px
    S = len(cur)
    L = cur.lengths
    # Vote groups: (stroke, carried id).
    if len(st):
        M = int(vid.max()) + 1
        key = st.astype(np.int64) * M + vid  # (stroke, id) as one integer
        ukey, ginv = unique_inverse(key)
        gkeys = np.empty((len(ukey), 2), np.int64)
        np.floor_divide(ukey, M, out=gkeys[:, 0])
        np.remainder(ukey, M, out=gkeys[:, 1])
        gw = np.bincount(ginv, weights=w)
    else:
        gkeys, ginv, gw = np.zeros((0, 2), np.int64), np.zeros(0, np.int64), np.zeros(0)
    if len(st):
        u = unwrap_loop_votes(prev, u, vid, s, ginv, w, P, o.vote_spacing_px)
    # Primary group per stroke: most matched length, ties to the lower id. gkeys come sorted
    # by (stroke, id): the first group of a stroke holding the stroke's maximum (no sort).
    primary = np.zeros(len(gw), bool)
    if len(gw):
        primary[first_max_per_group(gkeys[:, 0], gw)] = True
    b0 = 1.0 / P
    lam = o.stretch_weight * P * P * L  # see TrackingOptions.stretch_weight

    def fit(mask):
        if compiled is not None:
            return compiled.line_fit(st, s, u, w, mask, lam, b0)
        w_ = w * mask
        S0, S1, S2, T0, T1 = _segment_sums(st, S, w_, w_ * s, w_ * s * s, w_ * u, w_ * s * u)
        A11, A12, A22 = S0, S1, S2 + lam
        R1, R2 = T0, T1 + lam * b0
        det = A11 * A22 - A12 * A12
        ok = (S0 > 0) & (det > 1e-12 * np.maximum(A11 * A22, 1e-300))
        a = np.where(ok, (R1 * A22 - A12 * R2) / np.where(ok, det, 1), 0.0)
        b = np.where(ok, (A11 * R2 - A12 * R1) / np.where(ok, det, 1), b0)
        return a, b, ok

    if len(st):
        a, b, ok = fit(primary[ginv].astype(float))
        # Other groups join the primary one shifted by whole periods (periodic texture).
        res = u - (a[st] + b[st] * s)
        shift = np.round(np.bincount(ginv, weights=w * res, minlength=len(gw)) / np.maximum(gw, 1e-12))
        shift[primary] = 0
        u = u - shift[ginv]
        a, b, ok = fit(np.ones(len(st)))
        inlier = np.ones(len(st))
        if o.knot_spacing_px > 0:
            # Piecewise-linear u (knots every ~knot_spacing_px): follows uneven stretch
            # (perspective, edges of a loop growing at different rates) without sliding.
            pw = PiecewiseU(L, o.knot_spacing_px)
            for _ in range(2):
                knots = pw.fit(st, s, u, w * inlier, a, b, b0, o.stretch_weight * P * P, o.bend_weight,
                               None if compiled is None else compiled.band_terms)
                inlier = (np.abs(u - pw.eval(knots, st, s)) * P <= o.outlier_px).astype(float)
        else:
            inlier = (np.abs(u - (a[st] + b[st] * s)) * P <= o.outlier_px).astype(float)
            a2, b2, ok2 = fit(inlier)
            a, b, ok = np.where(ok2, a2, a), np.where(ok2, b2, b), ok | ok2
        gw_in = np.bincount(ginv, weights=w * inlier, minlength=len(gw))
        cand_s, cand_i, cand_w = gkeys[:, 0], gkeys[:, 1], gw_in
    else:
        a, b, ok = np.zeros(S), np.full(S, b0), np.zeros(S, bool)
        cand_s = cand_i = np.zeros(0, np.int64)
        cand_w = np.zeros(0)
    b = np.where(ok, np.maximum(b, 1e-3 * b0), b0)  # never fold the texture back
    sop = cur.stroke_of_point
    if len(st) and o.knot_spacing_px > 0:
        # u is interpolated linearly between points downstream: give it the knots as points.
        cur = (insert_points if compiled is None else compiled.insert_points)(cur, pw.inner_knot_stroke(),
                                                                              pw.inner_knot_s())
        sop = cur.stroke_of_point
        u_new = pw.eval(knots, sop, cur.arc_length)
        b = np.where((L > 0) & ok, (knots[pw.base[1:] - 1] - knots[pw.base[:-1]]) / np.maximum(L, 1e-9), b)
    else:
        u_new = a[sop] + b[sop] * cur.arc_length
    return cur, u_new, b, (cand_s, cand_i, cand_w)


def insert_points(strokes: Strokes, stroke: np.ndarray, s: np.ndarray) -> Strokes:
    """Strokes with extra points at arc lengths s (px) of strokes `stroke` (same polylines; the
    new points interpolate position and surface point). Points closer than 1e-6 px to an existing
    point are not added."""
    if len(stroke) == 0:
        return strokes
    offsets = strokes.offsets
    base, G = strokes.global_arc
    g = base[stroke] + np.asarray(s, float)
    first = offsets[:-1][stroke]
    last = offsets[1:][stroke] - 1
    i, j = bracket(G, G.searchsorted(g, side="right"), first, last)
    Gi, Gj = G[i], G[j]
    keep = ((Gj - Gi > 0) & (g - Gi > 1e-6) & (Gj - g > 1e-6)).nonzero()[0]
    i, j, g, stroke, Gi, Gj = i[keep], j[keep], g[keep], stroke[keep], Gi[keep], Gj[keep]
    if len(i) == 0:
        return strokes
    a = ((g - Gi) / (Gj - Gi))[:, None]
    # take(axis=0) for row gathers: numpy's fancy indexing of (N, 2) / (N, 3) rows is ~8x slower
    # on arrays of a frame's size (same values).
    P = np.concatenate([strokes.points, strokes.points.take(i, axis=0) * (1 - a) + strokes.points.take(j, axis=0) * a])
    X = np.concatenate([strokes.surface, surface_between(strokes, i, j, a[:, 0])])
    F = np.concatenate([strokes.face, np.where(a[:, 0] < 0.5, strokes.face[i], strokes.face[j])])
    U = np.concatenate([strokes.u, strokes.u[i] * (1 - a[:, 0]) + strokes.u[j] * a[:, 0]])
    # Sort by (stroke, arc); an old point precedes a new point at the same place. The global arc
    # coordinate alone orders the strokes (a 1 px gap between them), and old points come first in
    # allg: a stable sort of allg is that order (~4x cheaper than the 3-key lexsort it replaces).
    order = np.concatenate((G, g)).argsort(kind="stable")
    # Points per stroke: the old counts plus the new points of each stroke.
    counts = (offsets[1:] - offsets[:-1]) + np.bincount(stroke, minlength=len(strokes))
    return strokes.replace(points=P.take(order, axis=0), surface=X.take(order, axis=0), face=F[order], u=U[order],
                   offsets=np.concatenate(((0,), counts.cumsum())).astype(np.int64))


def touching_paths(strokes: Strokes, tol_px: float, angle_deg: float, label: np.ndarray | None = None,
                    other_tol_px: float | None = None, bridge_ok=None, free_px: float = 2.0,
                    weight: np.ndarray | None = None, link=None):
    """_join_segments(strokes, arange(S), zeros(S), lengths, zeros(S), ones(S), tol_px, angle_deg,
    straightest_first=True), the call chain_touching makes, specialized (same group, rev, pos): every
    run is a whole stroke, all labels agree and all signs are +1, so the label healing is moot, the
    ends are the open strokes' first and last points and a path is reversed when most of its
    strokes are entered at their end. The tracker runs it on every frame (~200 strokes): the
    per-member bookkeeping of the walk is done with numpy after a bare Python walk.

    `label` (S,) (the brush paths): strokes of two different labels >= 0 never join; two of one
    label join within tol_px, a stroke of label -1 (no label) joins any within `other_tol_px`
    (default tol_px); links within one label are taken first, then those to an unlabelled stroke,
    then between unlabelled strokes; within each, the cheapest first (the gap plus 10 px per radian
    of turn), then of the heaviest stroke (the larger `weight` (S,) of the two, default their
    lengths): at a junction of shingles the straight continuation wins over a turn onto a longer
    piece (120-frame orbits, M1: bunny +0.0004, rocker-arm +0.0015). `bridge_ok(pa, pb) -> (K,) bool`: where two ends are more
    than `free_px` apart, they join only where it says the bridge between them may be drawn.
    `link(a, b, e_run, n, S) -> (group, rev, pos)`: the links taken and walked into paths by
    another implementation of the steps below (the brush path stage's compiled one)."""
    S = len(strokes)
    group = np.arange(S)
    rev = np.zeros(S, bool)
    pos = np.zeros(S, np.int64)
    P = strokes.points
    first, last = strokes.offsets[:-1], strokes.offsets[1:] - 1
    closed = row_norm(P.take(first, axis=0) - P.take(last, axis=0)) < 1e-6
    op = np.flatnonzero(~closed)
    n = len(op)
    if 2 * n < 2:
        return group, rev, pos
    # Nodes: starts of the open strokes, then their ends (the order _join_segments uses).
    e_run = join_arrays(op, op)
    fo, lo = first[op], last[op]
    e_pt = join_arrays(fo, lo)
    nb = join_arrays(np.minimum(fo + 1, lo), np.maximum(lo - 1, fo))
    pt = P.take(e_pt, axis=0)
    d = P.take(nb, axis=0) - pt  # direction away from the end, into the stroke
    d = d / np.maximum(row_norm(d), 1e-12)[:, None]
    a, b = _close_pair_arrays(pt, tol_px if label is None or other_tol_px is None else max(tol_px, other_tol_px))
    if len(a) == 0:
        return group, rev, pos
    ok = (e_run[a] != e_run[b]) & (strokes.kind[e_run[a]] == strokes.kind[e_run[b]])
    dx, dy = d[:, 0], d[:, 1]
    straight = -(dx[a] * dx[b] + dy[a] * dy[b])  # cosine of the turn at the joint
    tier = None
    if label is None:
        ok &= straight >= np.cos(np.radians(angle_deg))
    else:
        la, lb = label[e_run[a]], label[e_run[b]]
        same = (la == lb) & (la >= 0)
        ok &= straight >= np.cos(np.radians(angle_deg))
        gap = row_norm(pt.take(a, axis=0) - pt.take(b, axis=0))
        other = tol_px if other_tol_px is None else other_tol_px
        ok &= (same & (gap <= tol_px)) | (((la < 0) | (lb < 0)) & (gap <= other))
        if bridge_ok is not None:
            far = np.flatnonzero(ok & (gap > free_px))
            if len(far):
                ok[far] = bridge_ok(pt.take(a[far], axis=0), pt.take(b[far], axis=0))
        tier = 2 * same + ((la < 0) != (lb < 0))
    if not ok.any():
        return group, rev, pos
    a, b, straight = a[ok], b[ok], straight[ok]
    # Greedy links in the order of _join_segments (straightest first; the pairs come in another
    # order than the k-d tree's, the sort decides). A node's code is 2 * stroke + end.
    if tier is None:
        o = _straightest_order(straight, e_run[a], e_run[b], S)
    else:
        wt = strokes.lengths if weight is None else weight
        heavy = np.maximum(wt[e_run[a]], wt[e_run[b]])
        # The cost of a link: its gap plus 10 px per radian of turn (seed 000's rule).
        cost = gap[ok] + 10.0 * np.arccos(np.clip(straight, -1.0, 1.0))
        o = np.lexsort((e_run[b], e_run[a], -np.round(heavy, 6), np.round(cost, 6), -tier[ok]))
    a, b = a[o], b[o]
    if link is not None:
        return link(a, b, e_run, n, S)
    code = 2 * e_run + (np.arange(2 * n) >= n)
    partner = np.full(2 * n, -1, np.int64)
    # A link whose two ends are in no other candidate link is taken whatever the order (most of
    # them): set at once; only links at junctions of 3+ ends go through the greedy pass.
    deg = np.bincount(join_arrays(a, b), minlength=2 * n)
    solo = (deg[a] == 1) & (deg[b] == 1)
    partner[a[solo]] = code[b[solo]]
    partner[b[solo]] = code[a[solo]]
    if not solo.all():
        # (The ends of these links are in no solo link: a set of the ends taken so far is all
        # the greedy pass needs.)
        taken, xs, ys = set(), [], []
        for x, y in zip(a[~solo].tolist(), b[~solo].tolist()):
            if x in taken or y in taken:
                continue
            taken.add(x)
            taken.add(y)
            xs.append(x)
            ys.append(y)
        partner[xs] = code[ys]
        partner[ys] = code[xs]
    # nxt[c]: code of the end linked to end c (-1: free); entering at c, one leaves at c ^ 1.
    nxt = np.full(2 * S, -1, np.int64)
    nxt[code] = partner
    linked = (nxt >= 0).reshape(S, 2)
    l0, l1 = linked[:, 0], linked[:, 1]
    runs = np.flatnonzero(l0 | l1)
    one = runs[l0[runs] != l1[runs]]
    nxt = nxt.tolist()
    walk, heads = [], []
    # Path starts: strokes with one linked end, entered through the free end, in stroke order. A
    # path (the links make paths and rings) runs from its start to its other end stroke, which
    # is the one start left to skip.
    done = set()
    for c in (2 * one + l0[one]).tolist():
        if c >> 1 in done:
            continue
        heads.append(len(walk))
        while True:
            walk.append(c)
            nc = nxt[c ^ 1]
            if nc < 0:
                break
            c = nc
        done.add(c >> 1)
    if len(walk) < len(runs):
        # Rings (linked strokes no path reached), entered through their start.
        seen = [False] * S
        for c in walk:
            seen[c >> 1] = True
        for c in (2 * runs).tolist():
            if seen[c >> 1]:
                continue
            heads.append(len(walk))
            while not seen[c >> 1]:
                seen[c >> 1] = True
                walk.append(c)
                c = nxt[c ^ 1]
                if c < 0:
                    break
    walk, heads = np.array(walk, np.int64), np.array(heads, np.int64)
    lens = np.diff(join_arrays(heads, len(walk)))
    path = np.repeat(np.arange(len(heads)), lens)
    k = np.arange(len(walk)) - heads[path]
    r, back = walk >> 1, (walk & 1).astype(bool)
    # A path goes backwards when more of its strokes are entered at their end (sum of signs < 0).
    flip = (2 * np.add.reduceat(walk & 1, heads) > lens)[path]
    group[r] = np.minimum.reduceat(r, heads)[path]
    rev[r] = back ^ flip
    pos[r] = np.where(flip, lens[path] - 1 - k, k)
    return group, rev, pos


def gather_paths(strokes: Strokes, group: np.ndarray, rev: np.ndarray, pos: np.ndarray) -> GatheredPaths:
    """The points of each path (group, rev, pos of touching_paths) in order, reversed strokes
    backwards; a joint point that repeats the previous one is dropped (a bridge, when the ends
    were apart, is kept)."""
    S = len(strokes)
    # (group, pos) pairs are distinct: one stable sort of group * S + pos is lexsort((pos, group)).
    order = (group * S + pos).argsort(kind="stable")
    offs = strokes.offsets
    start, counts = offs[:-1][order], (offs[1:] - offs[:-1])[order]
    csum = counts.cumsum()
    c0 = csum - counts  # where each stroke's points start in the gathered order
    # Point t of the gathered order: start + (t - c0), or start + count - 1 - (t - c0) reversed.
    t = np.arange(int(csum[-1]))
    ro = rev[order]
    src = np.where(ro.repeat(counts), (start + counts - 1 + c0).repeat(counts) - t, t + (start - c0).repeat(counts))
    g = group[order]
    new_g = np.concatenate(((True,), g[1:] != g[:-1]))
    joint = c0[~new_g]
    P = strokes.points
    drop = joint[row_norm(P.take(src[joint], axis=0) - P.take(src[joint - 1], axis=0)) < 1e-9]
    path = new_g.cumsum() - 1
    first = order[new_g]
    # Points per path: its strokes' points less the dropped joint points.
    n_path = np.bincount(path, weights=counts, minlength=len(first)).astype(np.int64) - np.bincount(
        path[c0.searchsorted(drop, side="right") - 1], minlength=len(first))
    if len(drop):
        keep = np.ones(len(src), bool)
        keep[drop] = False
        src = src[keep]
    return GatheredPaths(order, c0, src, new_g, joint, drop, path, first, n_path)
