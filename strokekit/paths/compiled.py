"""The brush path stage's compiled loops (numba): the steps of a frame that were k-d tree queries
or chains of small numpy calls. Imports numpy and numba only; loaded on first use by
`paths.kernels.kernels()` (runs that draw no brush paths never import numba), compiled once per
machine and cached on disk (`cache=True`, no fastmath: the same results on every run and in every
process).

Each gives, to the bit, what the step it stands in for gives (tests/test_paths_compiled.py): the
same arithmetic in the same order (sums in the order numpy's bincount and add.reduce take them;
no fused multiply-adds), the same tie rules. The neighbour searches give what scipy's cKDTree
gives for the same points (its squared distance dx * dx + dy * dy, its strict `<` against the
squared bound) and say where they cannot: where candidates tie at the distance that decides (the
tree's choice then depends on its traversal) or a pair lies within rounding of the cover radius;
the caller asks the tree there. Matrix products (surface points, projections) stay numpy's: their
rounding depends on the BLAS kernel.

* Neighbours on a grid of the samples: `grid_ok`, `grid_index`; `knn` (the k nearest); `match_pieces` (the
  lookback, sampling.match_samples with piece distances); `cover` (paths.stage.covering_samples);
  `bridges` (paths.stage.on_drawing).
* Samples and votes: `resample_at`, `resample_points` (sampling.resample_strokes less its surface
  points); `carried` (the votes of carried_votes); `vote_labels` (tracking.votes.sample_labels);
  `segment_runs` (tracking.votes.segment_by_votes after the labels).
* Paths: `link_candidates` (tracking.joins._touching_paths' candidate links), `link_paths` (its
  links and walk); `end_votes`, `continuing_links` (paths.stage.EndVotes: links that continue a
  previous path); `gather` (tracking.joins.gather_paths after its sort); `hairpins`
  (lines.strokeops.drop_hairpins' loop); `greedy_ids` (tracking.votes.assign_ids' pass);
  `id_claims` (paths.stage._path_ids' sums of the claims on the ids).
* u: `jump_order` (heal_jumps' order), `u_trend` (tracking.votes._u_trend),
  `band_terms` (tracking.ufit.PiecewiseU.fit's normal equations), `line_fit` (fit_u's linear
  fit), `vote_groups`, `to_primary` (fit_u's vote groups and their shift by whole periods),
  `knot_intervals`, `piecewise_system`, `piecewise_inliers`, `piecewise_at` (PiecewiseU's fit
  and evaluation), `inner_knots` (its inner knots), `insert_at`, `insert_merge`
  (tracking.joins.insert_points, the knots made points).
* Pieces: `cut_ends`, `cut_assemble` (lines.strokeops.cut_pieces less its surface points);
  `corner_cuts` (pieces cut where their line turns past the join angle).
* Points: `surface_mix` (sampling.surface_between after its depths), `keep_rows`
  (lines.strokeops.keep_points), `take_strokes` (Strokes.select's gathers); `arcs` (Strokes'
  arc lengths and global arc).
* Covers: `cover_runs`, `cover_table` (paths.stage._finish's covered runs, its covers); `one_label`
  (paths.stage._one_label_per_path after its sort).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from strokekit.numba_cache import kernel

#: cover's cells must be wider than this times its radius.
COVER_CELL = 1.001

#: Squared distances within this of the bound are ambiguous for the tree's pair search (it takes
#: whole node pairs whose box distance, tracked incrementally, is below the bound) (px^2).
PAIR_SLACK = 1e-6


@kernel("(f8[:, ::1],)")
def grid_ok(p):
    """Whether the points p (N, 2) can be put on a grid: N > 0, every coordinate finite and so
    is the spread (max - min) along each axis (what np.isfinite(p).all() and a finite np.ptp(p,
    axis=0) say; numpy's reduction along the short axis costs ~0.15 ms on a frame's samples)."""
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


@kernel(("(f8[:, ::1], i8, f8, f8, f8, i8, i8, i8[::1], i8[::1], f8[:, ::1], i8, f8, b1, f8[:, ::1], i8[:,"
        " ::1], b1[::1])"))
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


@kernel(("(f8[:, ::1], f8[:, ::1], f8[::1], i8[::1], b1[::1], i8[::1], i8[::1], f8, f8, f8, i8, i8, i8[::1],"
        " i8[::1], f8[:, ::1], f8, f8, i8[::1])"))
def cover(p, t, w, sk, contour, run, rank_of_run, x0, y0, cell, nx, ny, start, order, ps, radius, min_dot, out):
    """covering_samples on the grid of p (N, 2) (see paths.stage.covering_samples): for every
    contour sample x, the sample y within `radius` (squared distance <= radius**2, the tree's
    pair rule) of another run, the same kind sk and a run of higher rank (rank_of_run lower),
    beside x (|(p_y - p_x) . t_x| <= (w_x + w_y) / 2 - 0.25) with |t_y . t_x| >= min_dot; of
    several the one of the highest-ranked run, then the nearest, then the lowest index. out (N,)
    is set where one is found (left as it is elsewhere). Returns False where a pair of contour
    samples of two runs lies within PAIR_SLACK of the radius (the tree may count it either
    way: the caller asks the tree), else True.
    Each pair is looked at once, cell by cell (a pair's squared distance and its two tests are
    the same bits either way round: negated differences): the cells must be wider than the
    radius (COVER_CELL), so that a pair lies in one cell or two neighbouring ones (else False)."""
    if not radius * COVER_CELL < cell:
        return False
    r2 = radius * radius
    n = p.shape[0]
    # Per grid slot, read one after the other below: run (-1: not a contour) and kind (the rest
    # is looked up for the few pairs within the radius).
    run_s = np.empty(n, np.int64)
    sk_s = np.empty(n, np.int64)
    for q in range(n):
        j = order[q]
        run_s[q] = run[j] if contour[j] else -1
        sk_s[q] = sk[j]
    best = np.full(n, -1, np.int64)
    best_rank = np.zeros(n, np.int64)
    best_d2 = np.zeros(n)
    # The cells that hold samples, in slot order (each slot's cell as grid_index found it: no
    # walk over the empty cells).
    a1 = 0
    while a1 < n:
        cx = min(int((ps[a1, 0] - x0) / cell), nx - 1)
        cy = min(int((ps[a1, 1] - y0) / cell), ny - 1)
        c = cy * nx + cx
        a0 = start[c]
        if a0 != a1 or start[c + 1] <= a0:  # (never: the slots are in cell order)
            return False
        a1 = start[c + 1]
        # The pairs of this cell with itself and the next one in its row, then with the three
        # of the next row: two ranges of consecutive slots.
        e1 = start[c + 2] if cx + 1 < nx else a1
        f0 = f1 = 0
        if cy + 1 < ny:
            f0 = start[c + nx - 1] if cx > 0 else start[c + nx]
            f1 = start[c + nx + 2] if cx + 1 < nx else start[c + nx + 1]
        for q in range(a0, a1):
            rq = run_s[q]
            if rq < 0:
                continue
            qx = ps[q, 0]
            qy = ps[q, 1]
            for part in range(2):
                for q2 in range(q + 1 if part == 0 else f0, e1 if part == 0 else f1):
                    if run_s[q2] < 0 or run_s[q2] == rq or sk_s[q2] != sk_s[q]:
                        continue
                    ddx = ps[q2, 0] - qx
                    ddy = ps[q2, 1] - qy
                    d2 = ddx * ddx + ddy * ddy
                    if d2 > r2 + PAIR_SLACK:
                        continue
                    if abs(d2 - r2) <= PAIR_SLACK:
                        return False
                    if d2 > r2:
                        continue
                    # The sample of the lower-ranked run is the one covered (x), by y.
                    rk1 = rank_of_run[rq]
                    rk2 = rank_of_run[run_s[q2]]
                    if rk2 == rk1:
                        continue
                    if rk2 < rk1:
                        x = order[q]
                        y = order[q2]
                        ry = rk2
                    else:
                        x = order[q2]
                        y = order[q]
                        ry = rk1
                        ddx = -ddx
                        ddy = -ddy
                    tx0 = t[x, 0]
                    tx1 = t[x, 1]
                    along = abs(ddx * tx0 + ddy * tx1)
                    if not along <= 0.5 * (w[x] + w[y]) - 0.25:
                        continue
                    if not abs(t[y, 0] * tx0 + t[y, 1] * tx1) >= min_dot:
                        continue
                    b = best[x]
                    if b < 0 or ry < best_rank[x] or (ry == best_rank[x] and (d2 < best_d2[x] or (
                            d2 == best_d2[x] and y < b))):
                        best[x] = y
                        best_rank[x] = ry
                        best_d2[x] = d2
    for x in range(n):
        if best[x] >= 0:
            out[x] = best[x]
    return True


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
    """paths.stage.on_drawing's test of one point (qx, qy) on the grid of the line samples p (N,
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


@kernel(("(f8[:, ::1], f8[:, ::1], f8, f8[:, ::1], f8[:, ::1], f8[::1], f8, f8, f8, i8, i8, i8[::1], i8[::1],"
        " f8[:, ::1], i8, f8, f8, b1[::1], b1[::1])"))
def bridges(pa, pb, step, p, t, w, x0, y0, cell, nx, ny, start, order, ps, k, bound, limit, ok, unsure):
    """paths.stage.on_drawing on the grid: ok (K,) whether every point of the segments pa -> pb
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


@kernel(("(f8[:, ::1], f8[:, ::1], f8[:, ::1], f8[:, ::1], f8[::1], f8, f8, f8, i8, i8, i8[::1], i8[::1], f8[:,"
        " ::1], i8, f8, f8, i8[::1], b1[::1])"))
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


@njit(cache=True)
def _sort_by_key(o, lo, hi, key, buf, bounds):
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


@njit(cache=True)
def _argsort(key):
    """np.argsort(key, kind="stable") of a float array (not NaN) by _sort_by_key (numba's own
    merge sort costs seconds of compile)."""
    n = key.shape[0]
    o = np.arange(n)
    _sort_by_key(o, 0, n, key, np.empty(n, np.int64), np.empty(n + 1, np.int64))
    return o


@njit(cache=True)
def _buckets(st):
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


@kernel("(i8[::1], i8[::1], f8[::1], f8[::1], f8, f8)")
def jump_order(st, vid, s, u, P, min_jump):
    """heal_jumps' order of the votes, np.lexsort((s, vid, st)) (st, vid >= 0, vid < 2**53): by
    path (bucketed), then id, then s, each sort stable; and whether a step between two votes of
    one path and id, next to each other in it, has |du - ds / P| >= min_jump (rounded: a jump to
    heal)."""
    V = st.shape[0]
    S, start, o = _buckets(st)
    vf = vid.astype(np.float64)
    buf = np.empty(V, np.int64)
    bounds = np.empty(V + 1, np.int64)
    for j in range(S):
        _sort_by_key(o, start[j], start[j + 1], vf, buf, bounds)
        g0 = start[j]
        while g0 < start[j + 1]:
            g1 = g0 + 1
            while g1 < start[j + 1] and vid[o[g1]] == vid[o[g0]]:
                g1 += 1
            _sort_by_key(o, g0, g1, s, buf, bounds)
            g0 = g1
    for i in range(1, o.shape[0]):
        a = o[i - 1]
        b = o[i]
        if st[a] == st[b] and vid[a] == vid[b] and abs((u[b] - u[a]) - (s[b] - s[a]) / P) >= min_jump:
            if np.round((u[b] - u[a]) - (s[b] - s[a]) / P) != 0.0:
                return o, True
    return o, False


@kernel("(i8[::1], f8[::1], f8[::1], i8)")
def u_trend(rk, pk, u, R):
    """tracking.votes._u_trend after its selection: the votes rk (K,) (run), pk (K,) (position,
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
        n_runs, start, o = _buckets(rk)
        buf = np.empty(K, np.int64)
        bounds = np.empty(K + 1, np.int64)
        for r in range(n_runs):
            _sort_by_key(o, start[r], start[r + 1], key, buf, bounds)
    else:
        o = _argsort(key)
    for i in range(1, K):
        a = o[i - 1]
        b = o[i]
        if rk[b] == rk[a]:
            out[rk[b]] += np.sign(u[b] - u[a]) * (pk[b] - pk[a])
    return out


@kernel("(i8[::1], i8[::1], i8[::1], i8, i8)")
def link_paths(a, b, e_run, n, S):
    """tracking.joins._touching_paths' links and walk: the candidate links a, b (L,) between
    stroke ends (node i < n: the start of stroke e_run[i], else its end), in the order they are
    taken (each end in one link at most), walked into paths. Returns group (S,) (the lowest
    stroke of each path), rev (S,) and pos (S,) as _touching_paths does."""
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


@kernel("(f8[:, ::1], i8[::1], i8[::1], i8[::1], f8, f8, f8, f8)")
def link_candidates(P, offsets, kind, label, tol, other, cos_min, free_px):
    """tracking.joins._touching_paths' candidate links of labelled strokes (label (S,), -1: none),
    up to its bridge test: the open strokes' ends (e_run (2n,): starts, then ends), their points
    pt (2n, 2); the pairs a < b (in _close_pair_arrays' order: by the stable x order of pt, then
    by partner) within max(tol, other) px; per pair whether it may link (ok: two strokes of one
    kind, turning by at most acos(cos_min), of one label within tol or one unlabelled within
    other), its cosine of the turn `straight`, its gap, its tier (2 one label, 1 one of them
    unlabelled, 0 none), and `far` where ok and the gap exceeds free_px (the bridge decides)."""
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
    r = max(tol, other)
    m = 2 * n
    xs = np.empty(m)
    for e in range(m):
        xs[e] = pt[e, 0]
    o = _argsort(xs)
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
    ok = np.zeros(K, np.bool_)
    far = np.zeros(K, np.bool_)
    straight = np.empty(K)
    gap = np.empty(K)
    tier = np.empty(K, np.int64)
    for k in range(K):
        x = a[k]
        y = b[k]
        ra = e_run[x]
        rb = e_run[y]
        straight[k] = -(d[x, 0] * d[y, 0] + d[x, 1] * d[y, 1])
        ddx = pt[x, 0] - pt[y, 0]
        ddy = pt[x, 1] - pt[y, 1]
        gap[k] = math.sqrt(ddx * ddx + ddy * ddy)
        la = label[ra]
        lb = label[rb]
        same = la == lb and la >= 0
        tier[k] = 2 * same + ((la < 0) != (lb < 0))
        good = ra != rb and kind[ra] == kind[rb] and straight[k] >= cos_min
        good = good and ((same and gap[k] <= tol) or ((la < 0 or lb < 0) and gap[k] <= other))
        ok[k] = good
        far[k] = good and gap[k] > free_px
    return n, e_run, pt, a, b, ok, straight, gap, tier, far


@kernel("(i8[::1], f8[::1], f8[::1], i8[::1], i8[::1], f8[::1], f8, f8)")
def end_votes(vk, s_in, u, vid, label, plen, P, reach):
    """paths.stage.EndVotes.of: the votes (V,) landing on piece vk at arc length s_in (px) with
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
    """paths.stage.EndVotes.continues for the links (L,) of one label (tier 2; the others: False)."""
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


@njit(cache=True)
def _classes(codes, contour, n_kinds):
    """paths.stage._kind_class of kind codes (kind + n_kinds x occlusion level): their hidden
    levels as one, then the contour kinds (contour (n_kinds,)) in one class per level, -1 -
    level; every other code its own class."""
    out = np.empty(codes.shape[0], np.int64)
    for i in range(codes.shape[0]):
        c = codes[i] % n_kinds + n_kinds * min(codes[i] // n_kinds, 1)
        out[i] = -1 - c // n_kinds if contour[c % n_kinds] else c
    return out


@kernel(("(i8[::1], f8[:, ::1], i8[::1], i8[::1], i8[::1], i8[::1], b1[::1], i8, f8[:, ::1], f8[:, ::1],"
        " f8[::1], f8[::1], f8[::1], i8[::1], i8[::1], f8[::1], f8[:, ::1], i8)"))
def carried(rm, rq, sub, kind_d, Dstroke, kind_v, contour, n_kinds, Vp, Vt, Vw, Vu, Vs, Vstroke, Vids, Dw, Dt, step):
    """paths.stage.carried_votes from the lookback's matches: rm (M,) the previous path sample
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
        # du/ds at the path sample, from its neighbours on its stroke (tracking.ufit._local_slope).
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


@njit(cache=True)
def _sorted_unique(x):
    """np.unique of integers (|x| < 2**53: exact as floats)."""
    o = _argsort(x.astype(np.float64))
    out = np.empty(x.shape[0], x.dtype)
    n = 0
    for j in range(x.shape[0]):
        v = x[o[j]]
        if n == 0 or v != out[n - 1]:
            out[n] = v
            n += 1
    return out[:n].copy()


@kernel("(f8[:, ::1], b1[::1], i8[::1], f8, f8)")
def hairpins(P, ends, i, cos_max, max_px):
    """lines.strokeops.drop_hairpins' points kept (N,): P (N, 2) the points, ends (N,) the
    strokes' ends, i the sorted interior points looked at (hairpin_candidates)."""
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
        i = _sorted_unique(nxt[:t])
    return alive


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


@kernel("(i8, i8[::1], i8[::1], i8, f8[::1])")
def vote_labels(D, o, key, M, w):
    """tracking.votes.sample_labels: (D,) the id of most vote weight on every sample (ties: the
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


@kernel(("(i8[::1], i8[::1], f8[::1], f8, i8[::1], i8[::1], f8[::1], b1[::1], i8[::1], i8[::1], f8[::1],"
        " i8[::1])"))
def id_claims(path_of, p_label, plen, label_weight, vk, vid, vw, ok, ok_k, oid, ow, known):
    """paths.stage._path_ids' claims of the paths on the previous ids, summed per (path, id): the
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
    top, start, o = _buckets(pr)
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


@kernel("(i8[::1], f8[::1], f8[::1], f8[::1], f8[:, ::1], f8[:, ::1], f8[:, ::1], f8[:, ::1])")
def band_terms(k, a, w, u, f0, f1, f2, f3):
    """tracking.ufit.PiecewiseU.fit's banded normal equations: the votes' terms (vote i: knots
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


@kernel("(i8[::1], i8[::1], f8[::1], f8[::1], f8[::1], f8[::1], f8)")
def pieces_of_runs(cover, run, s, w, r_s0, r_s1, min_piece_px):
    """paths.stage.brush_step's pieces: the stretches of samples (N,) of one run not covered
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


@kernel("(i8[::1], f8[::1], f8[::1], f8[::1], f8[::1], f8[::1], f8)")
def line_fit(st, s, u, w, mask, lam, b0):
    """tracking.kalnins.fit_u's linear fit u = a + b s per stroke (S = lam.shape[0]) of the votes
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
    """tracking.kalnins.fit_u's vote groups: the distinct (stroke st, id vid) pairs of the votes
    (V,) (st, vid >= 0, vid < 2**53) in (stroke, id) order, gkeys (G, 2); each vote's group ginv
    (V,); each group's weight gw (G,) (w summed in vote order, as np.bincount takes it); primary
    (G,) the first group of each stroke holding the stroke's most weight
    (tracking.votes._first_max_per_group). The votes bucketed by stroke, each bucket sorted by
    id (a path's votes come in runs of one id)."""
    V = st.shape[0]
    S, start, perm = _buckets(st)
    vf = vid.astype(np.float64)
    buf = np.empty(V, np.int64)
    bounds = np.empty(V + 1, np.int64)
    ginv = np.empty(V, np.int64)
    gst = np.empty(V, np.int64)
    gid = np.empty(V, np.int64)
    G = 0
    for j in range(S):
        _sort_by_key(perm, start[j], start[j + 1], vf, buf, bounds)
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
    """tracking.kalnins.fit_u's shift of the votes u (V,) of other groups than their stroke's
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
    """tracking.ufit.PiecewiseU's interval of arc length s (V,) on stroke st (V,) (n (S,)
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


@kernel(("(i8[::1], f8[::1], f8[::1], f8[::1], f8[::1], i8[::1], f8[::1], i8[::1], f8[::1], f8[::1], f8[::1],"
        " f8, f8, f8)"))
def piecewise_system(k, a, w, inlier, u, n, h, base, L, prior_a, prior_b, b0, stretch_weight, bend_weight):
    """tracking.ufit.PiecewiseU.fit's banded system (band (3, nk), rhs (nk,)) for the votes at
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


@kernel("(f8[::1], f8[::1], i8[::1], i8[::1], f8[::1])")
def insert_at(base, G, offsets, stroke, s):
    """tracking.joins.insert_points' new points: at arc length s (px) of strokes `stroke`, the
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


@kernel(("(f8[:, ::1], f8[:, ::1], i8[::1], f8[::1], f8[::1], i8[::1], i8[::1], i8[::1], f8[::1], f8[::1],"
        " i8[::1], f8[:, ::1])"))
def insert_merge(P, X, F, U, G, offsets, i, j, a, g, stroke, Xn):
    """tracking.joins.insert_points' strokes: the points P, X, F, U (N) with the new ones
    (interpolated at fraction a of segments i -> j; surface points Xn) merged in by global arc
    (G (N,) increasing; g (K,) non-decreasing: an old point before a new one at the same
    place). Returns (in order, P, X, F, U, offsets); in order False (and nothing merged) where g
    is not in order."""
    N = G.shape[0]
    K = g.shape[0]
    for k in range(1, K):
        if g[k] < g[k - 1]:
            return False, P[:0], X[:0], F[:0], U[:0], offsets[:0]
    M = N + K
    P2 = np.empty((M, 2))
    X2 = np.empty((M, 3))
    F2 = np.empty(M, F.dtype)
    U2 = np.empty(M)
    m = 0
    k = 0
    for q in range(N):
        while k < K and g[k] < G[q]:
            f = a[k]
            P2[m, 0] = P[i[k], 0] * (1 - f) + P[j[k], 0] * f
            P2[m, 1] = P[i[k], 1] * (1 - f) + P[j[k], 1] * f
            X2[m, 0] = Xn[k, 0]
            X2[m, 1] = Xn[k, 1]
            X2[m, 2] = Xn[k, 2]
            F2[m] = F[i[k]] if f < 0.5 else F[j[k]]
            U2[m] = U[i[k]] * (1 - f) + U[j[k]] * f
            m += 1
            k += 1
        P2[m, 0] = P[q, 0]
        P2[m, 1] = P[q, 1]
        X2[m, 0] = X[q, 0]
        X2[m, 1] = X[q, 1]
        X2[m, 2] = X[q, 2]
        F2[m] = F[q]
        U2[m] = U[q]
        m += 1
    while k < K:
        f = a[k]
        P2[m, 0] = P[i[k], 0] * (1 - f) + P[j[k], 0] * f
        P2[m, 1] = P[i[k], 1] * (1 - f) + P[j[k], 1] * f
        X2[m, 0] = Xn[k, 0]
        X2[m, 1] = Xn[k, 1]
        X2[m, 2] = Xn[k, 2]
        F2[m] = F[i[k]] if f < 0.5 else F[j[k]]
        U2[m] = U[i[k]] * (1 - f) + U[j[k]] * f
        m += 1
        k += 1
    S = offsets.shape[0] - 1
    off = np.empty(S + 1, np.int64)
    off[0] = 0
    extra = np.zeros(S, np.int64)
    for k in range(K):
        extra[stroke[k]] += 1
    for t in range(S):
        off[t + 1] = off[t] + (offsets[t + 1] - offsets[t]) + extra[t]
    return True, P2, X2, F2, U2, off


@kernel("(f8[:, ::1], i8[::1], i8[::1], f8, f8)")
def hairpin_points(P, offsets, at, cos_max, max_px):
    """lines.strokeops.drop_hairpins' points kept (N,), from the strokes' offsets (S + 1,) and the
    points looked at `at` (hairpin_candidates' ends and interior points, then hairpins)."""
    n = P.shape[0]
    ends = np.zeros(n, np.bool_)
    for k in range(offsets.shape[0] - 1):
        if offsets[k + 1] > offsets[k]:  # (an empty stroke has no ends)
            ends[offsets[k]] = True
            ends[offsets[k + 1] - 1] = True
    i = _sorted_unique(at)
    m = 0
    for e in range(i.shape[0]):
        c = i[e]
        if c > 0 and c < n - 1 and not ends[c]:
            i[m] = c
            m += 1
    return hairpins(P, ends, i[:m].copy(), cos_max, max_px)


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


@kernel("(f8[:, ::1], f8[:, ::1], i8[::1], i8[::1], i8[::1], i8[::1], i8[::1], f8[::1], f8[:, ::1])")
def cut_assemble(P, X, F, lo, n_in, i, j, a, Xe):
    """cut_pieces' points (not reversed): each piece's interpolated start, its interior original
    points, its interpolated end; Xe (2K, 3) the ends' surface points. Returns points, surface,
    face and offsets."""
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
        for e in range(2):
            m = k + e * K
            q = t if e == 0 else off[k + 1] - 1
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
            p[q, 0] = P[src, 0]
            p[q, 1] = P[src, 1]
            x[q, 0] = X[src, 0]
            x[q, 1] = X[src, 1]
            x[q, 2] = X[src, 2]
            fc[q] = F[src]
    return p, x, fc, off


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
    """lines.strokeops.keep_points: the points (P (N, 2), surface X (N, 3), face F, u U) where
    alive (N,) is true, and the strokes' new offsets."""
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


@kernel("(i8[::1], i8[::1], i8[::1], i8[::1], f8[::1], f8[::1])")
def cover_runs(cover, smp_piece, path_of, stroke, s, w):
    """paths.stage._finish's covered runs: the samples covered (cover >= 0) by a sample of a
    drawn piece (smp_piece of the covering sample >= 0), in runs of consecutive samples of one
    line covered by one path (path_of the piece's path). Per run: its line, its start and end
    (px: first sample's s - w / 2, last sample's s + w / 2) and its path."""
    N = cover.shape[0]
    cl = np.empty(N, np.int64)
    c0 = np.empty(N)
    c1 = np.empty(N)
    cp = np.empty(N, np.int64)
    R = 0
    last = -2
    for i in range(N):
        if cover[i] < 0:
            continue
        k = smp_piece[cover[i]]
        if k < 0:
            continue
        pth = path_of[k]
        if R == 0 or i - last != 1 or stroke[i] != stroke[last] or pth != cp[R - 1]:
            if R > 0:
                c1[R - 1] = s[last] + 0.5 * w[last]
            cl[R] = stroke[i]
            c0[R] = s[i] - 0.5 * w[i]
            cp[R] = pth
            R += 1
        last = i
    if R > 0:
        c1[R - 1] = s[last] + 0.5 * w[last]
    return cl[:R].copy(), c0[:R].copy(), c1[:R].copy(), cp[:R].copy()


@kernel("(i8[::1], i8[::1], f8[::1], f8[::1], i8[::1], f8[::1], f8[::1], i8[::1], i8)")
def cover_table(path_of, p_line, p_s0, p_s1, cl, c0, c1, cp, S):
    """paths.stage._finish's covers: the drawn pieces (path path_of, line p_line, from p_s0 to
    p_s1 px) and the covered runs (cl, c0, c1, cp likewise), by path, the drawn ones first, then
    by line, then by start, ties in that order (np.lexsort((s0, line, ~drawn, path)) of the two
    joined). Returns the offsets (max(S, top path + 1) + 1,) of each path's covers (np.bincount's
    counts summed), their lines, starts, ends and whether drawn."""
    P = path_of.shape[0]
    n = P + cp.shape[0]
    path = np.empty(n, np.int64)
    line = np.empty(n)
    s0 = np.empty(n)
    for i in range(n):
        if i < P:
            path[i] = path_of[i]
            line[i] = p_line[i]
            s0[i] = p_s0[i]
        else:
            path[i] = cp[i - P]
            line[i] = cl[i - P]
            s0[i] = c0[i - P]
    # By path, stably (the drawn pieces, the first P, come first in each), then each part sorted
    # by start, then by line (stable sorts: by line, then start).
    top, start, o = _buckets(path)
    offsets = np.empty(max(S, top) + 1, np.int64)
    for r in range(offsets.shape[0]):
        offsets[r] = start[r] if r <= top else n
    buf = np.empty(n, np.int64)
    bounds = np.empty(n + 1, np.int64)
    for r in range(top):
        m = start[r]
        while m < start[r + 1] and o[m] < P:
            m += 1
        _sort_by_key(o, start[r], m, s0, buf, bounds)
        _sort_by_key(o, start[r], m, line, buf, bounds)
        _sort_by_key(o, m, start[r + 1], s0, buf, bounds)
        _sort_by_key(o, m, start[r + 1], line, buf, bounds)
    out_line = np.empty(n, np.int64)
    out_s0 = np.empty(n)
    out_s1 = np.empty(n)
    drawn = np.empty(n, np.bool_)
    for q in range(n):
        i = o[q]
        if i < P:
            out_line[q] = p_line[i]
            out_s0[q] = p_s0[i]
            out_s1[q] = p_s1[i]
            drawn[q] = True
        else:
            out_line[q] = cl[i - P]
            out_s0[q] = c0[i - P]
            out_s1[q] = c1[i - P]
            drawn[q] = False
    return offsets, out_line, out_s0, out_s1, drawn


@kernel("(i8[::1], i8[::1], i8[::1])")
def one_label(order, group, label):
    """paths.stage._one_label_per_path after its sort (order: the pieces by group, then position):
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
