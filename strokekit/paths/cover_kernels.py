"""The cover's loops (numba), for paths.cover: the covering sample of every line sample on the
grid of the samples (`cover`), the covered runs beside each path (`cover_runs`) and the covers'
table (`cover_table`). The pairs within the radius are those of cKDTree.query_pairs; a pair within
rounding of the radius (PAIR_SLACK) is left to the tree."""

from __future__ import annotations

import numpy as np

from strokekit.numba_cache import kernel
from strokekit.tracking.sort_kernels import buckets, sort_by_key

#: cover's cells must be wider than this times its radius.
COVER_CELL = 1.001

#: Squared distances within this of the bound are ambiguous for the tree's pair search (it takes
#: whole node pairs whose box distance, tracked incrementally, is below the bound) (px^2).
PAIR_SLACK = 1e-6


@kernel(("(f8[:, ::1], f8[:, ::1], f8[::1], i8[::1], b1[::1], i8[::1], i8[::1], f8, f8, f8, i8, i8, i8[::1], "
        "i8[::1], f8[:, ::1], f8, f8, i8[::1])"))
def cover(p, t, w, sk, contour, run, rank_of_run, x0, y0, cell, nx, ny, start, order, ps, radius, min_dot, out):
    """covering_samples on the grid of p (N, 2) (see paths.cover.covering_samples): for every
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


@kernel("(i8[::1], i8[::1], i8[::1], i8[::1], f8[::1], f8[::1])")
def cover_runs(cover, smp_piece, path_of, stroke, s, w):
    """paths.cover.covered_runs' runs: the samples covered (cover >= 0) by a sample of a
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
    """paths.cover.covered_runs' table: the drawn pieces (path path_of, line p_line, from p_s0 to
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
    top, start, o = buckets(path)
    offsets = np.empty(max(S, top) + 1, np.int64)
    for r in range(offsets.shape[0]):
        offsets[r] = start[r] if r <= top else n
    buf = np.empty(n, np.int64)
    bounds = np.empty(n + 1, np.int64)
    for r in range(top):
        m = start[r]
        while m < start[r + 1] and o[m] < P:
            m += 1
        sort_by_key(o, start[r], m, s0, buf, bounds)
        sort_by_key(o, start[r], m, line, buf, bounds)
        sort_by_key(o, m, start[r + 1], s0, buf, bounds)
        sort_by_key(o, m, start[r + 1], line, buf, bounds)
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
