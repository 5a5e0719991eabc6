"""The u fit's loops (numba), for tracking.ufit.fit_u: the vote groups and their shift by whole
periods, the linear fit, the piecewise-linear fit's banded normal equations (`piecewise_system`,
fixed terms included), its inliers, its knots made points and its evaluation. Sums in the order
numpy's bincount and add.reduce take them, no fused multiply-adds: the same bits as the numpy
fit (tests/oracles.py); the banded solve stays LAPACK's."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from strokekit.numba_cache import kernel
from strokekit.tracking.sort_kernels import buckets, sort_by_key


@kernel("(i8[::1], f8[::1], f8[::1], f8[::1], f8[::1], f8[::1], f8)")
def line_fit(st, s, u, w, mask, lam, b0):
    """fit_u's linear fit u = a + b s per stroke (S = lam.shape[0]) of the votes
    st, s, u weighted w * mask (sums in vote order, as np.bincount takes them), with the prior
    lam (b - b0)^2 on the slope. Returns a, b (b0 where the fit is singular), ok (S,)."""
    S = lam.shape[0]
    S0 = np.zeros(S)
    S1 = np.zeros(S)
    S2 = np.zeros(S)
    T0 = np.zeros(S)
    T1 = np.zeros(S)
    for i in range(st.shape[0]):
        k = st[i]
        wm = w[i] * mask[i]
        ws = wm * s[i]
        S0[k] += wm
        S1[k] += ws
        S2[k] += ws * s[i]
        T0[k] += wm * u[i]
        T1[k] += ws * u[i]
    a = np.zeros(S)
    b = np.empty(S)
    ok = np.zeros(S, np.bool_)
    for k in range(S):
        A11 = S0[k]
        A12 = S1[k]
        A22 = S2[k] + lam[k]
        R1 = T0[k]
        R2 = T1[k] + lam[k] * b0
        det = A11 * A22 - A12 * A12
        ok[k] = S0[k] > 0 and det > 1e-12 * max(A11 * A22, 1e-300)
        if ok[k]:
            a[k] = (R1 * A22 - A12 * R2) / det
            b[k] = (A11 * R2 - A12 * R1) / det
        else:
            b[k] = b0
    return a, b, ok


@kernel("(i8[::1], i8[::1], f8[::1])")
def vote_groups(st, vid, w):
    """fit_u's vote groups: the distinct (stroke st, id vid) pairs of the votes
    (V,) (st, vid >= 0, vid < 2**53) in (stroke, id) order, gkeys (G, 2); each vote's group ginv
    (V,); each group's weight gw (G,) (w summed in vote order, as np.bincount takes it); primary
    (G,) the first group of each stroke holding the stroke's most weight
    (tracking.votes.first_max_per_group). The votes bucketed by stroke, each bucket sorted by
    id (a path's votes come in runs of one id)."""
    V = st.shape[0]
    S, start, perm = buckets(st)
    vf = vid.astype(np.float64)
    buf = np.empty(V, np.int64)
    bounds = np.empty(V + 1, np.int64)
    ginv = np.empty(V, np.int64)
    gst = np.empty(V, np.int64)
    gid = np.empty(V, np.int64)
    G = 0
    for j in range(S):
        sort_by_key(perm, start[j], start[j + 1], vf, buf, bounds)
        for r in range(start[j], start[j + 1]):
            i = perm[r]
            if r == start[j] or vid[i] != gid[G - 1]:
                gst[G] = j
                gid[G] = vid[i]
                G += 1
            ginv[i] = G - 1
    return _group_weights(gst[:G], gid[:G], ginv, w)


@njit(cache=True)
def _group_weights(gst, gid, ginv, w):
    """vote_groups' result from its groups (stroke gst, id gid, in order) and the votes' groups."""
    G = gst.shape[0]
    gkeys = np.empty((G, 2), np.int64)
    for g in range(G):
        gkeys[g, 0] = gst[g]
        gkeys[g, 1] = gid[g]
    gw = np.zeros(G)
    for i in range(ginv.shape[0]):
        gw[ginv[i]] += w[i]
    primary = np.zeros(G, np.bool_)
    g = 0
    while g < G:
        best = g
        h = g + 1
        while h < G and gst[h] == gst[g]:
            if gw[h] > gw[best]:
                best = h
            h += 1
        primary[best] = True
        g = h
    return gkeys, ginv, gw, primary


@kernel("(i8[::1], f8[::1], f8[::1], f8[::1], i8[::1], f8[::1], b1[::1], f8[::1], f8[::1])")
def to_primary(st, s, u, w, ginv, gw, primary, a, b):
    """fit_u's shift of the votes u (V,) of other groups than their stroke's
    primary one by whole periods, towards the line a + b s of their stroke: the group's weighted
    mean residual (w * res summed in vote order, over max(gw, 1e-12)), rounded."""
    G = gw.shape[0]
    acc = np.zeros(G)
    for i in range(st.shape[0]):
        res = u[i] - (a[st[i]] + b[st[i]] * s[i])
        acc[ginv[i]] += w[i] * res
    shift = np.empty(G)
    for g in range(G):
        shift[g] = 0.0 if primary[g] else np.rint(acc[g] / max(gw[g], 1e-12))
    out = np.empty(st.shape[0])
    for i in range(st.shape[0]):
        out[i] = u[i] - shift[ginv[i]]
    return out


@kernel("(i8[::1], f8[::1], i8[::1], i8[::1], f8[::1])")
def knot_intervals(n, h, base, st, s):
    """PiecewiseU's interval of arc length s (V,) on stroke st (V,) (n (S,)
    intervals of h (S,) px, first knot base (S + 1,)): its first knot k and the fraction a
    within it."""
    V = st.shape[0]
    k = np.empty(V, np.int64)
    a = np.empty(V)
    for i in range(V):
        j_ = st[i]
        hi = h[j_]
        x = s[i] / hi if hi > 0 else 0.0
        f = math.floor(x)
        hi_j = n[j_] - 1
        if f < 0:
            f = 0.0
        if f > hi_j:
            f = float(hi_j)
        j = int(f)
        k[i] = base[j_] + j
        r = x - j
        if r < 0.0:
            r = 0.0
        if r > 1.0:
            r = 1.0
        a[i] = r
    return k, a


@kernel("(i8[::1], f8[::1], f8[::1], f8[::1], f8[:, ::1], f8[:, ::1], f8[:, ::1], f8[:, ::1])")
def band_terms(k, a, w, u, f0, f1, f2, f3):
    """The piecewise fit's banded normal equations: the votes' terms (vote i: knots
    k[i], k[i] + 1 at fraction a[i], weight w[i], value u[i]), each summed over the votes in
    their order, then the fixed terms' rows f0 .. f3 (the stretch, bend and anchor rows of band
    rows 0, 1, 2 and the right-hand side) added one row after the other, as np.add.reduce over
    the stacked rows adds them. Returns band (3, nk) and rhs (nk,)."""
    nk = f0.shape[1]
    band = np.zeros((3, nk))
    rhs = np.zeros(nk)
    b01 = np.zeros(nk)
    rhs1 = np.zeros(nk)
    for i in range(k.shape[0]):
        sw = math.sqrt(w[i])
        v0 = sw * (1 - a[i])
        v1 = sw * a[i]
        y = sw * u[i]
        band[0, k[i]] += v0 * v0
        b01[k[i] + 1] += v1 * v1
        band[1, k[i]] += v0 * v1
        rhs[k[i]] += v0 * y
        rhs1[k[i] + 1] += v1 * y
    for c in range(nk):
        band[0, c] += b01[c]
        rhs[c] += rhs1[c]
    for r in range(f0.shape[0]):
        for c in range(nk):
            band[0, c] += f0[r, c]
    for r in range(f1.shape[0]):
        for c in range(nk):
            band[1, c] += f1[r, c]
    for c in range(nk):
        band[2, c] = f2[0, c]
    for r in range(1, f2.shape[0]):
        for c in range(nk):
            band[2, c] += f2[r, c]
    for r in range(f3.shape[0]):
        for c in range(nk):
            rhs[c] += f3[r, c]
    return band, rhs


@kernel(("(i8[::1], f8[::1], f8[::1], f8[::1], f8[::1], i8[::1], f8[::1], i8[::1], f8[::1], f8[::1], f8[::1], "
        "f8, f8, f8)"))
def piecewise_system(k, a, w, inlier, u, n, h, base, L, prior_a, prior_b, b0, stretch_weight, bend_weight):
    """The piecewise fit's banded system (band (3, nk), rhs (nk,)) for the votes at
    knots k, fraction a (knot_intervals), weight w * inlier, value u: its fixed terms
    (PiecewiseU._fixed_terms: stretch per interval, bend per inner knot, anchor to the line
    prior_a + prior_b s per knot) made as it makes them, summed with the votes' by band_terms,
    the rows past the last knot zeroed."""
    S = n.shape[0]
    nk = base[S]
    f0 = np.zeros((6, nk))
    f1 = np.zeros((3, nk))
    f2 = np.zeros((1, nk))
    f3 = np.zeros((3, nk))
    for j_ in range(S):
        hs = h[j_]
        hh = max(hs, 1.0)
        ws = math.sqrt(stretch_weight / hh)
        va = -ws
        vb = ws
        y = ws * hs * b0
        wb = math.sqrt(bend_weight * max(L[j_], 1.0))
        for i in range(n[j_]):
            kk = base[j_] + i
            f0[0, kk] = va * va
            f3[0, kk] = va * y
            f1[0, kk] = va * vb
            f0[1, kk + 1] = vb * vb
            f3[1, kk + 1] = vb * y
            if i < n[j_] - 1:  # bend, at the inner knot after interval i
                ba = wb
                bb = -2 * wb
                bc = wb
                f0[2, kk] = ba * ba
                f1[1, kk] = ba * bb
                f2[0, kk] = ba * bc
                f0[3, kk + 1] = bb * bb
                f1[2, kk + 1] = bb * bc
                f0[4, kk + 2] = bc * bc
        for c in range(base[j_], base[j_ + 1]):
            sk = (c - base[j_]) * h[j_]
            f0[5, c] = 1e-3 * 1e-3
            f3[2, c] = 1e-3 * (1e-3 * (prior_a[j_] + prior_b[j_] * sk))
    wi = np.empty(w.shape[0])
    for i in range(w.shape[0]):
        wi[i] = w[i] * inlier[i]
    band, rhs = band_terms(k, a, wi, u, f0, f1, f2, f3)
    if nk >= 1:
        band[1, nk - 1] = 0.0
    for c in range(max(nk - 2, 0), nk):
        band[2, c] = 0.0
    return band, rhs


@kernel("(f8[::1], i8[::1], f8[::1], f8[::1], f8, f8)")
def piecewise_inliers(knots, k, a, u, P, outlier_px):
    """(V,) 1.0 where the vote u lies within outlier_px (px, u in periods of P px) of the
    piecewise-linear u (knots, at knot k and fraction a: PiecewiseU.eval), else 0.0."""
    out = np.empty(k.shape[0])
    for i in range(k.shape[0]):
        e = knots[k[i]] * (1 - a[i]) + knots[k[i] + 1] * a[i]
        out[i] = 1.0 if abs(u[i] - e) * P <= outlier_px else 0.0
    return out


@kernel("(f8[::1], i8[::1], f8[::1], i8[::1], i8[::1], f8[::1])")
def piecewise_at(knots, n, h, base, offsets, arc):
    """PiecewiseU.eval(knots, stroke_of_point, arc) of strokes with point offsets (S + 1,) and
    the points' arc lengths arc (N,)."""
    out = np.empty(arc.shape[0])
    for j_ in range(offsets.shape[0] - 1):
        hi = h[j_]
        top = n[j_] - 1
        for q in range(offsets[j_], offsets[j_ + 1]):
            x = arc[q] / hi if hi > 0 else 0.0
            f = math.floor(x)
            if f < 0:
                f = 0.0
            if f > top:
                f = float(top)
            j = int(f)
            r = x - j
            if r < 0.0:
                r = 0.0
            if r > 1.0:
                r = 1.0
            kq = base[j_] + j
            out[q] = knots[kq] * (1 - r) + knots[kq + 1] * r
    return out


@kernel("(i8[::1], f8[::1])")
def inner_knots(n, h):
    """PiecewiseU's inner knots (inner_knot_stroke, inner_knot_s): knots 1 .. n_r - 1 of every
    stroke r (n (S,) intervals of h (S,) px each), their stroke and arc length j * h_r (px)."""
    total = 0
    for r in range(n.shape[0]):
        total += n[r] - 1
    st = np.empty(total, np.int64)
    s = np.empty(total)
    e = 0
    for r in range(n.shape[0]):
        for j in range(1, n[r]):
            st[e] = r
            s[e] = j * h[r]
            e += 1
    return st, s
