"""The compiled loops of the brush path stage (`strokekit.paths.compiled`, numba), imported on
first use: runs that draw no brush paths never import numba. Cached on disk like the raster
kernels (`strokekit.numba_cache`); `warm_kernels` loads them, or compiles them on a machine's
first brush path run, before any frame, and says so when it compiles."""

from __future__ import annotations

import threading
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Callable

from strokekit.numba_cache import choose_cache_dir, compile_needed

#: About how long the first compile of the kernels takes (s), on this project's 2-core machine
#: (with another job running).
COMPILE_SECONDS = 25

_module = None
_lock = threading.Lock()


def kernels():
    """The module `strokekit.paths.compiled`, imported (its kernels loaded or compiled) on first use."""
    global _module
    if _module is None:
        import importlib

        with _lock:
            if _module is None:
                choose_cache_dir(Path(__file__).resolve().parent)
                _module = importlib.import_module("strokekit.paths.compiled")
    return _module


@contextmanager
def keyboard_interrupts():
    """Ctrl-C raised as KeyboardInterrupt in the block: one that lands while a compiled loop hands
    its arrays back to Python surfaces as a SystemError ("... returned a result with an
    exception set") with the KeyboardInterrupt as its cause (or further down its chain)."""
    try:
        yield
    except SystemError as e:
        c = e
        while c is not None and not isinstance(c, KeyboardInterrupt):
            c = c.__cause__ or c.__context__
        if c is not None:
            raise c from None
        raise


def warm_kernels(notify: Callable[[str], None] | None = None) -> tuple[float, bool]:
    """Load the kernels (from numba's disk cache), or compile them (the first brush path run on a
    machine) before any frame: (seconds, compiled). `notify(line)` is told once, before the
    wait, when they compile."""
    t = time.perf_counter()
    mod = kernels()
    compiles = compile_needed([mod])
    if compiles and notify is not None:
        notify(f"compiling the brush path kernels (first run on this machine, about {COMPILE_SECONDS} s)")
    with keyboard_interrupts():
        mod.warmup()
    return time.perf_counter() - t, bool(compiles)
