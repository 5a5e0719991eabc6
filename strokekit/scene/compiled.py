"""Compiled loops (numba) of the occlusion-level rays (`Occluder.levels`, hidden-line drawings):
the rays built from the points, and the hit lists sorted and filtered, in one pass each instead of
a few dozen numpy passes over a frame's rows. Imports numpy and numba only; loaded on first use
by `occluder.level_kernels()` (numba's import is not paid by visible-only drawings), cached on
disk (`cache=True`, no fastmath): every float operation is numpy's, in numpy's order (numpy 2.4's: an einsum
of three columns sums (x0 x0 + x2 x2) + x1 x1, a row norm (x0 x0 + x1 x1) + x2 x2), so the rays
and the hits kept are bit for bit those of the numpy path.

* `level_rays`: the segments from points on edges toward a perspective eye (Occluder.levels and
  Occluder._segments), as open3d rays in the Embree frame, with what the hit filter needs.
* `listed_hits`: list_intersections' hits within each segment, by ray then along it, less the
  hits on each ray's own faces, with the hits near its start to check in float64.
* `crosses`: that float64 check (Occluder._crosses).
"""

from __future__ import annotations

import math

import numpy as np

from strokekit.numba_cache import kernel


@kernel("(f8[:, ::1], f8[:, ::1], f8[::1], f8[::1], f8[::1], f8, f8, f8)", error_model="numpy")
def level_rays(P, lift, scale, eye, origin, k, offset, eye_tail):
    """For points P (N, 3) on mesh edges, with lifts (N, 3) and local sizes scale (N,): the open
    segment toward the eye (eye (3,), world), started offset x max(|P - origin|, scale) along and
    stopped short of the eye by max(that, eye_tail) (at most a quarter of the way). Returns rays
    (N, 6) float32 (Embree frame: (origin - scene origin) k, direction k), targets (N, 3) world,
    d_local (N, 3) the direction in float64, length (N,) its norm, and reach (N,): 100 lifts plus
    the start offset (the hits to check again in float64)."""
    n = P.shape[0]
    rays = np.empty((n, 6), np.float32)
    targets = np.empty((n, 3))
    d_local = np.empty((n, 3))
    length = np.empty(n)
    reach = np.empty(n)
    for i in range(n):
        c0, c1, c2 = P[i, 0] - origin[0], P[i, 1] - origin[1], P[i, 2] - origin[2]
        eps = offset * max(math.sqrt((c0 * c0 + c2 * c2) + c1 * c1), scale[i])
        d0, d1, d2 = eye[0] - P[i, 0], eye[1] - P[i, 1], eye[2] - P[i, 2]
        dist = math.sqrt((d0 * d0 + d2 * d2) + d1 * d1)
        w = dist if dist > 0 else 1.0
        t0, t1, t2 = d0 / w, d1 / w, d2 / w
        m = min(eps, 0.5 * dist)
        o0, o1, o2 = P[i, 0] + m * t0, P[i, 1] + m * t1, P[i, 2] + m * t2
        tail = min(max(eps, eye_tail), 0.25 * dist)
        g0, g1, g2 = eye[0] - tail * t0, eye[1] - tail * t1, eye[2] - tail * t2
        targets[i, 0], targets[i, 1], targets[i, 2] = g0, g1, g2
        e0, e1, e2 = (g0 - o0) * k, (g1 - o1) * k, (g2 - o2) * k
        d_local[i, 0], d_local[i, 1], d_local[i, 2] = e0, e1, e2
        rays[i, 0] = np.float32((o0 - origin[0]) * k)
        rays[i, 1] = np.float32((o1 - origin[1]) * k)
        rays[i, 2] = np.float32((o2 - origin[2]) * k)
        rays[i, 3], rays[i, 4], rays[i, 5] = np.float32(e0), np.float32(e1), np.float32(e2)
        length[i] = math.sqrt((e0 * e0 + e2 * e2) + e1 * e1)
        l0, l1, l2 = lift[i, 0], lift[i, 1], lift[i, 2]
        reach[i] = 100.0 * math.sqrt((l0 * l0 + l1 * l1) + l2 * l2) + eps
    return rays, targets, d_local, length, reach


@kernel("(f4[::1], u4[::1], u4[::1], i8[::1], f8[::1], f8, i8[:, ::1], f8[::1])", error_model="numpy")
def listed_hits(t, ray, prim, face_index, length, k, skip, reach):
    """The hits of list_intersections (t (K,) float32 along each ray's segment, ray (K,), prim
    (K,) Embree primitives; face_index (F',) their scene faces, (0,): the same numbers) that lie
    within the segment (t <= 1), by ray then t (ties in list order), less those on the ray's own
    faces skip (N, 2): (ok, t (K',) float64, ray, face, close): ok False when the list does not
    come grouped by ray in ray order (then nothing else is set); close where the hit lies within
    reach[ray] (world) of the ray's start, distance t length[ray] / k."""
    K = t.shape[0]
    keep_t = np.empty(K, np.float32)
    keep_r = np.empty(K, np.int64)
    keep_p = np.empty(K, np.int64)
    m = 0
    last = -1
    for h in range(K):
        if not (t[h] <= 1.0):
            continue
        r = np.int64(ray[h])
        if r < last:
            return False, np.empty(0), keep_r[:0], keep_r[:0], np.empty(0, np.bool_)
        last = r
        keep_t[m], keep_r[m], keep_p[m] = t[h], r, np.int64(prim[h])
        m += 1
    # Along each ray (an insertion sort: Embree lists a ray's few hits mostly in order).
    a = 0
    while a < m:
        b = a + 1
        while b < m and keep_r[b] == keep_r[a]:
            b += 1
        for i in range(a + 1, b):
            ti, pi = keep_t[i], keep_p[i]
            j = i
            while j > a and keep_t[j - 1] > ti:
                keep_t[j], keep_p[j] = keep_t[j - 1], keep_p[j - 1]
                j -= 1
            keep_t[j], keep_p[j] = ti, pi
        a = b
    out_t = np.empty(m)
    out_r = np.empty(m, np.int64)
    out_f = np.empty(m, np.int64)
    close = np.empty(m, np.bool_)
    n = 0
    mapped = face_index.shape[0] > 0
    for h in range(m):
        r = keep_r[h]
        f = face_index[keep_p[h]] if mapped else keep_p[h]
        if f == skip[r, 0] or f == skip[r, 1]:
            continue
        th = np.float64(keep_t[h])
        out_t[n], out_r[n], out_f[n] = th, r, f
        close[n] = th * length[r] / k <= reach[r]
        n += 1
    return True, out_t[:n], out_r[:n], out_f[:n], close[:n]


@kernel("(f8[:, ::1], f8[:, ::1], i8[::1], i8[:, ::1], f8[:, ::1])", error_model="numpy")
def crosses(a, b, face, faces, V):
    """Occluder._crosses (which see) of the open segments a -> b (M, 3) and scene faces `face`
    (M,), the numpy version's operations in its order, bit for bit."""
    m = face.shape[0]
    out = np.empty(m, np.bool_)
    for i in range(m):
        f = face[i]
        p, q, r = faces[f, 0], faces[f, 1], faces[f, 2]
        A0, A1, A2 = V[p, 0], V[p, 1], V[p, 2]
        e10, e11, e12 = V[q, 0] - A0, V[q, 1] - A1, V[q, 2] - A2
        e20, e21, e22 = V[r, 0] - A0, V[r, 1] - A1, V[r, 2] - A2
        d0, d1, d2 = b[i, 0] - a[i, 0], b[i, 1] - a[i, 1], b[i, 2] - a[i, 2]
        pv0, pv1, pv2 = d1 * e22 - d2 * e21, d2 * e20 - d0 * e22, d0 * e21 - d1 * e20
        det = (e10 * pv0 + e12 * pv2) + e11 * pv1
        c0, c1, c2 = e11 * e22 - e12 * e21, e12 * e20 - e10 * e22, e10 * e21 - e11 * e20
        scale = math.sqrt((c0 * c0 + c1 * c1) + c2 * c2) * math.sqrt((d0 * d0 + d1 * d1) + d2 * d2)
        inv = 1.0 / det
        t0, t1, t2 = a[i, 0] - A0, a[i, 1] - A1, a[i, 2] - A2
        u = ((t0 * pv0 + t2 * pv2) + t1 * pv1) * inv
        qv0, qv1, qv2 = t1 * e12 - t2 * e11, t2 * e10 - t0 * e12, t0 * e11 - t1 * e10
        v = ((d0 * qv0 + d2 * qv2) + d1 * qv1) * inv
        t = ((e20 * qv0 + e22 * qv2) + e21 * qv1) * inv
        out[i] = abs(det) > 1e-12 * scale and u >= 0 and v >= 0 and u + v <= 1 and t > 0 and t < 1
    return out
