"""The votes' loops (numba), for tracking.votes: the label of every sample (`vote_labels`), the
runs of one label (`segment_runs`), the greedy assignment of ids (`greedy_ids`), the trend of u
along the runs (`u_trend`). Sums in the order numpy's bincount takes them, ties as its sorts
break them: the same bits as the numpy steps (tests/oracles.py)."""

from __future__ import annotations

import numpy as np
from numba import njit

from strokekit.numba_cache import kernel
from strokekit.tracking.sort_kernels import argsort, buckets, sort_by_key


@kernel("(i8, i8[::1], i8[::1], i8, f8[::1])")
def vote_labels(D, o, key, M, w):
    """sample_labels: (D,) the id of most vote weight on every sample (ties: the
    lower id; -1: no vote), from the votes' keys sample * M + id (V,) and o (V,) a stable argsort
    of them. A key's weight is summed in vote order and rounded to 9 decimals as np.round does."""
    label = np.full(D, -1, np.int64)
    V = o.shape[0]
    g0 = 0
    best = 0.0
    while g0 < V:
        kg = key[o[g0]]
        tot = 0.0
        g1 = g0
        while g1 < V and key[o[g1]] == kg:
            tot += w[o[g1]]
            g1 += 1
        kw = np.rint(tot * 1e9) / 1e9
        smp = kg // M
        # keys come sorted by (sample, id): the first of a sample holding its maximum wins
        if g0 == 0 or key[o[g0 - 1]] // M != smp:
            label[smp] = kg % M
            best = kw
        elif kw > best:
            label[smp] = kg % M
            best = kw
        g0 = g1
    return label


@njit(cache=True)
def _fill(lab, stroke, s, out):
    """tracking.votes.segment_by_votes' fill: every sample without a label (-1) takes that of the
    nearest labelled sample of its stroke (ties: the one before), or stays -1."""
    D = lab.shape[0]
    # b[i]: the first labelled sample at or after i (D: none), found from the end.
    nxt = np.empty(D, np.int64)
    b = D
    for i in range(D - 1, -1, -1):
        if lab[i] >= 0:
            b = i
        nxt[i] = b
    f = -1
    for i in range(D):
        if lab[i] >= 0:
            f = i
        b = nxt[i]
        fok = f >= 0 and stroke[f] == stroke[i]
        bok = b < D and stroke[b] == stroke[i]
        df = s[i] - s[f] if fok else np.inf
        db = s[b] - s[i] if bok else np.inf
        if not (fok or bok):
            out[i] = -1
        elif df <= db:
            out[i] = lab[f]
        else:
            out[i] = lab[b]


@njit(cache=True)
def _runs(lab, stroke, w, run):
    """Runs of one label along a stroke: run (D,) set, returns the run lengths (sums of w)."""
    D = lab.shape[0]
    r = -1
    for i in range(D):
        if i == 0 or lab[i] != lab[i - 1] or stroke[i] != stroke[i - 1]:
            r += 1
        run[i] = r
    rl = np.zeros(r + 1)
    for i in range(D):
        rl[run[i]] += w[i]
    return rl


@kernel("(i8[::1], i8[::1], f8[::1], f8[::1], f8[::1], f8)")
def segment_runs(label, stroke, s, w, lengths, min_segment_px):
    """tracking.votes.segment_by_votes from its samples' labels (D,) (the id of most vote weight,
    -1: no vote; D >= 1): returns run (D,), and per run stroke, s0, s1 (px) and label."""
    D = label.shape[0]
    lab = np.empty(D, np.int64)
    _fill(label, stroke, s, lab)
    run = np.empty(D, np.int64)
    tmp = np.empty(D, np.int64)
    for _ in range(4):
        rl = _runs(lab, stroke, w, run)
        R = rl.shape[0]
        # Per stroke its longest run (ties: the first) is never short.
        first = np.empty(R, np.int64)
        for i in range(D - 1, -1, -1):
            first[run[i]] = i
        short = np.zeros(R, np.bool_)
        any_short = False
        r0 = 0
        while r0 < R:
            st = stroke[first[r0]]
            r1 = r0
            best = r0
            while r1 < R and stroke[first[r1]] == st:
                if rl[r1] > rl[best]:
                    best = r1
                r1 += 1
            for r in range(r0, r1):
                if r != best and rl[r] < min_segment_px and lab[first[r]] >= 0:
                    short[r] = True
                    any_short = True
            r0 = r1
        if not any_short:
            break
        for i in range(D):
            tmp[i] = -1 if short[run[i]] else lab[i]
        _fill(tmp, stroke, s, lab)
    else:
        rl = _runs(lab, stroke, w, run)
    R = rl.shape[0]
    first = np.empty(R, np.int64)
    last = np.empty(R, np.int64)
    for i in range(D - 1, -1, -1):
        first[run[i]] = i
    for i in range(D):
        last[run[i]] = i
    rs = np.empty(R, np.int64)
    s0 = np.empty(R)
    s1 = np.empty(R)
    rlab = np.empty(R, np.int64)
    for r in range(R):
        a = first[r]
        b = last[r]
        rs[r] = stroke[a]
        rlab[r] = lab[a]
        head = r == 0 or stroke[first[r - 1]] != stroke[a]
        tail = r == R - 1 or stroke[first[r + 1]] != stroke[a]
        # Runs meet halfway between their samples; strokes are covered from 0 to their length.
        s0[r] = 0.0 if head else 0.5 * (s[a] + s[max(a - 1, 0)])
        s1[r] = lengths[stroke[a]] if tail else 0.5 * (s[b] + s[min(b + 1, D - 1)])
    return run, rs, s0, s1, rlab


@kernel("(i8[::1], i8[::1], i8[::1], i8, i8)")
def greedy_ids(order, cs, ci, n_strokes, next_id):
    """tracking.votes.assign_ids' pass: the (stroke cs, id ci) pairs in `order` (heaviest first),
    each stroke and each id used once; strokes left without an id get fresh ids from next_id in
    stroke order. Returns (ids (n_strokes,), the new next_id)."""
    ids = np.full(n_strokes, -1, np.int64)
    top = 0
    for p in range(ci.shape[0]):
        if ci[p] + 1 > top:
            top = ci[p] + 1
    used = np.zeros(top, np.bool_)
    for p in order:
        s = cs[p]
        if ids[s] < 0 and not used[ci[p]]:
            ids[s] = ci[p]
            used[ci[p]] = True
    for s in range(n_strokes):
        if ids[s] < 0:
            ids[s] = next_id
            next_id += 1
    return ids, next_id


@kernel("(i8[::1], f8[::1], f8[::1], i8)")
def u_trend(rk, pk, u, R):
    """u_trend after its selection: the votes rk (K,) (run), pk (K,) (position,
    px, shifted to start at 0), u (K,): per run the px along which u increases less those along
    which it decreases, over steps between votes next to each other by position."""
    K = rk.shape[0]
    out = np.zeros(R)
    if K < 2:
        return out
    top = pk.max() + 1.0
    key = np.empty(K)
    for i in range(K):
        key[i] = rk[i] * top + pk[i]
    if R * top < 2.0 ** 40:
        # np.argsort(key, kind="mergesort") as the runs' keys lie apart (a run's span is less
        # than top, whole px apart at this scale): bucketed by run, each bucket sorted by key.
        n_runs, start, o = buckets(rk)
        buf = np.empty(K, np.int64)
        bounds = np.empty(K + 1, np.int64)
        for r in range(n_runs):
            sort_by_key(o, start[r], start[r + 1], key, buf, bounds)
    else:
        o = argsort(key)
    for i in range(1, K):
        a = o[i - 1]
        b = o[i]
        if rk[b] == rk[a]:
            out[rk[b]] += np.sign(u[b] - u[a]) * (pk[b] - pk[a])
    return out
