"""The pieces' loops (numba), for paths.pieces: the uncovered stretches of the runs
(`pieces_of_runs`), cut at the corners (`corner_cuts`), their candidate links (`link_pairs`)
and the cuts that leave one label per path (`one_label`)."""

from __future__ import annotations

import math

import numpy as np

from strokekit.numba_cache import kernel
from strokekit.tracking.sort_kernels import argsort


@kernel("(i8[::1], i8[::1], f8[::1], f8[::1], f8[::1], f8[::1], f8)")
def pieces_of_runs(cover, run, s, w, r_s0, r_s1, min_piece_px):
    """paths.pieces.line_pieces' pieces: the stretches of samples (N,) of one run not covered
    (cover < 0) from arc length s0 to s1 (px; a run's own ends where the stretch reaches them,
    else halfway to the next sample), kept where at least min_piece_px long or a whole run, and
    not empty. Returns their run, s0, s1 (P,) and the piece of every sample (N,) (-1: none)."""
    N = run.shape[0]
    smp_piece = np.full(N, -1, np.int64)
    p_run = np.empty(N, np.int64)
    p_s0 = np.empty(N)
    p_s1 = np.empty(N)
    P = 0
    a = 0
    while a < N:
        b = a
        while b + 1 < N and (cover[b + 1] < 0) == (cover[a] < 0) and run[b + 1] == run[a]:
            b += 1
        r = run[a]
        head = a == 0 or run[a - 1] != r
        tail = b == N - 1 or run[b + 1] != r
        s0 = r_s0[r] if head else s[a] - 0.5 * w[a]
        s1 = r_s1[r] if tail else s[b] + 0.5 * w[b]
        if cover[a] < 0 and (s1 - s0 >= min_piece_px or (head and tail)) and s1 > s0:
            p_run[P] = r
            p_s0[P] = s0
            p_s1[P] = s1
            for i in range(a, b + 1):
                smp_piece[i] = P
            P += 1
        a = b + 1
    return p_run[:P].copy(), p_s0[:P].copy(), p_s1[:P].copy(), smp_piece


@kernel("(f8[:, ::1], i8[::1], f8[::1], f8, i8[::1], f8[::1], f8[::1], i8[::1], f8[::1])")
def corner_cuts(P, offsets, arc, cos_min, p_line, p_s0, p_s1, smp_piece, d_s):
    """Pieces cut at the vertices of their line that turn by more than acos(cos_min): P (N, 2) the
    lines' points, offsets (S+1,), arc (N,) each point's arc length along its line (px); pieces
    p_line, p_s0, p_s1 (Q,); a vertex cuts a piece when it lies more than 0.5 px inside it. The
    line samples' pieces smp_piece (M,) at arc lengths d_s (M,) follow their part. Returns
    owner (Q',) (the piece each part comes from), s0, s1 (Q',) and the samples' parts (M,)."""
    S = offsets.shape[0] - 1
    c_start = np.zeros(S + 1, np.int64)
    c_s = np.empty(P.shape[0])
    n = 0
    for r in range(S):
        c_start[r] = n
        for i in range(offsets[r] + 1, offsets[r + 1] - 1):
            ax = P[i, 0] - P[i - 1, 0]
            ay = P[i, 1] - P[i - 1, 1]
            bx = P[i + 1, 0] - P[i, 0]
            by = P[i + 1, 1] - P[i, 1]
            la = math.sqrt(ax * ax + ay * ay)
            lb = math.sqrt(bx * bx + by * by)
            if la > 1e-6 and lb > 1e-6 and (ax * bx + ay * by) / (la * lb) < cos_min:
                c_s[n] = arc[i]
                n += 1
    c_start[S] = n
    Q = p_line.shape[0]
    lo = np.empty(Q, np.int64)
    cnt = np.zeros(Q, np.int64)
    total = 0
    for q in range(Q):
        r = p_line[q]
        a = c_start[r]
        while a < c_start[r + 1] and not c_s[a] > p_s0[q] + 0.5:
            a += 1
        b = a
        while b < c_start[r + 1] and c_s[b] < p_s1[q] - 0.5:
            b += 1
        lo[q] = a
        cnt[q] = b - a
        total += b - a + 1
    owner = np.empty(total, np.int64)
    s0 = np.empty(total)
    s1 = np.empty(total)
    first = np.empty(Q, np.int64)
    k = 0
    for q in range(Q):
        first[q] = k
        for j in range(cnt[q] + 1):
            owner[k] = q
            s0[k] = p_s0[q] if j == 0 else c_s[lo[q] + j - 1]
            s1[k] = p_s1[q] if j == cnt[q] else c_s[lo[q] + j]
            k += 1
    out = smp_piece.copy()
    for i in range(smp_piece.shape[0]):
        q = smp_piece[i]
        if q < 0:
            continue
        j = 0
        while j < cnt[q] and c_s[lo[q] + j] < d_s[i]:
            j += 1
        out[i] = first[q] + j
    return owner, s0, s1, out


@kernel("(f8[:, ::1], i8[::1], i8[::1], f8, f8)")
def link_pairs(P, offsets, kind, r, cos_min):
    """paths.pieces.LinkPairs: the open strokes' ends (e_run (2n,): starts, then ends), their
    points pt (2n, 2); the pairs a < b (in _close_pair_arrays' order: by the stable x order of pt,
    then by partner) within r px; per pair its cosine of the turn `straight`, its gap, and whether
    it may link whatever the labels (`fits`: two strokes of one kind, turning by at most
    acos(cos_min))."""
    S = offsets.shape[0] - 1
    n = 0
    op = np.empty(S, np.int64)
    for q in range(S):
        f = offsets[q]
        la = offsets[q + 1] - 1
        dx = P[f, 0] - P[la, 0]
        dy = P[f, 1] - P[la, 1]
        if not math.sqrt(dx * dx + dy * dy) < 1e-6:
            op[n] = q
            n += 1
    e_run = np.empty(2 * n, np.int64)
    pt = np.empty((2 * n, 2))
    d = np.empty((2 * n, 2))
    for e in range(2 * n):
        q = op[e % n] if n else 0
        f = offsets[q]
        la = offsets[q + 1] - 1
        if e < n:
            at = f
            nb = min(f + 1, la)
        else:
            at = la
            nb = max(la - 1, f)
        e_run[e] = q
        pt[e, 0] = P[at, 0]
        pt[e, 1] = P[at, 1]
        dx = P[nb, 0] - P[at, 0]
        dy = P[nb, 1] - P[at, 1]
        nn = max(math.sqrt(dx * dx + dy * dy), 1e-12)
        d[e, 0] = dx / nn
        d[e, 1] = dy / nn
    m = 2 * n
    xs = np.empty(m)
    for e in range(m):
        xs[e] = pt[e, 0]
    o = argsort(xs)
    # The pairs: counted, then listed (two sweeps: no growing arrays, dear to compile).
    K = 0
    for i in range(m):
        lim = xs[o[i]] + (r + 1e-6)
        for j in range(i + 1, m):
            if not xs[o[j]] <= lim:
                break
            ddx = pt[o[i], 0] - pt[o[j], 0]
            ddy = pt[o[i], 1] - pt[o[j], 1]
            if ddx * ddx + ddy * ddy <= r * r:
                K += 1
    a = np.empty(K, np.int64)
    b = np.empty(K, np.int64)
    K = 0
    for i in range(m):
        lim = xs[o[i]] + (r + 1e-6)
        for j in range(i + 1, m):
            if not xs[o[j]] <= lim:
                break
            x = o[i]
            y = o[j]
            ddx = pt[x, 0] - pt[y, 0]
            ddy = pt[x, 1] - pt[y, 1]
            if ddx * ddx + ddy * ddy <= r * r:
                a[K] = min(x, y)
                b[K] = max(x, y)
                K += 1
    fits = np.zeros(K, np.bool_)
    straight = np.empty(K)
    gap = np.empty(K)
    for k in range(K):
        x = a[k]
        y = b[k]
        ra = e_run[x]
        rb = e_run[y]
        straight[k] = -(d[x, 0] * d[y, 0] + d[x, 1] * d[y, 1])
        ddx = pt[x, 0] - pt[y, 0]
        ddy = pt[x, 1] - pt[y, 1]
        gap[k] = math.sqrt(ddx * ddx + ddy * ddy)
        fits[k] = ra != rb and kind[ra] == kind[rb] and straight[k] >= cos_min
    return n, e_run, pt, a, b, straight, gap, fits


@kernel("(i8[::1], i8[::1], i8[::1])")
def one_label(order, group, label):
    """paths.pieces.one_label_per_path after its sort (order: the pieces by group, then position):
    each group's pieces' labels filled forward over the unlabelled ones (-1), then backward
    before the first labelled one; the group cut where that label changes. Returns the new
    groups (numbered in order) and whether any cut was made."""
    K = order.shape[0]
    fill = np.empty(K, np.int64)
    start = np.empty(K, np.bool_)
    g0 = 0
    while g0 < K:
        g1 = g0 + 1
        while g1 < K and group[order[g1]] == group[order[g0]]:
            g1 += 1
        cur = -1
        for i in range(g0, g1):
            lab = label[order[i]]
            if lab >= 0:
                cur = lab
            fill[i] = cur
            start[i] = i == g0
        cur = -1
        for i in range(g1 - 1, g0 - 1, -1):
            lab = label[order[i]]
            if lab >= 0:
                cur = lab
            if fill[i] < 0:
                fill[i] = cur
        g0 = g1
    out = np.empty(K, np.int64)
    cuts = False
    c = -1
    for i in range(K):
        if start[i]:
            c += 1
        elif fill[i] != fill[i - 1]:
            c += 1
            cuts = True
        out[order[i]] = c
    return out, cuts
