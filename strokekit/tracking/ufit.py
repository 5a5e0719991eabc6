"""The per-stroke fit of u (`fit_u`): a piecewise-linear function of arc length fitted to the
carried votes, with a prior on its slope (1/P) and on bending, solved as one banded system per
frame; and the self-similar octave level that follows from its slope. Its sums and evaluations
are compiled (`ufit_kernels`); the tracker and the brush paths share it."""

from __future__ import annotations

import numpy as np
from numpy.linalg import LinAlgError

from strokekit.lines.strokeops import join_arrays
from strokekit.model import Strokes
from strokekit.numba_cache import LazyKernels
from strokekit.sampling import Samples
from strokekit.tracking.strokeops import insert_points, with_arcs
from strokekit.tracking.votes import unwrap_loop_votes

kernels = LazyKernels("strokekit.tracking.ufit_kernels").kernels


class PiecewiseU:
    """The knots of u along every stroke: a piecewise-linear function of arc length, n_s =
    ceil(L_s / knot_px) equal intervals of h_s px per stroke, knots base_s .. base_s + n_s, all
    strokes solved at once as one sparse least-squares problem (block diagonal)."""

    def __init__(self, lengths: np.ndarray, knot_px: float):
        self.L = np.asarray(lengths, float)
        self.n = np.maximum(1, np.ceil(self.L / knot_px - 1e-9)).astype(np.int64)
        self.h = self.L / self.n
        self.base = join_arrays(0, np.cumsum(self.n + 1)).astype(np.int64)  # first knot of each stroke


def fit_u(prev: Strokes, cur: Strokes, st: np.ndarray, s: np.ndarray, u: np.ndarray, vid: np.ndarray,
          w: np.ndarray, o):
    """u along the strokes `cur` fitted to the votes carried from `prev`: vote k lands on stroke
    st[k] at arc length s[k] (px) with u[k] (periods), carried id vid[k] and weight w[k]. Per
    stroke the votes of its primary id (most weight, ties: the lower id) set the fit, those of
    other ids join it shifted by whole periods (the texture is periodic); u is piecewise linear
    (knots every o.knot_spacing_px, inserted as points: u is interpolated linearly downstream)
    or linear, votes farther than o.outlier_px from the fit dropped and the fit redone: close to
    the votes (no sliding), slope close to 1/P (no stretch, o.stretch_weight), even stretch
    between knots (o.bend_weight); strokes without votes get u = s / P. Returns (cur with the
    knots inserted, u at its points, the slope du/ds per stroke, and the vote groups (stroke, id,
    inlier weight) that assign_ids takes)."""
    P = cur.period_px
    S = len(cur)
    b0 = 1.0 / P
    if len(st) == 0:
        z = np.zeros(0, np.int64)
        a, b = np.zeros(S), np.full(S, b0)
        sop = cur.stroke_of_point
        return cur, a[sop] + b[sop] * cur.arc_length, b, (z, z, np.zeros(0))
    K = kernels()
    st = np.asarray(st, np.int64)
    L = with_arcs(cur).lengths
    gkeys, ginv, gw, primary = K.vote_groups(st, np.asarray(vid, np.int64), w)
    u = unwrap_loop_votes(prev, u, vid, s, ginv, w, P, o.vote_spacing_px)
    lam = o.stretch_weight * P * P * L  # see TrackingOptions.stretch_weight
    a, b, ok = K.line_fit(st, s, u, w, primary[ginv].astype(float), lam, b0)
    u = K.to_primary(st, s, u, w, ginv, gw, primary, a, b)
    a, b, ok = K.line_fit(st, s, u, w, np.ones(len(st)), lam, b0)
    if o.knot_spacing_px > 0:
        # Piecewise-linear u: follows uneven stretch (perspective, edges of a loop growing at
        # different rates) without sliding.
        pw = PiecewiseU(L, o.knot_spacing_px)
        k, f = K.knot_intervals(pw.n, pw.h, pw.base, st, s)
        inlier = np.ones(len(st))
        for _ in range(2):
            band, rhs = K.piecewise_system(k, f, w, inlier, u, pw.n, pw.h, pw.base, L, a, b, b0,
                                           o.stretch_weight * P * P, o.bend_weight)
            knots = solve_banded(band, rhs)
            inlier = K.piecewise_inliers(knots, k, f, u, P, o.outlier_px)
    else:
        inlier = (np.abs(u - (a[st] + b[st] * s)) * P <= o.outlier_px).astype(float)
        a2, b2, ok2 = K.line_fit(st, s, u, w, inlier, lam, b0)
        a, b, ok = np.where(ok2, a2, a), np.where(ok2, b2, b), ok | ok2
    groups = (gkeys[:, 0], gkeys[:, 1], np.bincount(ginv, weights=w * inlier, minlength=len(gw)))
    b = np.where(ok, np.maximum(b, 1e-3 * b0), b0)  # never fold the texture back
    if o.knot_spacing_px > 0:
        cur = insert_points(cur, *K.inner_knots(pw.n, pw.h))
        u_new = K.piecewise_at(knots, pw.n, pw.h, pw.base, cur.offsets, with_arcs(cur).arc_length)
        b = np.where((L > 0) & ok, (knots[pw.base[1:] - 1] - knots[pw.base[:-1]]) / np.maximum(L, 1e-9), b)
    else:
        sop = cur.stroke_of_point
        u_new = a[sop] + b[sop] * cur.arc_length
    return cur, u_new, b, groups


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
