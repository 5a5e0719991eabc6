"""The z-buffer's parallel kernels (`strokekit.raster.zbuffer`'s set-up and drawing on numba's
threads), for frames drawn one at a time: the same arrays as the serial kernels, bit for bit,
whatever the thread count (each tile is drawn whole by one thread). A module of its own so that
runs drawing several frames at once, which never use them, neither compile nor load them; the
warm-up of the runs that do compiles them with the others (`WARM_PARALLEL`)."""

from __future__ import annotations

import numpy as np
from numba import prange

from strokekit.numba_cache import kernel
from strokekit.raster.zbuffer import _do_tile, _fill, _setup_range

#: The warm-up compiles these parallel kernels too (numba_cache.declared).
WARM_PARALLEL = True


@kernel("(f8[:, ::1], i4[:, ::1], i8, i8, f8, f8, f8, b1, f8, f8[:, ::1], i1[::1], f8[:, :, ::1], f8[:, ::1])",
        parallel=True, error_model="numpy")
def setup_parallel(vp, faces, W, H, f, cx, cy, ortho, near, fbox, fn, ftri, fplane):
    F = faces.shape[0]
    CH = 4096
    for c in prange((F + CH - 1) // CH):
        _setup_range(c * CH, min(F, (c + 1) * CH), vp, faces, W, H, f, cx, cy, ortho, near, fbox, fn, ftri, fplane)


@kernel(("(f8[:, ::1], i1[::1], f8[:, :, ::1], f8[:, ::1], b1[::1], i8, i8, i8, i8, b1, i4[:, ::1], b1[::1], "
        "i8[::1], f8[:, ::1], i4[::1], i4[::1], f4[::1], f4[:, ::1])"), parallel=True, error_model="numpy")
def draw_parallel(fbox, fn, ftri, fplane, keep, S, WS, HS, T, ortho, slots, active, off, rec, rid, face, depth,
                   bary):
    _fill(fbox, fn, ftri, fplane, keep, S, WS, HS, T, active, off, rec, rid)
    ntx = (WS + T - 1) // T
    nt = active.shape[0]
    TC = 4  # tiles a chunk (one local buffer a chunk); a tile's result does not depend on its thread
    for c in prange((nt + TC - 1) // TC):
        lrec = np.empty(T * T, np.int32)
        lkey = np.empty(T * T, np.float64)
        for t in range(c * TC, min(nt, (c + 1) * TC)):
            if active[t]:
                _do_tile(t, ntx, T, S, WS, HS, ortho, slots, off, rec, rid, lrec, lkey, face, depth, bary)
