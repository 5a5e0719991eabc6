"""Stable sorts and bucketings for kernels (numba): numba's own merge sort costs seconds of
compile. Called by the kernels of the tracker and of the brush paths."""

from __future__ import annotations

import numpy as np

from strokekit.numba_cache import kernel


@kernel("(i8[::1], i8, i8, f8[::1], i8[::1], i8[::1])")
def sort_by_key(o, lo, hi, key, buf, bounds):
    """o[lo:hi] sorted by key[o[.]] (float, not NaN), stably (equal keys keep their order): a
    natural merge sort (the votes of a path come in a few runs, one per piece, each in order or
    against it). buf, bounds: scratch of at least hi - lo and hi - lo + 1 entries."""
    if hi - lo < 2:
        return
    nr = 0
    i = lo
    while i < hi:
        j = i + 1
        if j < hi and key[o[j]] < key[o[i]]:
            while j < hi and key[o[j]] < key[o[j - 1]]:
                j += 1
            # (strictly decreasing: no ties whose order a reversal would break)
            a = i
            b = j - 1
            while a < b:
                t = o[a]
                o[a] = o[b]
                o[b] = t
                a += 1
                b -= 1
        else:
            while j < hi and not key[o[j]] < key[o[j - 1]]:
                j += 1
        bounds[nr] = i
        nr += 1
        i = j
    bounds[nr] = hi
    while nr > 1:
        m = 0
        k = 0
        while k < nr:
            if k + 1 < nr:
                a0 = bounds[k]
                a1 = bounds[k + 1]
                b1 = bounds[k + 2]
                for q in range(a0, a1):
                    buf[q - lo] = o[q]
                x = a0
                y = a1
                d = a0
                while x < a1 and y < b1:
                    if key[o[y]] < key[buf[x - lo]]:
                        o[d] = o[y]
                        y += 1
                    else:
                        o[d] = buf[x - lo]
                        x += 1
                    d += 1
                while x < a1:
                    o[d] = buf[x - lo]
                    x += 1
                    d += 1
                bounds[m] = a0
                k += 2
            else:
                bounds[m] = bounds[k]
                k += 1
            m += 1
        bounds[m] = hi
        nr = m


@kernel("(f8[::1],)")
def argsort(key):
    """np.argsort(key, kind="stable") of a float array (not NaN) by sort_by_key (numba's own
    merge sort costs seconds of compile)."""
    n = key.shape[0]
    o = np.arange(n)
    sort_by_key(o, 0, n, key, np.empty(n, np.int64), np.empty(n + 1, np.int64))
    return o


@kernel("(i8[::1],)")
def buckets(st):
    """The indices of st (V,) (values >= 0) bucketed by value, stably: (S = max + 1, start (S + 1,)
    where bucket j begins, order (V,))."""
    V = st.shape[0]
    S = 0
    for i in range(V):
        if st[i] + 1 > S:
            S = st[i] + 1
    start = np.zeros(S + 1, np.int64)
    for i in range(V):
        start[st[i] + 1] += 1
    for j in range(S):
        start[j + 1] += start[j]
    fill = start[:-1].copy()
    order = np.empty(V, np.int64)
    for i in range(V):
        order[fill[st[i]]] = i
        fill[st[i]] += 1
    return S, start, order


@kernel("(i8[::1],)")
def sorted_unique(x):
    """np.unique of integers (|x| < 2**53: exact as floats)."""
    o = argsort(x.astype(np.float64))
    out = np.empty(x.shape[0], x.dtype)
    n = 0
    for j in range(x.shape[0]):
        v = x[o[j]]
        if n == 0 or v != out[n - 1]:
            out[n] = v
            n += 1
    return out[:n].copy()
