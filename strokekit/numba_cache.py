"""strokekit's numba kernels: declared once, compiled once per machine, loaded on first use.

A kernel module (numba and numpy only) declares each kernel that Python calls with `kernel`,
giving the argument types it is called with; helpers that only kernels call are plain
`numba.njit(cache=True)` functions (compiled, and cached, with their callers). The warm-up
compiles, or loads from numba's disk cache, exactly the declared signatures: nothing to keep
in step by hand, and a test runs the pipelines with compiling turned off after the warm-up.

`LazyKernels(module)` imports a kernel module on first use (`kernels()`), so runs that need no
kernel never import numba. `KernelGroup` is what one stage needs (its modules, the label of its
compile notice); `Warmup` warms groups in a background thread, before a run's frames. A compile
is done by one process of the machine at a time (a file lock): the others, a dask cluster's
workers or concurrent runs, then load what it cached. A Ctrl-C in a compiled loop stays a
KeyboardInterrupt (`keyboard_interrupts`).

numba's cache of a kernel is keyed by the kernel's own source file: a kernel that calls a
kernel of another module is compiled again when that module's source changes (a stamp of the
modules it calls is kept beside its cache).

Where the cache lives: numba writes it to the `__pycache__` next to the module when that folder
is writable (an editable or a root install), else to its user-wide cache (`~/.cache/numba`,
`$XDG_CACHE_HOME/numba`), or `$NUMBA_CACHE_DIR` when set; when none of these is writable,
`choose_cache_dir` points numba at strokekit's own folder (`$STROKEKIT_CACHE_DIR/numba`, else
`~/.cache/strokekit/numba`, else a folder in the temporary directory)."""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import os
import subprocess
import sys
import tempfile
import threading
import time
import warnings
from contextlib import contextmanager
from pathlib import Path
from typing import Callable

try:
    import fcntl
except ImportError:  # not POSIX: no lock among processes
    fcntl = None


# --- declaring kernels ---------------------------------------------------------------------------

#: njit options of every kernel: `nogil` lets a run's other threads go on while a kernel runs
#: (kernels touch no Python object). Part of each kernel module's cache stamp: numba's own cache
#: key does not hold them.
KERNEL_OPTIONS = {"cache": True, "nogil": True}


def kernel(*signatures: str, **options):
    """A numba kernel called from Python (njit with KERNEL_OPTIONS, no fastmath: the same results
    on every run and in every process), compiled for each of `signatures`: numba type strings of
    its arguments, e.g. "(f8[:, ::1], i8[::1], f8)". `options`: more njit options
    (parallel=True kernels are compiled on their first use, not by the warm-up)."""
    def declare(f):
        import numba

        d = numba.njit(**KERNEL_OPTIONS, **options)(f)
        d.declared_signatures = tuple(signatures)
        return d

    return declare


def _dispatchers(mod):
    """The numba functions defined in module `mod` (not those it imports)."""
    return [v for v in vars(mod).values() if hasattr(v, "py_func") and v.py_func.__module__ == mod.__name__]


def declared(mod, parallel: bool = False):
    """(dispatcher, argument types) of every declared signature of module `mod`'s kernels that
    the warm-up compiles: its serial kernels, or with `parallel` its parallel ones (warmed only
    for the runs that use them: a group of its own)."""
    from numba.core import sigutils

    out = []
    for d in _dispatchers(mod):
        if bool(d.targetoptions.get("parallel")) != parallel:
            continue
        for s in getattr(d, "declared_signatures", ()):
            out.append((d, sigutils.normalize_signature(s)[0]))
    return out


def _callees(mod) -> list[str]:
    """The modules (by name, transitively) whose kernels the kernels of `mod` may call: those of
    the numba functions it imports."""
    seen: list[str] = []
    todo = [mod]
    while todo:
        m = todo.pop()
        for v in vars(m).values():
            name = getattr(getattr(v, "py_func", None), "__module__", None)
            if name and name != mod.__name__ and name not in seen and name in sys.modules:
                seen.append(name)
                todo.append(sys.modules[name])
    return sorted(seen)


def _callee_stamp(mod) -> str | None:
    """A digest of KERNEL_OPTIONS and of the source of the modules whose kernels `mod`'s kernels
    call (None: `mod` has no kernel)."""
    if not _dispatchers(mod):
        return None
    h = hashlib.sha256(repr(sorted(KERNEL_OPTIONS.items())).encode() + b"\0")
    for name in _callees(mod):
        h.update(name.encode() + b"\0" + Path(sys.modules[name].__file__).read_bytes() + b"\0")
    return h.hexdigest()


def _stamp_file(mod) -> Path | None:
    ds = _dispatchers(mod)
    if not ds or getattr(ds[0], "_cache", None) is None:
        return None
    return Path(ds[0]._cache.cache_path) / (Path(mod.__file__).stem + ".callees")


def _drop_stale(mod) -> bool:
    """Empty the cache of `mod`'s kernels when a module they call or KERNEL_OPTIONS changed since
    they were cached (numba would load them as they were). Returns whether it did."""
    stamp = _callee_stamp(mod)
    path = _stamp_file(mod)
    if stamp is None or path is None:
        return False
    try:
        if path.read_text() == stamp:
            return False
    except OSError:
        pass
    for d in _dispatchers(mod):
        d._cache.flush()
    return True


def _keep_stamp(mod) -> None:
    stamp, path = _callee_stamp(mod), _stamp_file(mod)
    if stamp is not None and path is not None:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            tmp = path.with_suffix(f".tmp{os.getpid()}")
            tmp.write_text(stamp)
            os.replace(tmp, path)
        except OSError:  # (an unwritable cache: numba says so when it compiles)
            pass


def compile_needed(mod, parallel: bool = False) -> bool | None:
    """Whether compiling `mod`'s declared signatures (`parallel`: its parallel kernels') will
    compile any (False: each is in this process or has a fresh entry in numba's disk cache, and
    they only load), or None when numba does not tell (its cache internals changed)."""
    try:
        if _drop_stale(mod):
            return True
        for d, sig in declared(mod, parallel):
            if sig in d.overloads:
                continue
            key = d._cache._index_key(sig, d.targetctx.codegen())
            if key not in d._cache._cache_file._load_index():
                return True
        return False
    except Exception:  # private numba API: any change means "cannot tell"
        return None


def _compile_declared(mod, parallel: bool = False) -> None:
    with keyboard_interrupts():
        for d, sig in declared(mod, parallel):
            d.compile(sig)
    _keep_stamp(mod)


# --- where the cache lives -----------------------------------------------------------------------

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


# --- interrupts and locks ------------------------------------------------------------------------

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
def machine_lock(name: str, wait: bool = True):
    """An exclusive lock among this machine's processes, by `name` (a file lock in the temporary
    folder; none where fcntl is missing or the file cannot be opened). Yields whether it is held:
    with `wait` False, False at once when another holds it."""
    if fcntl is None:
        yield True
        return
    path = Path(tempfile.gettempdir()) / f"strokekit-{name}-{os.getuid()}.lock"
    try:
        fh = open(path, "a")
    except OSError:
        yield True
        return
    with fh:
        try:
            fcntl.flock(fh, fcntl.LOCK_EX if wait else fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            yield False
            return
        try:
            yield True
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


# --- compiling on several cores ------------------------------------------------------------------

#: A module's parallel kernels, as `claim_and_compile` names them: "module" + PARALLEL.
PARALLEL = "+parallel"


def claim_and_compile(modules: list[str], parent: int | None = None) -> None:
    """Compile the declared kernels of each of `modules` (names, in order; "name+parallel": its
    parallel kernels) that needs it and that no other process of the machine is compiling (its
    machine lock is free); skip the others. `parent`: the pid of the process that asked; once it
    is gone (Ctrl-C), stop."""
    for spec in modules:
        if parent is not None and os.getppid() != parent:
            return
        name = spec.removesuffix(PARALLEL)
        parallel = name != spec
        mod = LazyKernels(name).imported()
        if compile_needed(mod, parallel) is False:
            continue
        with machine_lock(name, wait=False) as mine:
            if mine and compile_needed(mod, parallel) is not False:
                _compile_declared(mod, parallel)


def compile_side_by_side(modules: list[str], processes: int) -> None:
    """Compile the kernels of `modules` into numba's disk cache on `processes` cores at once:
    processes - 1 child interpreters and this thread each take the next module nobody has taken
    (`claim_and_compile`), so the modules spread over the cores (numba compiles one kernel at a
    time in a process). The callers then load them from the cache."""
    code = ("import sys; from strokekit.numba_cache import claim_and_compile; "
            "claim_and_compile(sys.argv[2:], int(sys.argv[1]))")
    # (run where this strokekit is imported from, not a checkout the current folder may hold)
    home = Path(__file__).resolve().parents[1]
    kids = [subprocess.Popen([sys.executable, "-c", code, str(os.getpid()), *modules], cwd=home, stdin=subprocess.DEVNULL,
                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            for _ in range(processes - 1)]
    try:
        claim_and_compile(modules)
    except BaseException:
        for k in kids:
            k.kill()
        raise
    finally:
        for k in kids:
            k.wait()


# --- loading -------------------------------------------------------------------------------------

class LazyKernels:
    """A kernel module (`module`, by name), imported on first use (`kernels()`) after
    `choose_cache_dir`. One object per module name: the kernels of a module load once per
    process whoever asks."""

    _made: dict[str, "LazyKernels"] = {}
    _made_lock = threading.Lock()

    def __new__(cls, module: str):
        with cls._made_lock:
            made = cls._made.get(module)
            if made is None:
                made = cls._made[module] = super().__new__(cls)
                made.module, made._module, made._raw = module, None, None
                made._lock = threading.RLock()
        return made

    def imported(self):
        """The module, imported (after `choose_cache_dir`), its kernels not yet loaded."""
        if self._raw is None:
            with self._lock:
                if self._raw is None:
                    choose_cache_dir(Path(importlib.util.find_spec(self.module).origin).resolve().parent)
                    self._raw = importlib.import_module(self.module)
        return self._raw

    def kernels(self):
        """The module, its kernels compiled on first use where numba's disk cache lacks them (by
        one process of the machine at a time), else loaded from it as they are called."""
        if self._module is None:
            self.load(every=False)
        return self._module

    def load(self, every: bool = True, parallel: bool = False):
        """Compile, or load from the cache, the module's declared kernels (`every`: load those
        that are cached too, before they are called; `parallel`: its parallel kernels instead of
        its serial ones). Returns the module."""
        mod = self.imported()
        with self._lock, warnings.catch_warnings():  # (two threads asking at once compile once)
            # (numba says, on its threads' first start, that open3d's older TBB is not used:
            # it takes OpenMP instead, nothing for the user to do)
            warnings.filterwarnings("ignore", message=".*TBB threading layer.*")
            if compile_needed(mod, parallel) is not False:
                with machine_lock(self.module):
                    if compile_needed(mod, parallel) is not False:
                        _compile_declared(mod, parallel)
            elif every:
                _compile_declared(mod, parallel)
            if not parallel:
                self._module = mod
        return mod


class KernelGroup:
    """The kernel modules one stage needs, warmed up together before a run's frames. `label`
    names them in the compile notice, `compile_seconds` is about how long their first compile
    takes (s, on a 2-core machine)."""

    def __init__(self, label: str, modules: tuple[LazyKernels, ...], compile_seconds: float, parallel: bool = False):
        self.label, self.modules, self.compile_seconds = label, tuple(modules), compile_seconds
        self.parallel = parallel  # the modules' parallel kernels, not their serial ones
        self._ready = False
        self._warming: Warmup | None = None

    def compile_needed(self) -> bool | None:
        """Whether warming the group up compiles (True), only loads (False), or cannot tell (None)."""
        said = [compile_needed(m.imported(), self.parallel) for m in self.modules]
        return True if True in said else (None if None in said else False)

    def warm(self, notify: Callable[[str], None] | None = None, compiles=None) -> tuple[float, bool]:
        """Compile (the first run on a machine) or load the group's kernels: (seconds,
        compiled). `notify(line)` is told once, before the wait, when they compile (where numba
        does not tell beforehand: when the warm-up takes over 2 s). `compiles`: what
        compile_needed said, when the caller asked already."""
        t = time.perf_counter()
        if compiles is None:
            compiles = self.compile_needed()
        timer = self.say_compile(notify, compiles)
        try:
            for m in self.modules:
                m.load(parallel=self.parallel)
        finally:
            if timer is not None:
                timer.cancel()
        self._ready = True
        return time.perf_counter() - t, bool(compiles)

    def say_compile(self, notify: Callable[[str], None] | None, compiles: bool | None):
        """Tell `notify` that the group compiles (where compile_needed said so; where it could
        not tell, after 2 s: the timer returned, to cancel once the kernels are there)."""
        msg = f"compiling the {self.label} kernels (first run on this machine, about {self.compile_seconds:g} s)"
        if notify is not None:
            if compiles:
                notify(msg)
            elif compiles is None:
                timer = threading.Timer(2.0, notify, (msg,))
                timer.daemon = True
                timer.start()
                return timer
        return None

    def ensure(self) -> float:
        """Make sure this process has the kernels (before a frame's clock starts): wait for the
        warm-up thread loading them, else load them. Returns the seconds this call loaded them
        for (0 when a warm-up thread did, or they were there)."""
        if self._ready:
            return 0.0
        w = self._warming
        if w is not None:
            w.join()
            if w.error is None:
                return 0.0
        return self.warm()[0]


class Warmup:
    """`KernelGroup.warm` of `groups` in a background thread, started as early as possible:
    loading kernels from the cache (numba's import and set-up: about a second a process) overlaps
    the process's other work. `compiles()` says, once known, whether any group compiles (a
    machine's first run: the caller then waits for `join()` before any worker starts a frame, so
    that the workers load the kernels from the cache instead of each compiling them)."""

    def __init__(self, groups, notify: Callable[[str], None] | None = None):
        self.groups = tuple(groups)
        self._notify = notify
        self._decided = threading.Event()
        self._compiles: bool | None = False
        self.seconds: dict[str, float] = {}
        self.error: BaseException | None = None
        for g in self.groups:
            g._warming = self
        self._thread = threading.Thread(target=self._run, name="strokekit-kernels", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        try:
            said = [g.compile_needed() for g in self.groups]
            self._compiles = True if True in said else (None if None in said else False)
            self._decided.set()
            todo = [m.module + (PARALLEL if g.parallel else "") for g, c in zip(self.groups, said) if c is not False
                    for m in g.modules]
            cores = os.cpu_count() or 1
            if len(todo) > 1 and cores > 1:
                # Several modules to compile: side by side on the cores, then loaded as cached.
                # Each group's share of the wait is counted by its compile estimate.
                t = time.perf_counter()
                timers = [g.say_compile(self._notify, c) for g, c in zip(self.groups, said)]
                try:
                    compile_side_by_side(todo, min(cores, len(todo)))
                finally:
                    for timer in timers:
                        if timer is not None:
                            timer.cancel()
                wait = time.perf_counter() - t
                weight = {g.label: g.compile_seconds for g, c in zip(self.groups, said) if c is not False}
                for label, w in weight.items():
                    self.seconds[label] = wait * w / sum(weight.values())
                said = [False] * len(said)
            for g, c in zip(self.groups, said):
                self.seconds[g.label] = self.seconds.get(g.label, 0.0) + g.warm(self._notify, compiles=c)[0]
        except BaseException as e:  # said by the frames that need the kernels
            self.error = e
        finally:
            self._decided.set()

    def compiles(self) -> bool | None:
        self._decided.wait()
        return self._compiles

    def join(self) -> dict[str, float]:
        """Wait for the warm-up: the seconds it took per group (by label)."""
        self._thread.join()
        return self.seconds
