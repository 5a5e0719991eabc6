"""The votes' loops of the brush paths (numba), for paths.votes: the votes carried from the
look-back's matches (`carried`), where they land on the pieces (`votes_landing`), the claims on
the ids (`id_claims`), the u at the pieces' ends (`end_votes`, `continuing_links`), the order of
the votes along the paths (`jump_order`). The same bits as the numpy steps they replaced."""

from __future__ import annotations

import numpy as np
from numba import njit

from strokekit.numba_cache import kernel
from strokekit.tracking.sort_kernels import buckets, sort_by_key


@njit(cache=True)
def _classes(codes, contour, n_kinds):
    """paths.votes.kind_class of kind codes (kind + n_kinds x occlusion level): their hidden
    levels as one, then the contour kinds (contour (n_kinds,)) in one class per level, -1 -
    level; every other code its own class."""
    out = np.empty(codes.shape[0], np.int64)
    for i in range(codes.shape[0]):
        c = codes[i] % n_kinds + n_kinds * min(codes[i] // n_kinds, 1)
        out[i] = -1 - c // n_kinds if contour[c % n_kinds] else c
    return out


@kernel(("(i8[::1], f8[:, ::1], i8[::1], i8[::1], i8[::1], i8[::1], b1[::1], i8, f8[:, ::1], f8[:, ::1], "
        "f8[::1], f8[::1], f8[::1], i8[::1], i8[::1], f8[::1], f8[:, ::1], i8)"))
def carried(rm, rq, sub, kind_d, Dstroke, kind_v, contour, n_kinds, Vp, Vt, Vw, Vu, Vs, Vstroke, Vids, Dw, Dt, step):
    """paths.votes.carried_votes from the lookback's matches: rm (M,) the previous path sample
    each looking-back line sample (line sample sub (M,)) found (-1: none), rq (M, 2) where it
    projected. The kind classes (_classes) of the line samples come from their lines' kind codes
    kind_d (by Dstroke), those of the path samples from their paths' kind_v (by Vstroke).
    Returns the votes where the classes agree: line sample m, id, u (refined along the old
    tangent by the local slope of u, the offset clipped to the sample's piece), weight (step
    times the line sample's length) and the sign of the tangents' agreement; then the matches
    where they differ (Votes.other): line sample, id, weight."""
    M = rm.shape[0]
    cls_d = _classes(kind_d, contour, n_kinds)
    cls_v = _classes(kind_v, contour, n_kinds)
    K = 0
    n_other = 0
    for i in range(M):
        j = rm[i]
        if j >= 0:
            if cls_d[Dstroke[sub[i]]] == cls_v[Vstroke[j]]:
                K += 1
            else:
                n_other += 1
    m = np.empty(K, np.int64)
    vid = np.empty(K, np.int64)
    u = np.empty(K)
    w = np.empty(K)
    sign = np.empty(K)
    om = np.empty(n_other, np.int64)
    oid = np.empty(n_other, Vids.dtype)
    ow = np.empty(n_other)
    nv = Vp.shape[0]
    k = 0
    o = 0
    for i in range(M):
        j = rm[i]
        if j < 0:
            continue
        h = sub[i]
        if cls_d[Dstroke[h]] != cls_v[Vstroke[j]]:
            om[o] = h
            oid[o] = Vids[j]
            ow[o] = step * Dw[h]
            o += 1
            continue
        t0 = Vt[j, 0]
        t1 = Vt[j, 1]
        off = (rq[i, 0] - Vp[j, 0]) * t0 + (rq[i, 1] - Vp[j, 1]) * t1
        lo = -0.5 * Vw[j]
        hi = 0.5 * Vw[j]
        if off < lo:
            off = lo
        if off > hi:
            off = hi
        # du/ds at the path sample, from its neighbours on its stroke (tracking.ufit.local_slope).
        nx = j + 1 if j + 1 < nv and Vstroke[j + 1] == Vstroke[j] else j
        pv = j - 1 if j >= 1 and Vstroke[j - 1] == Vstroke[j] else j
        ds = Vs[nx] - Vs[pv]
        slope = (Vu[nx] - Vu[pv]) / ds if ds > 0 else 0.0
        m[k] = h
        vid[k] = Vids[j]
        u[k] = Vu[j] + off * slope
        w[k] = step * Dw[h]
        sign[k] = np.sign(t0 * Dt[h, 0] + t1 * Dt[h, 1])
        k += 1
    return m, vid, u, w, sign, om, oid, ow


@kernel("(i8[::1], i8[::1], i8[::1], f8[::1], f8[::1], f8[::1])")
def votes_landing(vm, cover, smp_piece, s, p_s0, p_s1):
    """Where every vote (on line sample vm (V,)) lands: on its sample, or where a covered sample's
    covering sample lies; ok (V,) where that sample draws a piece, and for those (in order) the
    piece and the arc length within it (px, clipped to the piece)."""
    V = vm.shape[0]
    ok = np.zeros(V, np.bool_)
    n = 0
    for v in range(V):
        h = cover[vm[v]] if cover[vm[v]] >= 0 else vm[v]
        if smp_piece[h] >= 0:
            ok[v] = True
            n += 1
    vk = np.empty(n, np.int64)
    s_in = np.empty(n)
    n = 0
    for v in range(V):
        if not ok[v]:
            continue
        h = cover[vm[v]] if cover[vm[v]] >= 0 else vm[v]
        k = smp_piece[h]
        x = s[h] - p_s0[k]
        x = max(x, 0.0)
        x = min(x, p_s1[k] - p_s0[k])
        vk[n] = k
        s_in[n] = x
        n += 1
    return ok, vk, s_in


@njit(cache=True)
def _left(a, v):
    """np.searchsorted(a, v) (side left) in a sorted array a, without branches on the data (the
    halving steps are selects)."""
    n = a.shape[0]
    if n == 0:
        return 0
    base = 0
    while n > 1:
        half = n >> 1
        base = base + half if a[base + half] < v else base
        n -= half
    return base + 1 if a[base] < v else base


@kernel(("(i8[::1], i8[::1], f8[::1], f8, i8[::1], i8[::1], f8[::1], b1[::1], i8[::1], i8[::1], f8[::1], "
        "i8[::1])"))
def id_claims(path_of, p_label, plen, label_weight, vk, vid, vw, ok, ok_k, oid, ow, known):
    """paths.votes.path_ids' claims of the paths on the previous ids, summed per (path, id): the
    pieces' labels (piece i of path path_of[i], labelled p_label[i] >= 0, weighs label_weight *
    plen[i]), the votes (on piece vk, id vid, weight vw) and those of the other kind class (where
    ok: on piece ok_k (in order), id oid, weight ow). Returns (cs, ci, cw), the pairs of a
    nonzero sum by path, then by the place of the id in `known` (sorted; K = its length): what
    np.bincount(cs * K + np.searchsorted(known, ci), weights=cw, minlength=S * K) and its
    np.flatnonzero give for any S (sums in the same order: the labels, the votes, the other
    votes)."""
    K = known.shape[0]
    P = p_label.shape[0]
    V = vk.shape[0]
    n = V + ok_k.shape[0]
    for i in range(P):
        if p_label[i] >= 0:
            n += 1
    key = np.empty(n, np.int64)
    wt = np.empty(n)
    e = 0
    k = 0
    last = -1
    at = 0
    for i in range(P + V + ok.shape[0]):
        if i < P:
            if p_label[i] < 0:
                continue
            piece, cid, x = i, p_label[i], label_weight * plen[i]
        elif i < P + V:
            piece, cid, x = vk[i - P], vid[i - P], vw[i - P]
        else:
            if not ok[i - P - V]:
                continue
            piece, cid, x = ok_k[k], oid[i - P - V], ow[i - P - V]
            k += 1
        if e == 0 or cid != last:  # (the votes of a line come in runs of one id)
            last = cid
            at = _left(known, cid)
        key[e] = path_of[piece] * K + at
        wt[e] = x
        e += 1
    # By path (bucketed, in order), then summed per id on a scratch row of K: the sums of a
    # dense S x K bincount without its pages.
    pr = np.empty(n, np.int64)
    for i in range(n):
        pr[i] = key[i] // K
    top, start, o = buckets(pr)
    row = np.zeros(K)
    seen = np.zeros(K, np.bool_)
    touched = np.empty(K, np.int64)
    cs = np.empty(n, np.int64)
    ci = np.empty(n, known.dtype)
    cw = np.empty(n)
    m = 0
    for r in range(top):
        nt = 0
        for q in range(start[r], start[r + 1]):
            c = key[o[q]] % K
            row[c] += wt[o[q]]
            if not seen[c]:
                seen[c] = True
                # (kept sorted: a path claims a few ids)
                at = nt
                while at > 0 and touched[at - 1] > c:
                    touched[at] = touched[at - 1]
                    at -= 1
                touched[at] = c
                nt += 1
        for a in range(nt):
            c = touched[a]
            if row[c] != 0.0:
                cs[m] = r
                ci[m] = known[c]
                cw[m] = row[c]
                m += 1
            row[c] = 0.0
            seen[c] = False
    out_s = np.empty(m, np.int64)
    out_i = np.empty(m, known.dtype)
    out_w = np.empty(m)
    for q in range(m):
        out_s[q] = cs[q]
        out_i[q] = ci[q]
        out_w[q] = cw[q]
    return out_s, out_i, out_w


@kernel("(i8[::1], f8[::1], f8[::1], i8[::1], i8[::1], f8[::1], f8, f8)")
def end_votes(vk, s_in, u, vid, label, plen, P, reach):
    """paths.votes.EndVotes.of: the votes (V,) landing on piece vk at arc length s_in (px) with
    carried u and id vid; a piece's own votes are those of its label (label (K,), -1: none). Per
    piece and end (0: start, 1: end) the u of the own vote nearest the end (K, 2; nan: none) and
    its distance from the end (K, 2; px, inf: none within `reach`); of votes at equal s_in the
    first nearest the start, the last nearest the end (a stable sort by (piece, s_in)). slope (K,):
    |du/ds| x P between the first and the last own vote, 1 where they are under 4 px apart or it
    lies outside 1/4..4."""
    K = plen.shape[0]
    s_lo = np.full(K, np.nan)
    s_hi = np.full(K, np.nan)
    ue = np.full((K, 2), np.nan)
    for v in range(vk.shape[0]):
        k = vk[v]
        if label[k] < 0 or vid[v] != label[k]:
            continue
        x = s_in[v]
        if not x >= s_lo[k]:  # (nan: the piece's first own vote)
            s_lo[k] = x
            ue[k, 0] = u[v]
        if not x < s_hi[k]:
            s_hi[k] = x
            ue[k, 1] = u[v]
    d = np.full((K, 2), np.inf)
    slope = np.ones(K)
    for k in range(K):
        if not s_lo[k] == s_lo[k]:
            continue
        if s_lo[k] <= reach:
            d[k, 0] = s_lo[k]
        if plen[k] - s_hi[k] <= reach:
            d[k, 1] = plen[k] - s_hi[k]
        span = s_hi[k] - s_lo[k]
        if span >= 4.0:
            b = abs(ue[k, 1] - ue[k, 0]) * P / span
            if 0.25 <= b <= 4.0:
                slope[k] = b
    return ue, d, slope


@kernel("(i8[::1], b1[::1], i8[::1], b1[::1], f8[::1], i8[::1], f8[:, ::1], f8[:, ::1], f8[::1], f8, f8)")
def continuing_links(ra, end_a, rb, end_b, gap, tier, ue, d, slope, P, tol):
    """paths.votes.EndVotes.continues for the links (L,) of one label (tier 2; the others: False)."""
    L = ra.shape[0]
    out = np.zeros(L, np.bool_)
    for i in range(L):
        if tier[i] != 2:
            continue
        ea = 1 if end_a[i] else 0
        eb = 1 if end_b[i] else 0
        reach = gap[i] + d[ra[i], ea] + d[rb[i], eb]
        if not reach < np.inf:
            continue
        du = abs(ue[ra[i], ea] - ue[rb[i], eb]) * P
        sl = 0.5 * (slope[ra[i]] + slope[rb[i]])
        out[i] = du <= sl * (reach + tol)
    return out


@kernel("(i8[::1], i8[::1], f8[::1], f8[::1], f8, f8)")
def jump_order(st, vid, s, u, P, min_jump):
    """heal_jumps' order of the votes, np.lexsort((s, vid, st)) (st, vid >= 0, vid < 2**53): by
    path (bucketed), then id, then s, each sort stable; and whether a step between two votes of
    one path and id, next to each other in it, has |du - ds / P| >= min_jump (rounded: a jump to
    heal)."""
    V = st.shape[0]
    S, start, o = buckets(st)
    vf = vid.astype(np.float64)
    buf = np.empty(V, np.int64)
    bounds = np.empty(V + 1, np.int64)
    for j in range(S):
        sort_by_key(o, start[j], start[j + 1], vf, buf, bounds)
        g0 = start[j]
        while g0 < start[j + 1]:
            g1 = g0 + 1
            while g1 < start[j + 1] and vid[o[g1]] == vid[o[g0]]:
                g1 += 1
            sort_by_key(o, g0, g1, s, buf, bounds)
            g0 = g1
    for i in range(1, o.shape[0]):
        a = o[i - 1]
        b = o[i]
        if st[a] == st[b] and vid[a] == vid[b] and abs((u[b] - u[a]) - (s[b] - s[a]) / P) >= min_jump:
            if np.round((u[b] - u[a]) - (s[b] - s[a]) / P) != 0.0:
                return o, True
    return o, False
