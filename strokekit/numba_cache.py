"""Where numba keeps strokekit's compiled kernels (the raster pass's, hidden lines', brush
paths'), whether loading them will compile them, `LazyKernels`, which imports a module of
kernels on first use, and `keyboard_interrupts`, which keeps a Ctrl-C in a compiled loop a
KeyboardInterrupt. Imports numba only inside its functions: the modules that load kernels call
them on first use, so runs that need none never import numba.

Kernels are compiled once per machine and cached on disk by numba (`cache=True`): numba writes
them to the `__pycache__` next to their module when that folder is writable (an editable or a
root install), else to its user-wide cache (`~/.cache/numba`, `$XDG_CACHE_HOME/numba`), or
`$NUMBA_CACHE_DIR` when set; when none of these is writable, `choose_cache_dir` points numba at
strokekit's own cache folder (`$STROKEKIT_CACHE_DIR/numba`, else `~/.cache/strokekit/numba`,
else a folder in the temporary directory)."""

from __future__ import annotations

import importlib
import importlib.util
import os
import tempfile
import threading
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Callable

try:
    import fcntl
except ImportError:  # not POSIX: no lock among processes
    fcntl = None


def _writable(path: Path) -> bool:
    try:
        path.mkdir(parents=True, exist_ok=True)
        tempfile.TemporaryFile(dir=path).close()
        return True
    except OSError:
        return False


def _cache_folder() -> Path:
    """strokekit's own folder for numba's cache when numba has no writable one."""
    if os.environ.get("STROKEKIT_CACHE_DIR"):
        return Path(os.environ["STROKEKIT_CACHE_DIR"]) / "numba"
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "strokekit" / "numba"


def choose_cache_dir(package: Path) -> str | None:
    """Make sure numba can write the cache of the kernels in folder `package` (else a
    `cache=True` kernel refuses to compile, and the compile would be paid on every run): numba's
    own choice when one of its folders is writable (None returned), else strokekit's cache folder
    or a temporary one, set as numba's CACHE_DIR (returned). Call before the kernels' module is
    imported."""
    import numba
    from numba.misc.appdirs import AppDirs

    if numba.config.CACHE_DIR:  # $NUMBA_CACHE_DIR
        return None
    if _writable(Path(package) / "__pycache__"):
        return None
    if _writable(Path(AppDirs(appname="numba", appauthor=False).user_cache_dir)):
        return None
    for folder in (_cache_folder(), Path(tempfile.gettempdir()) / f"strokekit-numba-{os.getuid()}"):
        if _writable(folder):
            numba.config.CACHE_DIR = str(folder)
            return str(folder)
    return None  # nowhere to write: numba will say so when it compiles


def compile_needed(modules) -> bool | None:
    """Whether warming the serial kernels of `modules` up will compile them: False when every one
    is already in this process or has a fresh entry in numba's on-disk cache (the warm-up only
    loads them), True when one has neither, None when numba does not tell (its cache internals
    changed). Parallel kernels (`parallel=True`) are not counted: they are not warmed up."""
    try:
        disps = [v for m in modules for v in vars(m).values()
                 if hasattr(v, "py_func") and getattr(v, "_cache", None) is not None
                 and not v.targetoptions.get("parallel")]
        if not disps:
            return None
        if all(d.signatures for d in disps):
            return False
        return not all(d.signatures or d._cache._cache_file._load_index() for d in disps)
    except Exception:  # private numba API: any change means "cannot tell"
        return None


@contextmanager
def keyboard_interrupts():
    """Ctrl-C raised as KeyboardInterrupt in the block: one that lands while a compiled loop hands
    its arrays back to Python surfaces as a SystemError ("... returned a result with an
    exception set") with the KeyboardInterrupt as its cause (or further down its chain)."""
    try:
        yield
    except SystemError as e:
        c, seen = e, set()
        while c is not None and not isinstance(c, KeyboardInterrupt) and id(c) not in seen:
            seen.add(id(c))  # (a chain may loop back on itself)
            c = c.__cause__ or c.__context__
        if c is not None and not isinstance(c, KeyboardInterrupt):
            c = None
        if c is not None:
            raise c from None
        raise


@contextmanager
def machine_lock(name: str):
    """An exclusive lock among this machine's processes, by `name` (a file lock in the temporary
    folder; none where fcntl is missing or the file cannot be opened)."""
    if fcntl is None:
        yield
        return
    path = Path(tempfile.gettempdir()) / f"strokekit-{name}-{os.getuid()}.lock"
    try:
        fh = open(path, "a")
    except OSError:
        yield
        return
    with fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


class LazyKernels:
    """A module of numba kernels (`module`, by name), imported on first use (`kernels()`) after
    `choose_cache_dir`, so runs that never call it never import numba. For `warm`: `label` names
    the kernels in the compile notice, `compile_seconds` is about how long their first compile
    takes (s), `also` are other LazyKernels warmed up (and counted) with these."""

    def __init__(self, module: str, label: str = "", compile_seconds: float = 0,
                 also: tuple["LazyKernels", ...] = ()):
        self.module, self.label, self.compile_seconds, self.also = module, label, compile_seconds, also
        self._module = self._raw = None
        self._lock = threading.RLock()

    def _imported(self):
        """The module, imported (after `choose_cache_dir`), its kernels not yet loaded."""
        if self._raw is None:
            with self._lock:
                if self._raw is None:
                    choose_cache_dir(Path(importlib.util.find_spec(self.module).origin).resolve().parent)
                    self._raw = importlib.import_module(self.module)
        return self._raw

    def kernels(self):
        """The module, imported on first use. When its kernels are not in numba's disk cache, they
        are compiled then, by one process of the machine at a time: a dask cluster's workers or
        concurrent runs on one machine wait for the first, then load what it cached."""
        if self._module is None:
            mod = self._imported()
            with self._lock:  # (two threads asking at once compile once)
                if self._module is None:
                    if compile_needed([mod]) is not False:
                        with machine_lock(self.module):
                            if compile_needed([mod]) is not False:
                                with keyboard_interrupts():
                                    mod.warmup()
                    self._module = mod
        return self._module

    def warm(self, notify: Callable[[str], None] | None = None) -> tuple[float, bool]:
        """Load the kernels (and those of `also`), or compile them (the first such run on a
        machine), before any frame: (seconds, compiled). `notify(line)` is told once, before the
        wait, when they compile."""
        t = time.perf_counter()
        lazy = (self, *self.also)
        compiles = compile_needed([k._imported() for k in lazy])
        if compiles and notify is not None:
            notify(f"compiling the {self.label} kernels (first run on this machine, about {self.compile_seconds} s)")
        mods = [k.kernels() for k in lazy]
        with keyboard_interrupts():
            for mod in mods:
                mod.warmup()
        return time.perf_counter() - t, bool(compiles)
