"""The kernels of hidden-line drawings (numba): the lines' pair searches
(`strokekit.lines.compiled`) and the occlusion-level rays (`strokekit.scene.compiled`), loaded
on first use: drawings of visible lines only never import numba."""

from __future__ import annotations

from strokekit.lines.levels import LEVEL_KERNELS
from strokekit.numba_cache import KernelGroup, LazyKernels

LINES = LazyKernels("strokekit.lines.compiled")
HIDDEN_LINES = KernelGroup("hidden-line", (LINES, LEVEL_KERNELS), compile_seconds=12)

#: The module `strokekit.lines.compiled`, its kernels loaded on first use.
kernels = LINES.kernels
#: Load (or compile) the hidden-line kernels before any frame: (seconds, compiled).
warm_kernels = HIDDEN_LINES.warm
