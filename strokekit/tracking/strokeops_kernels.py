"""The stroke operations' loops (numba), for tracking.strokeops: arc lengths, samples, pieces,
points inserted and kept, strokes selected, hairpins found. The same arithmetic in the same order
as the numpy operations of the line pass, to the bit."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from strokekit.numba_cache import kernel
from strokekit.tracking.sort_kernels import sorted_unique


@kernel("(f8[:, ::1], i8[::1], f8[::1], f8[::1], f8[::1], f8[::1], f8[::1])")
def arcs(P, offsets, seg, arc, L, base, G):
    """Strokes' arc caches, the same bits (model.Strokes), into seg (N,) (zeros): segment_lengths
    (row_norm of the differences, 0 at each stroke's first point), arc (N,): arc_length (their
    running sum less its value at the stroke's first point), L (S,): lengths, base (S,), G (N,):
    global_arc. Returns False (nothing computed) where a stroke has no point."""
    N = P.shape[0]
    S = offsets.shape[0] - 1
    for k in range(S):
        if offsets[k + 1] <= offsets[k]:
            return False
    for i in range(1, N):
        dx = P[i, 0] - P[i - 1, 0]
        dy = P[i, 1] - P[i - 1, 1]
        seg[i] = math.sqrt(dx * dx + dy * dy)
    for k in range(S):
        seg[offsets[k]] = 0.0
    c = 0.0
    for i in range(N):  # (arc_length: the running sum over all strokes, as cumsum takes it)
        c += seg[i]
        arc[i] = c
    b = 0.0
    for k in range(S):
        c0 = arc[offsets[k]]
        for i in range(offsets[k], offsets[k + 1]):
            arc[i] = arc[i] - c0
        L[k] = arc[offsets[k + 1] - 1]
        if k > 0:
            b += L[k - 1] + 1.0
        base[k] = b
        for i in range(offsets[k], offsets[k + 1]):
            G[i] = arc[i] + b
    return True


@kernel("(f8[::1], f8, f8[::1], f8[::1], i8[::1])")
def resample_at(L, step, base, G, offsets):
    """sampling.resample_strokes' samples, before their points are read: every stroke of lengths L
    (S,) cut into n = max(1, ceil(L / step - 1e-9)) equal pieces, a sample at the middle of each.
    base, G: the strokes' global arc (Strokes.global_arc); offsets (S + 1,). Returns per sample
    its stroke, arc length s and length w (px), and the segment i -> j and fraction a (in [0, 1])
    of the polyline where it lies."""
    S = L.shape[0]
    n = np.empty(S, np.int64)
    M = 0
    for k in range(S):
        v = math.ceil(L[k] / step - 1e-9)
        n[k] = int(max(1.0, v))
        M += n[k]
    stroke = np.empty(M, np.int64)
    s = np.empty(M)
    w = np.empty(M)
    i = np.empty(M, np.int64)
    j = np.empty(M, np.int64)
    a = np.empty(M)
    last_g = G.shape[0] - 1
    m = 0
    for k in range(S):
        wk = L[k] / n[k]
        first = offsets[k]
        last = offsets[k + 1] - 1
        # G.searchsorted(g, "right") by a walk along the stroke (g increases along it; where
        # the walk starts, G <= g: G[first] is the stroke's base): the same index.
        r = max(first, 0)
        for q in range(n[k]):
            sm = (q + 0.5) * wk
            g = sm + base[k]
            if r > 0 and G[r - 1] > g:  # (not past g: search from the start)
                r = np.searchsorted(G, g, side="right")
            while r <= last_g and G[r] <= g:
                r += 1
            # bracket(G, G.searchsorted(g, "right"), first, last)
            jj = min(max(r, first + 1), max(last, first + 1))
            jj = min(jj, last_g)
            ii = max(jj - 1, first)
            if last == first:  # (one-point stroke)
                ii = first
                jj = first
            gi = G[ii]
            d = G[jj] - gi
            f = (g - gi) / d if d > 0 else 0.0
            f = min(max(f, 0.0), 1.0)
            stroke[m] = k
            s[m] = sm
            w[m] = wk
            i[m] = ii
            j[m] = jj
            a[m] = f
            m += 1
    return stroke, s, w, i, j, a


@kernel("(f8[:, ::1], f8[::1], i8[::1], i8[::1], f8[::1])")
def resample_points(P, U, i, j, a):
    """sampling.resample_strokes' positions (M, 2), unit tangents (M, 2) (0 on a zero-length
    segment) and u (M,) of the samples at fraction a of the segments i -> j."""
    M = i.shape[0]
    p = np.empty((M, 2))
    t = np.empty((M, 2))
    u = np.empty(M)
    for m in range(M):
        ii = i[m]
        jj = j[m]
        f = a[m]
        g = 1 - f
        u[m] = U[ii] * g + U[jj] * f
        t0 = P[jj, 0] - P[ii, 0]
        t1 = P[jj, 1] - P[ii, 1]
        tn = math.sqrt(t0 * t0 + t1 * t1)
        if tn > 0:
            t[m, 0] = t0 / tn
            t[m, 1] = t1 / tn
        else:
            t[m, 0] = 0.0
            t[m, 1] = 0.0
        p[m, 0] = P[ii, 0] * g + P[jj, 0] * f
        p[m, 1] = P[ii, 1] * g + P[jj, 1] * f
    return p, t, u


@kernel("(f8[:, ::1], f8[:, ::1], f8[::1], f8[::1], f8[::1])")
def surface_mix(Xi, Xj, zi, zj, a):
    """sampling.surface_between's perspective-correct mix of the surface points Xi, Xj (K, 3) at
    screen fraction a (K,), their depths zi, zj (K,) given (numpy's matrix products: their
    rounding is the BLAS kernel's): where both depths are positive and so is (1 - a) zj + a zi,
    a becomes a zi / that; the point Xi (1 - a) + Xj a."""
    K = a.shape[0]
    out = np.empty((K, 3))
    for k in range(K):
        f = a[k]
        if zi[k] > 0 and zj[k] > 0:
            den = (1 - f) * zj[k] + f * zi[k]
            if den > 0:
                f = f * zi[k] / den
        g = 1 - f
        for c in range(3):
            out[k, c] = Xi[k, c] * g + Xj[k, c] * f
    return out


@kernel("(f8[::1], f8[::1], i8[::1], i8[::1], f8[::1], f8[::1])")
def cut_ends(G, base, offsets, stroke, s0, s1):
    """lines.strokeops.cut_pieces' bookkeeping: for every piece k (stroke[k] from arc length s0[k]
    to s1[k], px) its first interior original point lo and their count n_in (G strictly inside),
    and the segments i -> j and fractions a of its two ends (2K: the starts, then the ends)."""
    K = stroke.shape[0]
    last_g = G.shape[0] - 1
    lo = np.empty(K, np.int64)
    n_in = np.empty(K, np.int64)
    i = np.empty(2 * K, np.int64)
    j = np.empty(2 * K, np.int64)
    a = np.empty(2 * K)
    for k in range(K):
        st = stroke[k]
        first = offsets[st]
        last = offsets[st + 1] - 1
        for e in range(2):
            g = base[st] + (s0[k] if e == 0 else s1[k])
            r = np.searchsorted(G, g, side="right")
            if e == 0:
                lo[k] = max(r, first)
            else:
                hi = min(np.searchsorted(G, g, side="left"), last + 1)
                n_in[k] = max(hi - lo[k], 0)
            jj = min(max(r, first + 1), max(last, first + 1))
            jj = min(jj, last_g)
            ii = max(jj - 1, first)
            gi = G[ii]
            d = G[jj] - gi
            f = (g - gi) / d if d > 0 else 0.0
            m = k + e * K
            i[m] = ii
            j[m] = jj
            a[m] = min(max(f, 0.0), 1.0)
    return lo, n_in, i, j, a


@kernel("(f8[:, ::1], f8[:, ::1], i8[::1], i8[::1], i8[::1], i8[::1], i8[::1], f8[::1], f8[:, ::1], b1[::1])")
def cut_assemble(P, X, F, lo, n_in, i, j, a, Xe, rev):
    """cut_pieces' points: each piece's interpolated start, its interior original points, its
    interpolated end, in the opposite order where `rev` (K,); Xe (2K, 3) the ends' surface
    points. Returns points, surface, face and offsets."""
    K = lo.shape[0]
    off = np.empty(K + 1, np.int64)
    off[0] = 0
    for k in range(K):
        off[k + 1] = off[k] + n_in[k] + 2
    N = off[K]
    p = np.empty((N, 2))
    x = np.empty((N, 3))
    fc = np.empty(N, F.dtype)
    for k in range(K):
        t = off[k]
        # (reversed: point q of the piece goes to t + t1 - q)
        t1 = off[k + 1] - 1
        for e in range(2):
            m = k + e * K
            q = t if e == 0 else t1
            if rev[k]:
                q = t + t1 - q
            f = a[m]
            p[q, 0] = P[i[m], 0] * (1 - f) + P[j[m], 0] * f
            p[q, 1] = P[i[m], 1] * (1 - f) + P[j[m], 1] * f
            x[q, 0] = Xe[m, 0]
            x[q, 1] = Xe[m, 1]
            x[q, 2] = Xe[m, 2]
            fc[q] = F[i[m]] if f < 0.5 else F[j[m]]
        for c in range(n_in[k]):
            src = lo[k] + c
            q = t + 1 + c
            if rev[k]:
                q = t + t1 - q
            p[q, 0] = P[src, 0]
            p[q, 1] = P[src, 1]
            x[q, 0] = X[src, 0]
            x[q, 1] = X[src, 1]
            x[q, 2] = X[src, 2]
            fc[q] = F[src]
    return p, x, fc, off


@njit(cache=True)
def _gather_points(P, X, F, U, rows):
    """The points' rows `rows` (M,): screen points P (N, 2), surface X (N, 3), face F, u U."""
    M = rows.shape[0]
    p = np.empty((M, 2))
    x = np.empty((M, 3))
    f = np.empty(M, F.dtype)
    u = np.empty(M, U.dtype)
    for m in range(M):
        q = rows[m]
        p[m, 0] = P[q, 0]
        p[m, 1] = P[q, 1]
        x[m, 0] = X[q, 0]
        x[m, 1] = X[q, 1]
        x[m, 2] = X[q, 2]
        f[m] = F[q]
        u[m] = U[q]
    return p, x, f, u


@kernel("(f8[:, ::1], f8[:, ::1], i8[::1], f8[::1], i8[::1], b1[::1])")
def keep_rows(P, X, F, U, offsets, alive):
    """The points (P (N, 2), surface X (N, 3), face F, u U) where alive (N,) is true, and the
    strokes' new offsets (every stroke keeps one point at least: its ends are never dropped)."""
    S = offsets.shape[0] - 1
    off = np.empty(S + 1, np.int64)
    off[0] = 0
    for k in range(S):
        c = 0
        for q in range(offsets[k], offsets[k + 1]):
            c += alive[q]
        off[k + 1] = off[k] + c
    rows = np.empty(off[S], np.int64)
    m = 0
    for q in range(P.shape[0]):
        if alive[q]:
            rows[m] = q
            m += 1
    p, x, f, u = _gather_points(P, X, F, U, rows)
    return p, x, f, u, off


@kernel("(f8[:, ::1], f8[:, ::1], i8[::1], f8[::1], i8[::1], i8[::1])")
def take_strokes(P, X, F, U, offsets, which):
    """The points (P (N, 2), surface X (N, 3), face F, u U) of the strokes `which` (K,), in that
    order, and their offsets (K + 1,) (Strokes.select's gathers, `which` its mask's indices)."""
    K = which.shape[0]
    off = np.empty(K + 1, np.int64)
    off[0] = 0
    for k in range(K):
        off[k + 1] = off[k] + offsets[which[k] + 1] - offsets[which[k]]
    rows = np.empty(off[K], np.int64)
    m = 0
    for k in range(K):
        for q in range(offsets[which[k]], offsets[which[k] + 1]):
            rows[m] = q
            m += 1
    p, x, f, u = _gather_points(P, X, F, U, rows)
    return p, x, f, u, off


@kernel("(f8[::1], f8[::1], i8[::1], i8[::1], f8[::1])")
def insert_at(base, G, offsets, stroke, s):
    """insert_points' new points: at arc length s (px) of strokes `stroke`, the
    segment i -> j and fraction a holding it, its global arc g; points within 1e-6 px of an
    existing point (or on a zero-length segment) left out. Returns i, j, a, g, stroke (kept)."""
    K = stroke.shape[0]
    last_g = G.shape[0] - 1
    ii = np.empty(K, np.int64)
    jj = np.empty(K, np.int64)
    aa = np.empty(K)
    gg = np.empty(K)
    ss = np.empty(K, np.int64)
    n = 0
    for k in range(K):
        st = stroke[k]
        g = base[st] + s[k]
        first = offsets[st]
        last = offsets[st + 1] - 1
        r = np.searchsorted(G, g, side="right")
        j = min(max(r, first + 1), max(last, first + 1))
        j = min(j, last_g)
        i = max(j - 1, first)
        gi = G[i]
        gj = G[j]
        if gj - gi > 0 and g - gi > 1e-6 and gj - g > 1e-6:
            ii[n] = i
            jj[n] = j
            aa[n] = (g - gi) / (gj - gi)
            gg[n] = g
            ss[n] = st
            n += 1
    return ii[:n].copy(), jj[:n].copy(), aa[:n].copy(), gg[:n].copy(), ss[:n].copy()


@kernel(("(f8[:, ::1], f8[:, ::1], i8[::1], f8[::1], f8[::1], i8[::1], i8[::1], i8[::1], f8[::1], f8[::1], "
        "i8[::1], f8[:, ::1])"))
def insert_merge(P, X, F, U, G, offsets, i, j, a, g, stroke, Xn):
    """insert_points' strokes: the points P, X, F, U (N) with the new ones (interpolated at
    fraction a of segments i -> j; surface points Xn) merged in by global arc (G (N,) increasing;
    g (K,) non-decreasing: an old point before a new one at the same place). Returns P, X, F, U,
    offsets."""
    N = G.shape[0]
    K = g.shape[0]
    M = N + K
    P2 = np.empty((M, 2))
    X2 = np.empty((M, 3))
    F2 = np.empty(M, F.dtype)
    U2 = np.empty(M)
    q = 0
    k = 0
    for m in range(M):
        if k < K and (q == N or g[k] < G[q]):  # (a new point before the old one at its place)
            f = a[k]
            P2[m, 0] = P[i[k], 0] * (1 - f) + P[j[k], 0] * f
            P2[m, 1] = P[i[k], 1] * (1 - f) + P[j[k], 1] * f
            X2[m, 0] = Xn[k, 0]
            X2[m, 1] = Xn[k, 1]
            X2[m, 2] = Xn[k, 2]
            F2[m] = F[i[k]] if f < 0.5 else F[j[k]]
            U2[m] = U[i[k]] * (1 - f) + U[j[k]] * f
            k += 1
        else:
            P2[m, 0] = P[q, 0]
            P2[m, 1] = P[q, 1]
            X2[m, 0] = X[q, 0]
            X2[m, 1] = X[q, 1]
            X2[m, 2] = X[q, 2]
            F2[m] = F[q]
            U2[m] = U[q]
            q += 1
    S = offsets.shape[0] - 1
    off = np.empty(S + 1, np.int64)
    off[0] = 0
    extra = np.zeros(S, np.int64)
    for k in range(K):
        extra[stroke[k]] += 1
    for t in range(S):
        off[t + 1] = off[t] + (offsets[t + 1] - offsets[t]) + extra[t]
    return P2, X2, F2, U2, off


@njit(cache=True)
def _hairpins(P, ends, i, cos_max, max_px):
    """drop_hairpins' points kept (N,): P (N, 2) the points, ends (N,) the strokes' ends, i the
    sorted interior points looked at."""
    n = P.shape[0]
    alive = np.ones(n, np.bool_)
    live = np.arange(n)
    dropped = False
    mx2 = max_px * max_px
    for _ in range(8):
        m = i.shape[0]
        if m == 0:
            break
        bad = np.zeros(m, np.bool_)
        kk = np.empty(m, np.int64)
        any_bad = False
        for e in range(m):
            c = i[e]
            # Neighbours among the points still there (ends are never dropped).
            k = np.searchsorted(live, c) if dropped else c
            kk[e] = k
            pv = live[k - 1]
            nx = live[k + 1]
            ax = P[c, 0] - P[pv, 0]
            ay = P[c, 1] - P[pv, 1]
            bx = P[nx, 0] - P[c, 0]
            by = P[nx, 1] - P[c, 1]
            la = ax * ax + ay * ay
            lb = bx * bx + by * by
            dot = ax * bx + ay * by
            if min(la, lb) <= mx2 and la > 0 and lb > 0 and dot < cos_max * math.sqrt(la * lb):
                bad[e] = True
                any_bad = True
        if not any_bad:
            break
        # Of neighbouring candidates (next to each other among the live points) the first goes;
        # the fold can move to a neighbour of a dropped point: those are looked at too.
        cand = np.empty(m, np.int64)
        near = np.empty(2 * m, np.int64)
        nc = 0
        last_k = -2
        for e in range(m):
            if not bad[e]:
                continue
            k = kk[e]
            if nc == 0 or k - last_k > 1:
                cand[nc] = i[e]
                near[2 * nc] = live[k - 1]
                near[2 * nc + 1] = live[min(k + 1, live.shape[0] - 1)]
                nc += 1
            last_k = k
        for e in range(nc):
            alive[cand[e]] = False
        live = np.flatnonzero(alive)
        dropped = True
        nxt = np.empty(m + 2 * nc, np.int64)
        t = 0
        for e in range(m):
            if alive[i[e]]:
                nxt[t] = i[e]
                t += 1
        for e in range(2 * nc):
            c = near[e]
            if alive[c] and not ends[c]:
                nxt[t] = c
                t += 1
        i = sorted_unique(nxt[:t])
    return alive


@kernel("(f8[:, ::1], i8[::1], i8[::1], f8, f8)")
def hairpin_points(P, offsets, at, cos_max, max_px):
    """drop_hairpins' points kept (N,), from the strokes' offsets (S + 1,) and the points looked
    at `at` (any order, repeats; the strokes' ends and first and last points left out)."""
    n = P.shape[0]
    ends = np.zeros(n, np.bool_)
    for k in range(offsets.shape[0] - 1):
        if offsets[k + 1] > offsets[k]:  # (an empty stroke has no ends)
            ends[offsets[k]] = True
            ends[offsets[k + 1] - 1] = True
    i = sorted_unique(at)
    m = 0
    for e in range(i.shape[0]):
        c = i[e]
        if c > 0 and c < n - 1 and not ends[c]:
            i[m] = c
            m += 1
    return _hairpins(P, ends, i[:m].copy(), cos_max, max_px)
