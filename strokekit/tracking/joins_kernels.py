"""The links' loops (numba), for tracking.joins: candidate links taken in order and walked into
paths (`link_paths`), the points of the paths gathered (`gather`)."""

from __future__ import annotations

import math

import numpy as np

from strokekit.numba_cache import kernel


@kernel("(i8[::1], i8[::1], i8[::1], i8, i8)")
def link_paths(a, b, e_run, n, S):
    """tracking.joins.walk_links: the candidate links a, b (L,) between stroke ends (node i < n:
    the start of stroke e_run[i], else its end), in the order they are taken (each end in one
    link at most), walked into paths. Returns group (S,) (the lowest stroke of each path), rev
    (S,) and pos (S,)."""
    group = np.arange(S)
    rev = np.zeros(S, np.bool_)
    pos = np.zeros(S, np.int64)
    nn = 2 * n
    code = np.empty(nn, np.int64)
    for i in range(nn):
        code[i] = 2 * e_run[i] + (1 if i >= n else 0)
    deg = np.zeros(nn, np.int64)
    for i in range(a.shape[0]):
        deg[a[i]] += 1
        deg[b[i]] += 1
    # nxt[c]: code of the end linked to end c (-1: free); entering at c, one leaves at c ^ 1.
    nxt = np.full(2 * S, -1, np.int64)
    taken = np.zeros(nn, np.bool_)
    for i in range(a.shape[0]):
        x = a[i]
        y = b[i]
        if deg[x] == 1 and deg[y] == 1:  # (in no other link: taken whatever the order)
            nxt[code[x]] = code[y]
            nxt[code[y]] = code[x]
    for i in range(a.shape[0]):
        x = a[i]
        y = b[i]
        if (deg[x] == 1 and deg[y] == 1) or taken[x] or taken[y]:
            continue
        taken[x] = True
        taken[y] = True
        nxt[code[x]] = code[y]
        nxt[code[y]] = code[x]
    walk = np.empty(S, np.int64)
    heads = np.empty(S + 1, np.int64)
    nw = 0
    nh = 0
    seen = np.zeros(S, np.bool_)
    n_runs = 0
    # Path starts: strokes with one linked end, entered through the free end, in stroke order; a
    # path's other end stroke is a start left to skip.
    for r in range(S):
        l0 = nxt[2 * r] >= 0
        l1 = nxt[2 * r + 1] >= 0
        if l0 or l1:
            n_runs += 1
        if l0 == l1 or seen[r]:
            continue
        c = 2 * r + (1 if l0 else 0)
        heads[nh] = nw
        nh += 1
        while True:
            walk[nw] = c
            nw += 1
            seen[c >> 1] = True
            nc = nxt[c ^ 1]
            if nc < 0:
                break
            c = nc
    if nw < n_runs:
        # Rings (linked strokes no path reached), entered through their start.
        for r in range(S):
            if seen[r] or (nxt[2 * r] < 0 and nxt[2 * r + 1] < 0):
                continue
            c = 2 * r
            heads[nh] = nw
            nh += 1
            while not seen[c >> 1]:
                seen[c >> 1] = True
                walk[nw] = c
                nw += 1
                c = nxt[c ^ 1]
                if c < 0:
                    break
    heads[nh] = nw
    for h in range(nh):
        h0 = heads[h]
        h1 = heads[h + 1]
        ln = h1 - h0
        # A path goes backwards when more of its strokes are entered at their end.
        ends = 0
        low = walk[h0] >> 1
        for i in range(h0, h1):
            ends += walk[i] & 1
            if (walk[i] >> 1) < low:
                low = walk[i] >> 1
        flip = 2 * ends > ln
        for i in range(h0, h1):
            r = walk[i] >> 1
            k = i - h0
            group[r] = low
            rev[r] = ((walk[i] & 1) == 1) != flip
            pos[r] = ln - 1 - k if flip else k
    return group, rev, pos


@kernel("(i8[::1], i8[::1], b1[::1], i8[::1], f8[:, ::1])")
def gather(offsets, order, rev, group, P):
    """tracking.joins.gather_paths after its order (the strokes by path, then position): where
    each stroke starts in the gathered points c0 (S,), the source point of each gathered point
    src (repeated joint points left out), the joints and the joints dropped as repeats (gathered
    indices, before the drop), the path of each stroke in order, each path's first stroke and
    its points."""
    S = order.shape[0]
    c0 = np.empty(S, np.int64)
    N = 0
    for k in range(S):
        c0[k] = N
        N += offsets[order[k] + 1] - offsets[order[k]]
    src = np.empty(N, np.int64)
    path = np.empty(S, np.int64)
    new_g = np.empty(S, np.bool_)
    nj = 0
    npth = 0
    for k in range(S):
        q = order[k]
        a = offsets[q]
        n = offsets[q + 1] - a
        for t in range(n):
            src[c0[k] + t] = a + n - 1 - t if rev[q] else a + t
        new_g[k] = k == 0 or group[q] != group[order[k - 1]]
        if new_g[k]:
            npth += 1
        else:
            nj += 1
        path[k] = npth - 1
    joint = np.empty(nj, np.int64)
    first = np.empty(npth, np.int64)
    n_path = np.zeros(npth, np.int64)
    nd = 0
    j = 0
    for k in range(S):
        n_path[path[k]] += offsets[order[k] + 1] - offsets[order[k]]
        if new_g[k]:
            first[path[k]] = order[k]
        else:
            joint[j] = c0[k]
            j += 1
            x = src[c0[k]]
            y = src[c0[k] - 1]
            dx = P[x, 0] - P[y, 0]
            dy = P[x, 1] - P[y, 1]
            if math.sqrt(dx * dx + dy * dy) < 1e-9:
                nd += 1
    drop = np.empty(nd, np.int64)
    d = 0
    for k in range(S):
        if not new_g[k]:
            x = src[c0[k]]
            y = src[c0[k] - 1]
            dx = P[x, 0] - P[y, 0]
            dy = P[x, 1] - P[y, 1]
            if math.sqrt(dx * dx + dy * dy) < 1e-9:
                drop[d] = c0[k]
                d += 1
                n_path[path[k]] -= 1
    if nd > 0:
        kept = np.empty(N - nd, np.int64)
        d = 0
        m = 0
        for t in range(N):
            if d < nd and drop[d] == t:
                d += 1
            else:
                kept[m] = src[t]
                m += 1
        src = kept
    return c0, src, new_g, joint, drop, path, first, n_path
