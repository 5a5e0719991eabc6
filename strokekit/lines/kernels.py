"""The compiled loops of hidden-line drawings (`strokekit.lines.compiled`, numba), imported on
first use: drawings of visible lines only never import numba. Cached on disk like the raster
kernels (`strokekit.numba_cache`); `warm_kernels` loads them and those of the level rays
(`strokekit.scene.compiled`), or compiles them on a machine's first hidden-line run, before any
frame, and says so when it compiles."""

from __future__ import annotations

from typing import Callable

from strokekit.lines.levels import LEVEL_KERNELS
from strokekit.numba_cache import LazyKernels

#: About how long the first compile of the kernels takes (s) on a free 2-core machine (longer
#: under load).
COMPILE_SECONDS = 15

_KERNELS = LazyKernels("strokekit.lines.compiled", "hidden-line", COMPILE_SECONDS, also=(LEVEL_KERNELS,))


def kernels():
    """The module `strokekit.lines.compiled`, imported (its kernels loaded or compiled) on first use."""
    return _KERNELS.kernels()


def warm_kernels(notify: Callable[[str], None] | None = None) -> tuple[float, bool]:
    """Load the kernels (from numba's disk cache), or compile them (the first hidden-line run on
    a machine) before any frame: (seconds, compiled). `notify(line)` is told once, before the
    wait, when they compile."""
    return _KERNELS.warm(notify)
