"""The compiled loops of the brush path stage (`strokekit.paths.compiled`, numba), imported on
first use: runs that draw no brush paths never import numba. Cached on disk like the raster
kernels (`strokekit.numba_cache`); `warm_kernels` loads them, or compiles them on a machine's
first brush path run, before any frame, and says so when it compiles."""

from __future__ import annotations

from typing import Callable

from strokekit.numba_cache import LazyKernels

#: About how long the first compile of the kernels takes (s) on a free 2-core machine (longer
#: under load).
COMPILE_SECONDS = 50

_KERNELS = LazyKernels("strokekit.paths.compiled", "brush path", COMPILE_SECONDS)


def kernels():
    """The module `strokekit.paths.compiled`, imported (its kernels loaded or compiled) on first use."""
    return _KERNELS.kernels()


def warm_kernels(notify: Callable[[str], None] | None = None) -> tuple[float, bool]:
    """Load the kernels (from numba's disk cache), or compile them (the first brush path run on a
    machine) before any frame: (seconds, compiled). `notify(line)` is told once, before the
    wait, when they compile."""
    return _KERNELS.warm(notify)
