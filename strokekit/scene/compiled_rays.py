"""Compiled loop (numba) of a moving scene's rays (`occluder.RayPart`): which rays of a query may
meet one object's box, taken into that object's frame, in one pass instead of a few dozen numpy
passes per object and query. Imports numpy and numba only; loaded on first use by
`occluder.ray_kernels()`."""

from __future__ import annotations

import numpy as np

from strokekit.numba_cache import kernel


@kernel("(f4[:, ::1], f8[::1], f8[::1], f8, f8[:, ::1], f8[::1], b1)", error_model="numpy")
def rays_into(rays, lo, hi, tfar, A, b, cull):
    """The rays (N, 6) float32 (origin o, direction d; the ray o + t d, t in [0, tfar]) that may
    meet the box lo, hi (3,) (the slab test, in float64; every ray when not `cull`), taken into
    a frame by x -> A x + b (A (3, 3), b (3,)): (indices (M,), rays (M, 6) float32)."""
    n = rays.shape[0]
    idx = np.empty(n, np.int64)
    out = np.empty((n, 6), np.float32)
    m = 0
    for i in range(n):
        if cull:
            near, far = 0.0, tfar
            for ax in range(3):
                o, d = np.float64(rays[i, ax]), np.float64(rays[i, 3 + ax])
                if d == 0.0:
                    if o < lo[ax] or o > hi[ax]:
                        near, far = 1.0, 0.0
                    continue
                t1, t2 = (lo[ax] - o) / d, (hi[ax] - o) / d
                if t1 > t2:
                    t1, t2 = t2, t1
                near, far = max(near, t1), min(far, t2)
            if near > far:
                continue
        o0, o1, o2 = np.float64(rays[i, 0]), np.float64(rays[i, 1]), np.float64(rays[i, 2])
        d0, d1, d2 = np.float64(rays[i, 3]), np.float64(rays[i, 4]), np.float64(rays[i, 5])
        for r in range(3):
            out[m, r] = np.float32((A[r, 0] * o0 + A[r, 1] * o1 + A[r, 2] * o2) + b[r])
            out[m, 3 + r] = np.float32(A[r, 0] * d0 + A[r, 1] * d1 + A[r, 2] * d2)
        idx[m] = i
        m += 1
    return idx[:m], out[:m]
