"""Where numba keeps strokekit's compiled kernels (the raster pass's, hidden lines'), and whether
loading them will compile them. Imports numba only inside its functions: the modules that load
kernels call them on first use, so runs that need none never import numba.

Kernels are compiled once per machine and cached on disk by numba (`cache=True`): numba writes
them to the `__pycache__` next to their module when that folder is writable (an editable or a
root install), else to its user-wide cache (`~/.cache/numba`, `$XDG_CACHE_HOME/numba`), or
`$NUMBA_CACHE_DIR` when set; when none of these is writable, `choose_cache_dir` points numba at
strokekit's own cache folder (`$STROKEKIT_CACHE_DIR/numba`, else `~/.cache/strokekit/numba`,
else a folder in the temporary directory)."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path


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
