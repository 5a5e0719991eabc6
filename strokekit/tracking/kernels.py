"""The kernels of the tracker, which the brush paths share (numba): the grid searches and the
look-back match, the stroke operations, the labels and runs of the votes, the ids, the u fit and
the walk of the links. Loaded on first use: runs that track nothing never import numba."""

from __future__ import annotations

from strokekit.numba_cache import KernelGroup, LazyKernels

TRACKING = KernelGroup("tracking", tuple(LazyKernels(m) for m in (
    "strokekit.tracking.sort_kernels", "strokekit.tracking.grid_kernels", "strokekit.tracking.strokeops_kernels",
    "strokekit.tracking.votes_kernels", "strokekit.tracking.ufit_kernels", "strokekit.tracking.joins_kernels")),
    compile_seconds=20)
