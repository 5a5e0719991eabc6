"""Compiled loops (numba) of hidden-line drawings (`LineOptions.occlusion`): the pair searches
that numpy does with large temporaries. Imports numpy and numba only; loaded on first use
(`lines.kernels`: drawings of visible lines only never import numba). Every float operation is
the one numpy does, in the same order, so results are bit for bit numpy's.

* `outline_crossings`: where segments' images cross the images of outline edges in front of
  them (`occlusion.outline_crossings`), candidates from a grid of GRID_PX cells.
* `close_pairs`: the pairs of samples of two strokes of one kind code closer than a radius
  (`strokeops.drop_overlaps`), from a grid of cells one radius wide.
* `crossing_deltas`: what each outline crossing does to the level (`occlusion.crossing_deltas`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from strokekit.numba_cache import kernel


@njit(cache=True, error_model="numpy")
def _segment_cells(pa, pb, grid):
    """(cell x, cell y, segment of each): the grid cells (`grid` px wide) that each segment pa ->
    pb (px) may pass through: cut into ceil(L / grid) pieces, the cells of each piece's bounding
    box (at most 2 x 2); non-finite segments have none. A segment's cells come together."""
    n = pa.shape[0]
    m = np.zeros(n, np.int64)
    total = 0
    for i in range(n):
        ax, ay, bx, by = pa[i, 0], pa[i, 1], pb[i, 0], pb[i, 1]
        if not (np.isfinite(ax) and np.isfinite(ay) and np.isfinite(bx) and np.isfinite(by)):
            continue
        dx, dy = bx - ax, by - ay
        L = math.sqrt(dx * dx + dy * dy)
        mi = int(max(1.0, math.ceil(L / grid)))
        m[i] = mi
        total += mi
    gx = np.empty(4 * total, np.int64)
    gy = np.empty(4 * total, np.int64)
    owner = np.empty(4 * total, np.int64)
    c = 0
    for i in range(n):
        mi = m[i]
        if mi == 0:
            continue
        ax, ay = pa[i, 0], pa[i, 1]
        dx, dy = pb[i, 0] - ax, pb[i, 1] - ay
        for k in range(mi):
            f0 = k / mi
            f1 = (k + 1) / mi
            x0, y0 = ax + f0 * dx, ay + f0 * dy
            x1, y1 = ax + f1 * dx, ay + f1 * dy
            lox = np.int64(math.floor(min(x0, x1) / grid))
            loy = np.int64(math.floor(min(y0, y1) / grid))
            hix = np.int64(math.floor(max(x0, x1) / grid))
            hiy = np.int64(math.floor(max(y0, y1) / grid))
            for ddx in range(2):
                for ddy in range(2):
                    cx, cy = lox + ddx, loy + ddy
                    if cx <= hix and cy <= hiy:
                        gx[c], gy[c], owner[c] = cx, cy, i
                        c += 1
    return gx[:c], gy[:c], owner[:c]


@kernel(("(f8[:, ::1], f8[:, ::1], f8[::1], f8[::1], i8[::1], i8[::1], f8[:, ::1], f8[:, ::1], f8[::1], "
        "f8[::1], i8[::1], i8[::1], b1, f8)"), error_model="numpy")
def outline_crossings(pa, pb, za, zb, va, vb, qa, qb, wa, wb, e0, e1, ortho, grid):
    """(segment (K,), s (K,), outline edge (K,), u (K,), depth gap (K,)), sorted by segment then
    s, each place once per outline edge: where segment f (pa -> pb, px; view depths za, zb; mesh vertices va,
    vb, -1 for none) crosses the image of outline edge c (qa -> qb, depths wa, wb, vertices e0,
    e1) at 0 < s < 1, 0 <= u <= 1, sharing no vertex with it, the outline nearer there (view
    depth: 1/z linear on screen, z when `ortho`). u is the place's parameter along the outline
    edge, the gap (zf - zc) / zf the outline's relative depth in front of the segment there.
    Candidates: the pairs that share a cell of `_segment_cells` (the outline's bucketed in a grid
    over their cells' box, coarser where that box would exceed 16 buckets an outline cell: the crossing point
    lies in a cell of both), each pair once; each is first tested on depth (the outline's nearer
    end before the segment's far end) and bounding boxes, then as numpy did."""
    fx, fy, of = _segment_cells(pa, pb, grid)
    cx, cy, oc = _segment_cells(qa, qb, grid)
    cap = max(16, pa.shape[0])
    out_f = np.empty(cap, np.int64)
    out_s = np.empty(cap)
    out_c = np.empty(cap, np.int64)
    out_u = np.empty(cap)
    out_g = np.empty(cap)
    n_out = 0
    if oc.shape[0] == 0 or of.shape[0] == 0:
        return out_f[:0], out_s[:0], out_c[:0], out_u[:0], out_g[:0]
    x0, y0, x1, y1 = cx.min(), cy.min(), cx.max(), cy.max()
    # Buckets of merge x merge cells: at most 16 an outline cell (at least 2^16), so that outlines
    # spread far apart (a huge image, an edge far off screen) cost no more memory than their cells.
    merge = np.int64(1)  # grid cells a bucket holds along each axis
    most = max(np.int64(1 << 16), 16 * np.int64(oc.shape[0]))
    while ((x1 - x0) // merge + 1) * ((y1 - y0) // merge + 1) > most:
        merge *= 2
    nx, ny = (x1 - x0) // merge + 1, (y1 - y0) // merge + 1
    start = np.zeros(nx * ny + 1, np.int64)
    for k in range(oc.shape[0]):
        start[((cx[k] - x0) // merge) * ny + (cy[k] - y0) // merge + 1] += 1
    for k in range(nx * ny):
        start[k + 1] += start[k]
    fill = start[:-1].copy()
    members = np.empty(oc.shape[0], np.int64)
    for k in range(oc.shape[0]):
        b = ((cx[k] - x0) // merge) * ny + (cy[k] - y0) // merge
        members[fill[b]] = oc[k]
        fill[b] += 1
    seen = np.full(qa.shape[0], -1, np.int64)  # the last segment each outline edge was tested with
    for r in range(of.shape[0]):
        f = of[r]
        if fx[r] < x0 or fx[r] > x1 or fy[r] < y0 or fy[r] > y1:
            continue
        b = ((fx[r] - x0) // merge) * ny + (fy[r] - y0) // merge
        far = max(za[f], zb[f])
        lo_fx, hi_fx = min(pa[f, 0], pb[f, 0]), max(pa[f, 0], pb[f, 0])
        lo_fy, hi_fy = min(pa[f, 1], pb[f, 1]), max(pa[f, 1], pb[f, 1])
        ax, ay = pb[f, 0] - pa[f, 0], pb[f, 1] - pa[f, 1]
        for j in range(start[b], start[b + 1]):
            c = members[j]
            if seen[c] == f:
                continue
            seen[c] = f
            if not (min(wa[c], wb[c]) < far):
                continue
            if not (min(qa[c, 0], qb[c, 0]) <= hi_fx and lo_fx <= max(qa[c, 0], qb[c, 0])):
                continue
            if not (min(qa[c, 1], qb[c, 1]) <= hi_fy and lo_fy <= max(qa[c, 1], qb[c, 1])):
                continue
            if e0[c] == va[f] or e0[c] == vb[f] or e1[c] == va[f] or e1[c] == vb[f]:
                continue
            ex, ey = qb[c, 0] - qa[c, 0], qb[c, 1] - qa[c, 1]
            wx = qa[c, 0] - pa[f, 0]
            wy = qa[c, 1] - pa[f, 1]
            den = ax * ey - ay * ex
            if den == 0:
                continue
            # 0 < s < 1 needs a numerator of den's sign and smaller size (rounding is monotone):
            # most candidates fail this before any division.
            num = wx * ey - wy * ex
            if (num > 0) != (den > 0) or abs(num) > abs(den):
                continue
            s = num / den
            u = (wx * ay - wy * ax) / den
            if not (s > 0 and s < 1 and u >= 0 and u <= 1):
                continue
            if ortho:
                zf = (1 - s) * za[f] + s * zb[f]
                zc = (1 - u) * wa[c] + u * wb[c]
            else:
                zf = 1.0 / ((1 - s) / za[f] + s / zb[f])
                zc = 1.0 / ((1 - u) / wa[c] + u / wb[c])
            if not (zc < zf):
                continue
            if n_out == cap:
                cap *= 2
                out_f, out_s, out_c = _grown(out_f, cap), _grown(out_s, cap), _grown(out_c, cap)
                out_u, out_g = _grown(out_u, cap), _grown(out_g, cap)
            out_f[n_out] = f
            out_s[n_out] = s
            out_c[n_out] = c
            out_u[n_out] = u
            out_g[n_out] = (zf - zc) / zf
            n_out += 1
    # The places come grouped by segment, in segment order: each group sorted by s (stable, an
    # insertion sort: a segment crosses few outline edges) gives np.lexsort((s, f))'s order.
    a = 0
    while a < n_out:
        b = a + 1
        while b < n_out and out_f[b] == out_f[a]:
            b += 1
        for i in range(a + 1, b):
            s_i, c_i, u_i, g_i = out_s[i], out_c[i], out_u[i], out_g[i]
            j = i
            while j > a and out_s[j - 1] > s_i:
                out_s[j], out_c[j], out_u[j], out_g[j] = out_s[j - 1], out_c[j - 1], out_u[j - 1], out_g[j - 1]
                j -= 1
            out_s[j], out_c[j], out_u[j], out_g[j] = s_i, c_i, u_i, g_i
        a = b
    return out_f[:n_out], out_s[:n_out], out_c[:n_out], out_u[:n_out], out_g[:n_out]


@njit(cache=True)
def _grown(x, cap):
    """x copied into a new array of length cap."""
    y = np.empty(cap, x.dtype)
    y[:x.shape[0]] = x
    return y


@kernel("(f8[:, ::1], i8[::1], i1[::1], f8, Omitted(16.0))", error_model="numpy")
def close_pairs(p, stroke, code, radius, per_point=16.0):
    """(i (K,), j (K,)): the pairs of points p (M, 2) (px, finite) within `radius` of each other
    (dx dx + dy dy <= radius^2, the test of scipy's cKDTree.query_pairs) whose strokes `stroke`
    (M,) differ and whose codes `code` (M,) agree, each pair once, in no set order. A grid over
    the points' bounding box, cells a little wider than `radius` (a pair within reach lies in
    one cell or two neighbouring ones; wider cells where the points are few and spread out, at
    most 16 cells a point), the points copied out in cell order (a counting sort) so that the
    scan of a cell reads contiguous memory."""
    n = p.shape[0]
    out_i = np.empty(max(16, n), np.int64)
    out_j = np.empty(max(16, n), np.int64)
    if n < 2:
        return out_i[:0], out_j[:0]
    x0, y0, x1, y1 = p[0, 0], p[0, 1], p[0, 0], p[0, 1]
    for i in range(n):
        x0, x1 = min(x0, p[i, 0]), max(x1, p[i, 0])
        y0, y1 = min(y0, p[i, 1]), max(y1, p[i, 1])
    cell = radius * (1.0 + 1e-9)  # (a pair at exactly radius never lands two cells apart)
    area = (x1 - x0 + cell) * (y1 - y0 + cell)
    if area > per_point * n * cell * cell:
        cell = math.sqrt(area / (per_point * n))
    nx = int((x1 - x0) / cell) + 1
    ny = int((y1 - y0) / cell) + 1
    g = np.empty(n, np.int64)
    start = np.zeros(nx * ny + 1, np.int32)
    for i in range(n):
        cx = min(int((p[i, 0] - x0) / cell), nx - 1)
        cy = min(int((p[i, 1] - y0) / cell), ny - 1)
        g[i] = cx * ny + cy
        start[g[i] + 1] += 1
    for c in range(nx * ny):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    idx = np.empty(n, np.int64)
    xs = np.empty(n)
    ys = np.empty(n)
    ss = np.empty(n, np.int64)
    ks = np.empty(n, np.int64)
    for i in range(n):
        k = fill[g[i]]
        fill[g[i]] += 1
        idx[k], xs[k], ys[k], ss[k], ks[k] = i, p[i, 0], p[i, 1], stroke[i], code[i]
    r2 = radius * radius
    cap = out_i.shape[0]
    n_out = 0
    for a in range(n):  # in cell order; each pair once: the half of the neighbourhood after a
        ca = g[idx[a]]
        cx, cy = ca // ny, ca % ny
        # Cells (cx, cy..cy+1) from a on, and (cx+1, cy-1..cy+1): two runs of the cell order.
        b0, b1 = a + 1, start[cx * ny + min(cy + 1, ny - 1) + 1]
        if cx + 1 < nx:
            b2, b3 = start[(cx + 1) * ny + max(cy - 1, 0)], start[(cx + 1) * ny + min(cy + 1, ny - 1) + 1]
        else:
            b2, b3 = 0, 0
        for run in range(2):
            lo, hi = (b0, b1) if run == 0 else (b2, b3)
            for b in range(lo, hi):
                if ss[b] == ss[a] or ks[b] != ks[a]:
                    continue
                dx = xs[a] - xs[b]
                dy = ys[a] - ys[b]
                if dx * dx + dy * dy <= r2:
                    if n_out == cap:
                        cap *= 2
                        out_i, out_j = _grown(out_i, cap), _grown(out_j, cap)
                    out_i[n_out] = idx[a]
                    out_j[n_out] = idx[b]
                    n_out += 1
    return out_i[:n_out], out_j[:n_out]


@kernel(("(i8[::1], f8[::1], f8[::1], f8[:, ::1], i8[:, ::1], i8[:, ::1], i8[:, ::1], i8[::1], i8[:, ::1], "
        "f8[:, ::1], f8[::1], b1, b1[::1], i8)"), error_model="numpy")
def crossing_deltas(edge, end_px, gap, ab, own, edges, edge_faces, face_count, faces, V, view, ortho, kept,
                    no_delta):
    """`occlusion.crossing_deltas` (which see) in one pass: view is the projection rays' direction
    (ortho) or the eye; kept (F,) the faces the occluder hides with, (0,) for all. Each float
    operation is the numpy version's, in its order (an einsum of three columns sums
    (x0 y0 + x2 y2) + x1 y1)."""
    K = edge.shape[0]
    delta = np.full(K, no_delta, np.int64)
    for i in range(K):
        e = edge[i]
        if e < 0 or face_count[e] > 2 or not (gap[i] > 1e-6) or not (end_px[i] > 1e-3):
            continue
        a, b = edges[e, 0], edges[e, 1]
        x0, x1, x2 = V[a, 0], V[a, 1], V[a, 2]
        g0, g1, g2 = V[b, 0] - x0, V[b, 1] - x1, V[b, 2] - x2
        if ortho:
            t0, t1, t2 = view[0], view[1], view[2]
        else:
            t0, t1, t2 = view[0] - x0, view[1] - x1, view[2] - x2
        n0 = g1 * t2 - g2 * t1
        n1 = g2 * t0 - g0 * t2
        n2 = g0 * t1 - g1 * t0
        nn = math.sqrt((n0 * n0 + n2 * n2) + n1 * n1)
        a0, a1, a2 = ab[i, 0], ab[i, 1], ab[i, 2]
        move = (n0 * a0 + n2 * a2) + n1 * a1
        if not (abs(move) > 1e-6 * nn * math.sqrt((a0 * a0 + a2 * a2) + a1 * a1)):
            continue
        d = 0
        ok = True
        for col in range(2):
            f = edge_faces[e, col]
            if f < 0:
                continue
            third = faces[f, 0] + faces[f, 1] + faces[f, 2] - a - b
            w0, w1, w2 = V[third, 0] - x0, V[third, 1] - x1, V[third, 2] - x2
            side = (n0 * w0 + n2 * w2) + n1 * w1
            if not (abs(side) > 1e-6 * nn * math.sqrt((w0 * w0 + w2 * w2) + w1 * w1)):
                ok = False
            if f == own[i, 0] or f == own[i, 1] or (kept.shape[0] > 0 and not kept[f]):
                ok = False
            d += 1 if (side > 0) == (move > 0) else -1
        if ok:
            delta[i] = d
    return delta
