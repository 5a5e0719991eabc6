"""The per-stroke fit of u: a piecewise-linear function of arc length fitted to the carried
votes, with a prior on its slope (1/P) and on bending, solved as one banded system per frame;
and the self-similar octave level that follows from its slope."""

from __future__ import annotations

import numpy as np
from numpy.linalg import LinAlgError

from strokekit.lines.strokeops import join_arrays
from strokekit.model import uclip
from strokekit.sampling import Samples


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


def local_slope(smp: Samples) -> np.ndarray:
    """du/ds (periods per px) at every sample, from its neighbours in the same stroke."""
    n = len(smp)
    if n < 2:
        return np.zeros(n)
    # The next (previous) sample where it is on the same stroke, else the sample itself.
    same = smp.stroke[1:] == smp.stroke[:-1]
    ar = np.arange(n)
    nxt = ar + np.concatenate((same, (False,)))
    prv = ar - np.concatenate(((False,), same))
    ds = smp.s[nxt] - smp.s[prv]
    return np.where(ds > 0, (smp.u[nxt] - smp.u[prv]) / np.where(ds > 0, ds, 1.0), 0.0)


def levels_from_slope(slope_periods_per_px: np.ndarray, period_px: float) -> tuple[np.ndarray, np.ndarray]:
    """Self-similar octave level and blend weight (see module doc) from du/ds per stroke."""
    c = np.log2(np.maximum(np.abs(slope_periods_per_px) * period_px, 1e-6))
    level = np.floor(c)
    return level, 1.0 - (c - level)


def solve_banded(band: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """The symmetric positive definite banded system (lower form, `band` (3, n)) solved for `rhs`
    (n,): scipy.linalg.solveh_banded without its checks and wrappers, the same LAPACK pbsv.
    `band` and `rhs` are overwritten."""
    from scipy.linalg.lapack import dpbsv

    _, x, info = dpbsv(band, rhs, lower=1, overwrite_ab=1, overwrite_b=1)
    if info > 0:
        raise LinAlgError(f"{info}th leading minor not positive definite")
    if info < 0:
        raise ValueError(f"illegal value in {-info}th argument of internal pbsv")
    return x
