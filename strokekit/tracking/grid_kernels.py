"""Neighbour searches on a grid of a frame's samples (numba), for tracking.grid: the k nearest
(`knn`), the look-back match by piece distance (`match_pieces`), the test that a bridge lies on
the lines (`bridges`). They give what scipy's cKDTree gives for the same points (its squared
distance dx * dx + dy * dy, its strict `<` against the squared bound) and say where they cannot:
where candidates tie at the distance that decides (the tree's choice then depends on its
traversal); the caller asks the tree there."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from strokekit.numba_cache import kernel


@kernel("(f8[:, ::1],)")
def grid_ok(p):
    """Whether the points p (N, 2) can be put on a grid: N > 0, every coordinate finite and so
    is the spread (max - min) along each axis (what np.isfinite(p).all() and a finite np.ptp(p,
    axis=0) say, without numpy's slow reduction along the short axis)."""
    n = p.shape[0]
    if n == 0:
        return False
    x0 = p[0, 0]
    y0 = p[0, 1]
    x1 = x0
    y1 = y0
    for i in range(n):
        x = p[i, 0]
        y = p[i, 1]
        if not (math.isfinite(x) and math.isfinite(y)):
            return False
        if x < x0:
            x0 = x
        if x > x1:
            x1 = x
        if y < y0:
            y0 = y
        if y > y1:
            y1 = y
    return math.isfinite(x1 - x0) and math.isfinite(y1 - y0)


@kernel("(f8[:, ::1], f8)")
def grid_index(p, cell):
    """Points p (N, 2) (finite, and so is their spread; cell > 0 finite) sorted into square cells of about `cell` px (larger where the
    points spread wide: at most max(8 N, 65536) cells). Returns (x0, y0, cell, nx, ny, start,
    order, ps): cell (cx, cy) = ((x - x0) // cell, (y - y0) // cell) holds points order[start[c] :
    start[c + 1]] (in index order), c = cy * nx + cx; ps (N, 2) the points in that order (read
    one after the other by the searches)."""
    n = p.shape[0]
    x0 = p[0, 0]
    y0 = p[0, 1]
    x1 = x0
    y1 = y0
    for i in range(1, n):
        x = p[i, 0]
        y = p[i, 1]
        if x < x0:
            x0 = x
        if x > x1:
            x1 = x
        if y < y0:
            y0 = y
        if y > y1:
            y1 = y
    limit = max(8 * n, 65536)
    while True:  # (counted in float64: a wide spread would overflow int64's product)
        fx = math.floor((x1 - x0) / cell) + 1.0
        fy = math.floor((y1 - y0) / cell) + 1.0
        if fx * fy <= limit:
            break
        cell *= 2.0
    nx = int(fx)
    ny = int(fy)
    start = np.zeros(nx * ny + 1, np.int64)
    key = np.empty(n, np.int64)
    rank = np.empty(n, np.int64)  # (each point's place among the earlier points of its cell)
    for i in range(n):
        cx = min(int((p[i, 0] - x0) / cell), nx - 1)
        cy = min(int((p[i, 1] - y0) / cell), ny - 1)
        c = cy * nx + cx
        key[i] = c
        rank[i] = start[c + 1]
        start[c + 1] += 1
    for c in range(nx * ny):
        start[c + 1] += start[c]
    order = np.empty(n, np.int64)
    ps = np.empty((n, 2))
    for i in range(n):
        at = start[key[i]] + rank[i]
        order[at] = i
        ps[at, 0] = p[i, 0]
        ps[at, 1] = p[i, 1]
    return x0, y0, cell, nx, ny, start, order, ps


@njit(cache=True)
def _window(v, v0, cell, reach, n):
    """The first and last cell along one axis a point within `reach` of v can lie in (with a
    margin for the rounding of the cell's computation)."""
    a = math.floor((v - reach - v0) / cell - 1e-6)
    b = math.floor((v + reach - v0) / cell + 1e-6)
    if a < 0:
        a = 0
    if b > n - 1:
        b = n - 1
    return int(a), int(b)


@kernel(("(f8[:, ::1], i8, f8, f8, f8, i8, i8, i8[::1], i8[::1], f8[:, ::1], i8, f8, b1, f8[:, ::1], "
        "i8[:, ::1], b1[::1])"))
def knn(q, n, x0, y0, cell, nx, ny, start, order, ps, k, bound, as_set, out_d2, out_i, unsure):
    """For every query point q (M, 2): its k nearest of the n points of a grid (grid_index) at
    squared distance < bound**2, nearest first (equal distances: lower index first): out_d2 (M,
    k) their squared distances (inf: none), out_i (M, k) their indices (N: none). unsure (M,) is
    set where the tree could choose them otherwise (the k-th and the next at the same distance),
    or order them otherwise (two of them at the same distance; not looked at with `as_set`),
    and where q is not finite."""
    b2 = bound * bound
    bd = np.empty(k + 1)
    bi = np.empty(k + 1, np.int64)
    for m in range(q.shape[0]):
        qx = q[m, 0]
        qy = q[m, 1]
        for s in range(k):
            out_d2[m, s] = np.inf
            out_i[m, s] = n
        if not (math.isfinite(qx) and math.isfinite(qy)):
            unsure[m] = True
            continue
        cnt = _nearest(qx, qy, x0, y0, cell, nx, ny, start, order, ps, bound, b2, bd, bi)
        for s in range(k - 1 if as_set else 0, min(cnt, k + 1) - 1):
            if bd[s] == bd[s + 1]:
                unsure[m] = True
        for s in range(min(cnt, k)):
            out_d2[m, s] = bd[s]
            out_i[m, s] = bi[s]


@njit(cache=True)
def _insert(bd, bi, cnt, d2, j):
    """(d2, j) into the sorted (by d2, then j) buffer bd, bi holding cnt entries (at most its
    size: the last one goes). Returns the new count."""
    size = bd.shape[0]
    if cnt == size:
        if d2 > bd[size - 1] or (d2 == bd[size - 1] and j > bi[size - 1]):
            return cnt
        pos = size - 1
    else:
        pos = cnt
        cnt += 1
    while pos > 0 and (bd[pos - 1] > d2 or (bd[pos - 1] == d2 and bi[pos - 1] > j)):
        bd[pos] = bd[pos - 1]
        bi[pos] = bi[pos - 1]
        pos -= 1
    bd[pos] = d2
    bi[pos] = j
    return cnt


@njit(cache=True)
def _nearest(qx, qy, x0, y0, cell, nx, ny, start, order, ps, bound, b2, bd, bi):
    """The grid points (grid_index: ps (N, 2) in cell order, `order` their indices) at squared
    distance < b2 (bound**2) from (qx, qy), the nearest kept in the sorted buffers bd (squared
    distances) and bi (indices) as _insert keeps them: returns how many bd, bi hold."""
    cnt = 0
    ax, bx = _window(qx, x0, cell, bound, nx)
    ay, by = _window(qy, y0, cell, bound, ny)
    for cy in range(ay, by + 1):
        row = cy * nx
        for cx in range(ax, bx + 1):
            c = row + cx
            for s in range(start[c], start[c + 1]):
                dx = ps[s, 0] - qx
                dy = ps[s, 1] - qy
                d2 = dx * dx + dy * dy
                if d2 < b2:
                    cnt = _insert(bd, bi, cnt, d2, order[s])
    return cnt


@njit(cache=True)
def _near_one(qx, qy, p, t, w, x0, y0, cell, nx, ny, start, order, ps, k, bound, limit, bd, bi):
    """paths.cover.on_drawing's test of one point (qx, qy) on the grid of the line samples p (N,
    2), their tangents t (N, 2) and lengths w (N,): (near, unsure), whether it lies within
    `limit` px of the piece of line of one of its k nearest samples within `bound`, as the tree's
    k nearest give it (where samples tie at the k-th distance: what every choice among them
    gives; unsure where the choice decides, or the point is not finite). The piece of sample j:
    length w_j along t_j, centred on p_j; the distance across it from the tree's distance
    sqrt(d2). bd, bi: buffers of size k + 8."""
    if not (math.isfinite(qx) and math.isfinite(qy)):
        return False, True
    b2 = bound * bound
    size = bd.shape[0]
    cnt = _nearest(qx, qy, x0, y0, cell, nx, ny, start, order, ps, bound, b2, bd, bi)
    # The tree keeps the k nearest: those nearer than the k-th for sure, then some of the
    # samples at the k-th's distance.
    last = bd[k - 1] if cnt >= k else np.inf
    any_sure = False
    n_sure = 0
    tied_near = 0
    tied = 0
    for s in range(cnt):
        j = bi[s]
        if bd[s] > last:
            break
        dist = math.sqrt(bd[s])
        along = (qx - p[j, 0]) * t[j, 0] + (qy - p[j, 1]) * t[j, 1]
        beyond = abs(along) - 0.5 * w[j]
        if beyond < 0.0:
            beyond = 0.0
        across = dist * dist - along * along
        if across < 0.0:
            across = 0.0
        near = across + beyond * beyond <= limit * limit
        if bd[s] < last:
            n_sure += 1
            any_sure |= near
        else:
            tied += 1
            tied_near += near
    full = cnt == size and bd[size - 1] == last  # (more samples at the k-th's distance than the buffer holds)
    if any_sure or (tied_near > 0 and tied_near == tied):
        return True, False
    if tied_near > 0:
        # Some of the tied samples are near, some not: it depends on which the tree keeps, unless
        # it keeps them all.
        if tied == k - n_sure and not full:
            return True, False
        return False, True
    return False, full


@kernel(("(f8[:, ::1], f8[:, ::1], f8, f8[:, ::1], f8[:, ::1], f8[::1], f8, f8, f8, i8, i8, i8[::1], i8[::1], "
        "f8[:, ::1], i8, f8, f8, b1[::1], b1[::1])"))
def bridges(pa, pb, step, p, t, w, x0, y0, cell, nx, ny, start, order, ps, k, bound, limit, ok, unsure):
    """paths.cover.on_drawing on the grid: ok (K,) whether every point of the segments pa -> pb
    (K, 2) tested every `step` px (pa + (pb - pa) i / n, 0 < i < n, n = max(1, ceil(length /
    step))) passes _near_one's test; unsure (K,) where one of them is unsure (ok is then
    False)."""
    bd = np.empty(k + 8)
    bi = np.empty(k + 8, np.int64)
    for e in range(pa.shape[0]):
        dx = pb[e, 0] - pa[e, 0]
        dy = pb[e, 1] - pa[e, 1]
        n = int(max(1.0, math.ceil(math.sqrt(dx * dx + dy * dy) / step)))
        good = True
        for i in range(1, n):
            f = i / n
            g = 1 - f
            near, un = _near_one(pa[e, 0] * g + pb[e, 0] * f, pa[e, 1] * g + pb[e, 1] * f, p, t, w, x0, y0, cell,
                                 nx, ny, start, order, ps, k, bound, limit, bd, bi)
            if un:
                unsure[e] = True
            good &= near
        ok[e] = good and not unsure[e]


@njit(cache=True)
def _window_inv(v, v0, inv, reach, n):
    """_window with the division by the cell made a product by its inverse `inv` (the margin
    covers the rounding either way: a window that holds every cell a point within `reach` can
    lie in, which is all a search needs)."""
    a = math.floor((v - reach - v0) * inv - 1e-6)
    b = math.floor((v + reach - v0) * inv + 1e-6)
    if a < 0:
        a = 0
    if b > n - 1:
        b = n - 1
    return int(a), int(b)


@kernel(("(f8[:, ::1], f8[:, ::1], f8[:, ::1], f8[:, ::1], f8[::1], f8, f8, f8, i8, i8, i8[::1], i8[::1], "
        "f8[:, ::1], i8, f8, f8, i8[::1], b1[::1])"))
def match_pieces(q, st, p, t, hw, x0, y0, cell, nx, ny, start, order, ps, k, bound, min_dot, out, unsure):
    """sampling.match_samples(piece_distance=True) on the grid of the samples p (N, 2), their
    tangents t (N, 2) and half lengths hw (N,): for every query point q (M, 2) (finite) with
    tangent st (M, 2), among its k nearest samples within `bound` those whose tangent agrees
    (|t . st| >= min_dot), the first of least squared distance to its piece of line (across:
    the tree's distance squared less the part along t; beyond its ends along t): out (M,) its
    index, or -1. unsure (M,) set where two of the k + 1 nearest lie at the same distance (the
    tree's order decides). The cells of a window's row hold consecutive grid slots: a window is
    one slot range per row, found once for the queries that follow in the same window (line
    samples 1 px apart: most of them)."""
    b2 = bound * bound
    inv = 1.0 / cell
    bd = np.empty(k + 1)
    bi = np.empty(k + 1, np.int64)
    lo = np.empty(ny, np.int64)
    hi = np.empty(ny, np.int64)
    nr = 0  # (rows of the window holding samples)
    wax = wbx = way = wby = -1
    for m in range(q.shape[0]):
        qx = q[m, 0]
        qy = q[m, 1]
        s0 = st[m, 0]
        s1 = st[m, 1]
        ax, bx = _window_inv(qx, x0, inv, bound, nx)
        ay, by = _window_inv(qy, y0, inv, bound, ny)
        if ax != wax or bx != wbx or ay != way or by != wby:
            wax, wbx, way, wby = ax, bx, ay, by
            nr = 0
            for cy in range(ay, by + 1):
                a = start[cy * nx + ax]
                b = start[cy * nx + bx + 1]
                if a < b:
                    lo[nr] = a
                    hi[nr] = b
                    nr += 1
        cnt = 0
        e0 = e1 = e2 = np.inf
        j0 = j1 = j2 = -1
        for r in range(nr):
            for e in range(lo[r], hi[r]):
                dx = ps[e, 0] - qx
                dy = ps[e, 1] - qy
                d2 = dx * dx + dy * dy
                if not d2 < b2:
                    continue
                if k != 2:
                    cnt = _insert(bd, bi, cnt, d2, order[e])
                    continue
                # (k = 2, the lookback's: the three nearest in scalars, as _insert keeps them)
                j = order[e]
                if cnt == 3 and (d2 > e2 or (d2 == e2 and j > j2)):
                    continue
                cnt = min(cnt + 1, 3)
                if cnt >= 2 and (d2 < e1 or (d2 == e1 and j < j1)):
                    e2, j2 = e1, j1
                    if d2 < e0 or (d2 == e0 and j < j0):
                        e1, j1 = e0, j0
                        e0, j0 = d2, j
                    else:
                        e1, j1 = d2, j
                elif cnt >= 2:
                    e2, j2 = d2, j
                elif cnt == 1:
                    e0, j0 = d2, j
        if k == 2:
            bd[0], bi[0], bd[1], bi[1], bd[2], bi[2] = e0, j0, e1, j1, e2, j2
        for s in range(cnt - 1):
            if bd[s] == bd[s + 1]:
                unsure[m] = True
        best = np.inf
        found = -1
        for s in range(min(cnt, k)):
            j = bi[s]
            t0 = t[j, 0]
            t1 = t[j, 1]
            if not abs(t0 * s0 + t1 * s1) >= min_dot:
                continue
            dist = math.sqrt(bd[s])
            along = (qx - p[j, 0]) * t0 + (qy - p[j, 1]) * t1
            beyond = abs(along) - hw[j]
            if beyond < 0.0:
                beyond = 0.0
            cost = dist * dist - along * along
            if cost < 0.0:
                cost = 0.0
            cost += beyond * beyond
            if found < 0 or cost < best:
                found = j
                best = cost
        out[m] = found
