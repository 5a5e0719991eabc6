"""The kernels of the brush path stage (numba): the tracker's (`strokekit.tracking.kernels`) and
the stage's own, of its votes, covers and pieces. Loaded on first use: runs that draw no brush
paths never import numba."""

from __future__ import annotations

from strokekit.numba_cache import KernelGroup, LazyKernels
from strokekit.tracking.kernels import TRACKING

BRUSH_PATHS = KernelGroup("brush path", TRACKING.modules + tuple(LazyKernels(m) for m in (
    "strokekit.paths.votes_kernels", "strokekit.paths.cover_kernels", "strokekit.paths.pieces_kernels")),
    compile_seconds=25)
