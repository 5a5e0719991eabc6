"""The kernels of the brush path stage (`strokekit.paths.compiled`, numba), loaded on first use:
runs that draw no brush paths never import numba."""

from __future__ import annotations

from strokekit.numba_cache import KernelGroup, LazyKernels

PATHS = LazyKernels("strokekit.paths.compiled")
BRUSH_PATHS = KernelGroup("brush path", (PATHS,), compile_seconds=50)

#: The module `strokekit.paths.compiled`, its kernels loaded on first use.
kernels = PATHS.kernels
#: Load (or compile) the brush path kernels before any frame: (seconds, compiled).
warm_kernels = BRUSH_PATHS.warm
