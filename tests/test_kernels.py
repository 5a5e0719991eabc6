"""strokekit's numba kernels (strokekit.numba_cache): declared with the types they are called
with, warmed up from those declarations, compiled once per machine under a lock, recompiled when
a module they call changes, and said once when they compile."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
import threading
from pathlib import Path

import pytest

from strokekit import numba_cache
from strokekit.lines.kernels import HIDDEN_LINES
from strokekit.paths.kernels import BRUSH_PATHS
from strokekit.raster.hits import RASTER, RASTER_THREADS
from strokekit.run.kernels import LINE_STYLE
from strokekit.tracking.kernels import TRACKING
from strokekit.writers.exr import EXR_KERNELS

ROOT = Path(__file__).resolve().parents[1]
GROUPS = (RASTER, RASTER_THREADS, HIDDEN_LINES, BRUSH_PATHS, TRACKING, LINE_STYLE, EXR_KERNELS)
#: A style with every thickness modifier (the sample style file), its creases dashed (outlines
#: cut into dashes).
FIVE = """\
[[lineset]]
name = "creases"
kinds = ["crease"]
dashes = [6, 3]
thickness = [{ by = "along", head = 4, tail = 4 }, { by = "noise", amplitude = 0.2, wavelength = 12 }]
""" + (ROOT / "samples" / "five.toml").read_text()


@pytest.mark.parametrize("group", GROUPS, ids=lambda g: g.label)
def test_the_first_compile_is_said_once_before_the_wait(monkeypatch, group):
    """A warm-up whose kernels are not in numba's cache says so in one line before it compiles;
    one whose kernels are cached (or already loaded in the process) says nothing."""
    said = []
    monkeypatch.setattr(group, "compile_needed", lambda: True)
    _, compiled = group.warm(said.append)
    assert compiled and said == [f"compiling the {group.label} kernels (first run on this machine, about "
                                 f"{group.compile_seconds:g} s)"]
    monkeypatch.setattr(group, "compile_needed", lambda: False)
    said.clear()
    assert group.warm(said.append)[1] is False and said == []
    monkeypatch.undo()
    assert group.compile_needed() is False  # loaded in this process by now


def test_numba_gets_a_writable_cache_folder(monkeypatch, tmp_path):
    """When neither numba's in-tree __pycache__ nor its user-wide folder is writable, strokekit
    points numba at its own cache folder (else a cache=True kernel refuses to compile)."""
    import numba

    raster = ROOT / "strokekit" / "raster"
    monkeypatch.setattr(numba.config, "CACHE_DIR", "")
    monkeypatch.setenv("STROKEKIT_CACHE_DIR", str(tmp_path / "sk"))
    real = numba_cache._writable
    monkeypatch.setattr(numba_cache, "_writable", lambda p: str(p).startswith(str(tmp_path)) and real(p))
    assert numba_cache.choose_cache_dir(raster) == str(tmp_path / "sk" / "numba")
    assert numba.config.CACHE_DIR == str(tmp_path / "sk" / "numba")
    monkeypatch.setattr(numba_cache, "_writable", real)
    monkeypatch.setattr(numba.config, "CACHE_DIR", "")
    assert numba_cache.choose_cache_dir(raster) is None  # the in-tree folder is writable here


def _kernel_modules():
    return sorted({m for g in GROUPS for m in g.modules}, key=lambda m: m.module)


@pytest.mark.parametrize("lazy", _kernel_modules(), ids=lambda m: m.module)
def test_every_kernel_python_calls_says_how_it_is_called(lazy):
    """The warm-up compiles what the kernels declare: every kernel a module exports (its public
    numba functions, those other modules call) declares its signatures, each one numba parses;
    private helpers are compiled with their callers."""
    from numba.core import sigutils

    mod = lazy.imported()
    for d in numba_cache._dispatchers(mod):
        sigs = getattr(d, "declared_signatures", ())
        name = d.py_func.__name__
        if not name.startswith("_"):
            assert sigs, f"{mod.__name__}.{name} declares no signature"
        for s in sigs:
            args, ret = sigutils.normalize_signature(s)
            assert ret is None and len(args) == d.py_func.__code__.co_argcount, (name, s)


def test_the_warm_up_compiles_every_signature_the_pipelines_call(tmp_path):
    """After the warm-up, drawing frames compiles nothing more: brush paths, tracked lines,
    hidden lines, the raster pass (its z-buffer on threads: the runs draw one frame at a time), a moving scene's rays and a style's widths and outlines (its
    five modifiers, dashed outlines too) call their kernels with the declared
    types only (a kernel
    called with another type would compile during a run's first frame, after the run said
    nothing of a compile). Checked in a fresh interpreter (this one's other tests call the
    kernels themselves)."""
    code = textwrap.dedent(f"""
        from strokekit import numba_cache
        from strokekit.lines.kernels import HIDDEN_LINES
        from strokekit.paths.kernels import BRUSH_PATHS
        from strokekit.raster.hits import RASTER, RASTER_THREADS
        from strokekit.scene.occluder import MOVING_SCENE
        from strokekit.run.kernels import LINE_STYLE
        from strokekit.tracking.kernels import TRACKING
        from strokekit.writers.exr import EXR_KERNELS
        from strokekit_cli.main import cli
        import sys
        sys.path.insert(0, {str(ROOT / 'tests')!r})
        from animated import sphere_and_box_glb
        from pathlib import Path
        groups = (RASTER, RASTER_THREADS, HIDDEN_LINES, BRUSH_PATHS, TRACKING, MOVING_SCENE, LINE_STYLE, EXR_KERNELS)
        for g in groups:
            g.warm()
        warm = {{}}
        for g in groups:
            for m in g.modules:
                for d in numba_cache._dispatchers(m.kernels()):
                    warm[d] = set(d.signatures)
        FIVE = {FIVE!r}
        S, M, out = {str(ROOT / 'samples')!r}, {str(ROOT.parent / 'shared' / 'models')!r}, {str(tmp_path)!r}
        runs = [["render", S + "/still_life.glb", "--camera", S + "/orbit.json", "--frames", "1-3", "--gltf",
                 "--bands", "3", "--exr", "--exr-codec", "rle", "--masks", "--objectid", "--depth", "--fill",
                 "--size", "160x120"],
                ["render", M + "/fandisk.obj", "--orbit", "3", "--hidden", "--size", "240x200"],
                ["render", M + "/spot.obj", "--orbit", "3", "--strokes", "lines", "--size", "240x200"],
                ["render", str(sphere_and_box_glb(Path(out) / "sphere.glb", "sphere")), "--orbit", "3",
                 "--strokes", "lines", "--size", "240x200"],
                ["render", M + "/spot.obj", "--orbit", "3", "--style", out + "/five.toml", "--size", "240x200"]]
        Path(out, "five.toml").write_text(FIVE)
        for k, r in enumerate(runs):
            try:
                cli.main(args=r + ["--workers", "1", "-q", "--out", out + "/r%d" % k], standalone_mode=False)
            except SystemExit as e:
                assert not e.code, r
        for d, had in warm.items():
            new = set(d.signatures) - had
            if new and (getattr(d, "declared_signatures", ()) or not d.py_func.__name__.startswith("_")):
                print(d.py_func.__module__, d.py_func.__name__, [str(s) for s in new])
    """)
    if not (ROOT.parent / "shared" / "models" / "fandisk.obj").exists():
        pytest.skip("shared models not found")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT)
    assert out.returncode == 0, out.stderr[-3000:]
    assert out.stdout == "", out.stdout


#: A kernel module of one tiny kernel, for the tests of compiling and caching.
TINY_TOTAL = """
        from strokekit.numba_cache import kernel

        @kernel("(f8[::1],)")
        def total(a):
            s = 0.0
            for x in a:
                s += x
            return s
        """


def _tiny_module(folder: Path, name: str, body: str) -> None:
    (folder / f"{name}.py").write_text(textwrap.dedent(body))


def test_kernels_compile_under_a_machine_lock_and_only_when_needed(monkeypatch, tmp_path):
    """First use of a kernel module whose kernels are not cached compiles them while holding
    the machine-wide lock of that module, so a dask cluster's workers on one machine compile
    once; when they are cached, first use neither compiles nor waits for the lock."""
    name = "sk_tiny_kernels"
    _tiny_module(tmp_path, name, TINY_TOTAL)
    monkeypatch.syspath_prepend(str(tmp_path))
    held, release, got = threading.Event(), threading.Event(), []

    def holder():
        with numba_cache.machine_lock(name):
            held.set()
            release.wait(30)

    t = threading.Thread(target=holder)
    t.start()
    held.wait(10)
    user = threading.Thread(target=lambda: got.append(numba_cache.LazyKernels(name).kernels()))
    user.start()
    user.join(0.5)
    assert user.is_alive() and not got  # waiting for the lock, not compiling beside its holder
    release.set()
    t.join()
    user.join(60)
    assert got and len(got[0].total.signatures) == 1 and got[0].total.stats.cache_misses
    # Cached now: a fresh import of the module neither compiles nor takes the lock.
    sys.modules.pop(name)
    numba_cache.LazyKernels._made.pop(name)
    with numba_cache.machine_lock(name):
        again = threading.Thread(target=lambda: got.append(numba_cache.LazyKernels(name).kernels()))
        again.start()
        again.join(30)
        assert not again.is_alive() and not got[1].total.signatures  # (loaded from the cache when called)
    assert numba_cache.compile_needed(got[1]) is False
    sys.modules.pop(name)
    numba_cache.LazyKernels._made.pop(name)


def test_a_kernel_is_compiled_again_when_a_kernel_it_calls_changes(tmp_path):
    """numba keys a kernel's cache by its own file: one that calls a kernel of another module is
    compiled again when that module changes (else it would run the old callee, cached in it)."""
    _tiny_module(tmp_path, "sk_callee", """
        from numba import njit

        @njit(cache=True)
        def step(x):
            return x + 1.0
        """)
    _tiny_module(tmp_path, "sk_caller", """
        from strokekit.numba_cache import kernel
        from sk_callee import step

        @kernel("(f8,)")
        def twice(x):
            return step(step(x))
        """)
    code = ("from strokekit.numba_cache import LazyKernels\n"
            "K = LazyKernels('sk_caller').kernels()\n"
            "print(K.twice(1.0))\n")
    env = {**os.environ, "PYTHONPATH": f"{tmp_path}:{ROOT}"}
    env.pop("NUMBA_CACHE_DIR", None)

    def run():
        return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path, env=env,
                              check=True).stdout.strip()

    assert run() == "3.0"
    assert run() == "3.0"  # (from the cache)
    (tmp_path / "sk_callee.py").write_text((tmp_path / "sk_callee.py").read_text().replace("x + 1.0", "x + 2.0"))
    assert run() == "5.0"


def test_a_ctrl_c_in_the_trackers_compiled_loops_stays_a_keyboard_interrupt():
    """A KeyboardInterrupt that lands as one of the tracker's compiled loops hands back its arrays
    (a SystemError caused by it) comes out of Tracker.step as the KeyboardInterrupt."""
    from types import SimpleNamespace

    import numpy as np

    from strokekit.camera.view import Camera
    from strokekit.model import Strokes
    from strokekit.tracking.tracker import Tracker

    cam = Camera(eye=(0.0, 0.0, 10.0), target=(0.0, 0.0, 0.0), fov_y=40, width=64, height=64)
    lines = Strokes(points=np.array([[1.0, 1.0], [9.0, 1.0]]), surface=np.zeros((2, 3)), face=np.zeros(2, np.int64),
                    offsets=np.array([0, 2]), kind=np.zeros(1, np.int64), ids=np.zeros(1, np.int64), u=np.zeros(2),
                    level=np.zeros(1), level_weight=np.ones(1), camera=cam, frame=1, period_px=10.0)

    def in_loop(*a):
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as k:
            raise SystemError("CPUDispatcher(segment_runs) returned a result with an exception set") from k

    tr = Tracker()
    tr.step(lines)
    tr.method = SimpleNamespace(track=in_loop)
    with pytest.raises(KeyboardInterrupt):
        tr.step(lines)


def test_kernels_let_other_threads_run_and_their_options_are_in_the_cache_stamp(tmp_path):
    """A kernel releases Python's lock while it runs (KERNEL_OPTIONS nogil: the workers of a run
    are threads), so another thread of the process keeps running meanwhile; and a kernel cached
    under other options is compiled again (numba's own cache key does not hold them)."""
    _tiny_module(tmp_path, "sk_busy", """
        from strokekit.numba_cache import kernel

        @kernel("(i8,)")
        def spin(n):
            s = 0.0
            for i in range(n):
                s += (i % 7) * 0.5
            return s
        """)
    code = textwrap.dedent("""
        import importlib, sys, threading, time
        from strokekit import numba_cache
        if sys.argv[1] == "gil":
            numba_cache.KERNEL_OPTIONS = {"cache": True, "nogil": False}
        mod = importlib.import_module("sk_busy")
        print(numba_cache.compile_needed(mod))
        numba_cache.LazyKernels("sk_busy").kernels()
        mod.spin(10)
        n = 10
        while True:  # a call of about 0.3 s
            t = time.perf_counter(); mod.spin(n); dt = time.perf_counter() - t
            if dt > 0.3:
                break
            n *= 4
        wakes = []
        th = threading.Thread(target=mod.spin, args=(n,))
        th.start()
        while th.is_alive():
            time.sleep(0.001)
            wakes.append(1)
        print(len(wakes))
        """)
    env = {**os.environ, "PYTHONPATH": f"{tmp_path}:{ROOT}"}
    env.pop("NUMBA_CACHE_DIR", None)

    def run(options):
        out = subprocess.run([sys.executable, "-c", code, options], capture_output=True, text=True, cwd=tmp_path,
                             env=env, check=True).stdout.split()
        return out[0], int(out[1])

    needed, wakes = run("nogil")
    assert needed == "True" and wakes >= 20, wakes  # this thread woke while the kernel ran
    assert run("nogil")[0] == "False"  # (from the cache)
    needed, wakes = run("gil")
    assert needed == "True", "a kernel cached with other options would be loaded as it was"
    assert wakes <= 3, wakes  # holding the lock, the kernel keeps this thread asleep


def test_a_run_drawing_one_frame_at_a_time_warms_the_threaded_z_buffer(monkeypatch):
    """One worker: each frame's z-buffer runs on the machine's cores, so the warm-up compiles its
    parallel kernels with the others (else the first frame would compile them unsaid); frames
    drawn several at once keep the serial kernels and never load the parallel ones."""
    from strokekit.raster.options import RasterOptions
    from strokekit.run.kernels import kernels_needed
    from strokekit.run.spec import OutputOptions, RenderRequest, RunSpec

    monkeypatch.setattr(os, "cpu_count", lambda: 4)
    spec = RunSpec(scene_path="s.obj", cameras=(), outputs=OutputOptions(out_dir=Path("o")),
                   request=RenderRequest(raster=RasterOptions(bands=2)), workers=1)
    assert spec.raster_threads == 4 and RASTER_THREADS in kernels_needed(spec, frames_here=True)
    two = RunSpec(scene_path="s.obj", cameras=(), outputs=OutputOptions(out_dir=Path("o")),
                  request=RenderRequest(raster=RasterOptions(bands=2)), workers=2)
    assert two.raster_threads == 1 and RASTER_THREADS not in kernels_needed(two, frames_here=True)
    monkeypatch.setattr(os, "cpu_count", lambda: 1)
    assert RASTER_THREADS not in kernels_needed(spec, frames_here=True)


def _forget(*names):
    for n in names:
        sys.modules.pop(n, None)
        numba_cache.LazyKernels._made.pop(n, None)


def test_kernels_compile_side_by_side_each_module_once(monkeypatch, tmp_path):
    """A first run's warm-up spreads the modules to compile over the cores: each process takes
    the next module whose machine lock is free and skips those another process holds (so no
    module compiles twice), and the child interpreters' compiles land in numba's disk cache,
    where this process then finds them."""
    names = ["sk_side_a", "sk_side_b", "sk_side_c"]
    for n in names:
        _tiny_module(tmp_path, n, TINY_TOTAL)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(tmp_path), str(ROOT), os.environ.get("PYTHONPATH", "")]))
    # Another process holds sk_side_a's lock: this one compiles the other two only.
    held, release = threading.Event(), threading.Event()

    def holder():
        with numba_cache.machine_lock("sk_side_a"):
            held.set()
            release.wait(30)

    t = threading.Thread(target=holder)
    t.start()
    held.wait(10)
    try:
        numba_cache.claim_and_compile(names[:2])
    finally:
        release.set()
        t.join()
    mods = [numba_cache.LazyKernels(n).imported() for n in names]
    assert not mods[0].total.signatures and len(mods[1].total.signatures) == 1
    # Side by side with this thread taking nothing: the child interpreter compiles both others.
    monkeypatch.setattr(numba_cache, "claim_and_compile", lambda modules, parent=None: None)
    numba_cache.compile_side_by_side(["sk_side_a", "sk_side_c"], 2)
    _forget(*names)
    assert [numba_cache.compile_needed(numba_cache.LazyKernels(n).imported()) for n in names] == [False] * 3
    _forget(*names)


def test_warming_the_threaded_z_buffer_says_nothing_of_numbas_threading_layer(tmp_path):
    """A one-worker run compiles the z-buffer's parallel kernels on a machine's first run: numba
    then finds open3d's TBB too old and takes OpenMP, which must not print a NumbaWarning at the
    user. (A fresh interpreter and an empty cache: numba says it once, when it compiles.)"""
    code = "import open3d\nfrom strokekit.raster.hits import RASTER_THREADS\nRASTER_THREADS.warm()\n"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT,
                         env=dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path)))
    assert out.returncode == 0, out.stderr[-2000:]
    assert "Warning" not in out.stderr, out.stderr[-2000:]
