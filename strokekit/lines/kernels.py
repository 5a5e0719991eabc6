"""The compiled loops of hidden-line drawings (`strokekit.lines.compiled`, numba), imported on
first use: drawings of visible lines only never import numba. Cached on disk like the raster
kernels (`strokekit.numba_cache`); `warm_kernels` loads them and those of the level rays
(`strokekit.scene.compiled`), or compiles them on a machine's first hidden-line run, before any
frame, and says so when it compiles."""

from __future__ import annotations

import threading
import time
from pathlib import Path
from typing import Callable

from strokekit.numba_cache import choose_cache_dir, compile_needed
from strokekit.scene.occluder import level_kernels

#: About how long the first compile of the kernels takes (s) on a free 2-core machine (longer
#: under load).
COMPILE_SECONDS = 20

_module = None
_lock = threading.Lock()


def kernels():
    """The module `strokekit.lines.compiled`, imported (its kernels loaded or compiled) on first use."""
    global _module
    if _module is None:
        import importlib

        with _lock:
            if _module is None:
                choose_cache_dir(Path(__file__).resolve().parent)
                _module = importlib.import_module("strokekit.lines.compiled")
    return _module


def warm_kernels(notify: Callable[[str], None] | None = None) -> tuple[float, bool]:
    """Load the kernels (from numba's disk cache), or compile them (the first hidden-line run on
    a machine) before any frame: (seconds, compiled). `notify(line)` is told once, before the
    wait, when they compile."""
    t = time.perf_counter()
    mods = (kernels(), level_kernels())
    compiles = compile_needed(mods)
    if compiles and notify is not None:
        notify(f"compiling the hidden-line kernels (first run on this machine, about {COMPILE_SECONDS} s)")
    for mod in mods:
        mod.warmup()
    return time.perf_counter() - t, bool(compiles)
