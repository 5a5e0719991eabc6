"""Where the raster pass's samples come from: the first surface behind the near plane at each
sample, from the z-buffer rasterizer (the default, `strokekit.raster.zbuffer`, numba kernels) or
from the Embree ray caster (`strokekit.raster.rays`, the reference that tests and `strokekit
bench` hold the rasterizer against).

Both give the same arrays for the same sample positions (image space as `Camera`: x right, y
down, origin top-left): `grid(K)` the K x K-per-pixel grid, sample (i, j) at output pixel
coordinates ((i + 0.5) / K, (j + 0.5) / K); `pixels(pix, R)` R x R samples in each listed pixel,
sample b * R + a at (px + (a + 0.5) / R, py + (b + 0.5) / R). Face int32 (-1: background),
barycentrics float32 (u, v) with P = (1 - u - v) A + u B + v C, depth float32 view depth z
(inf: background).

The kernels are compiled once per machine and cached on disk by numba (`cache=True`; where:
`strokekit.numba_cache`). numba itself (about 0.3 s to import) is only imported when
a raster pass runs: lines-only runs never load it.
"""

from __future__ import annotations

import threading
import time
from pathlib import Path
from typing import Callable

import numpy as np

from strokekit.camera.view import Camera
from strokekit.numba_cache import choose_cache_dir as _choose_cache_dir
from strokekit.numba_cache import compile_needed, machine_lock
from strokekit.raster.rays import cast_pixels, cast_samples
from strokekit.scene.load import Scene

#: The modules of the compiled kernels, imported on first use (numba's import costs about 0.3 s):
#: the z-buffer, and the raster pass's own loops.
KERNELS = ("strokekit.raster.zbuffer", "strokekit.raster.compiled")
#: About how long the first compile of the kernels takes (s), on this project's 2-core machine
#: (19-20 s measured with another job running, 2026-11-26; README "Raster pass").
COMPILE_SECONDS = 20

_kernels = None
_lock = threading.Lock()


def choose_cache_dir() -> str | None:
    """numba_cache.choose_cache_dir for the raster kernels' folder. Call before they are imported."""
    return _choose_cache_dir(Path(__file__).resolve().parent)


def kernels():
    """The z-buffer module (`strokekit.raster.zbuffer`), imported on first use."""
    return _modules()[0]


def compiled():
    """The raster pass's own compiled loops (`strokekit.raster.compiled`), imported on first use."""
    return _modules()[1]


def _modules():
    global _kernels
    if _kernels is None:
        import importlib

        with _lock:
            if _kernels is None:
                choose_cache_dir()
                _kernels = tuple(importlib.import_module(m) for m in KERNELS)
    return _kernels


def _compile_needed(modules) -> bool | None:
    """numba_cache.compile_needed: whether warming the kernels up will compile them. The raster
    pass runs serial kernels (one frame a process; the run's processes share the cores)."""
    return compile_needed(modules)


_ASK = object()


def warm_kernels(notify: Callable[[str], None] | None = None, *, compiles=_ASK) -> tuple[float, bool]:
    """Compile (the first run on a machine) or load (from numba's disk cache) the kernels the
    raster pass uses, before any frame: (seconds, compiled). `notify(line)` is told once, before
    the wait, when they compile. Workers started afterwards load them from the cache.
    (`compiles`: what _compile_needed said, when the caller has asked it already.)"""
    t = time.perf_counter()
    mods = _modules()
    if compiles is _ASK:
        compiles = _compile_needed(mods)
    msg = f"compiling the raster kernels (first run on this machine, about {COMPILE_SECONDS} s)"
    timer = None
    if notify is not None:
        if compiles:
            notify(msg)
        elif compiles is None:  # cannot tell beforehand: say it if the warm-up is slow
            timer = threading.Timer(2.0, notify, (msg,))
            timer.daemon = True
            timer.start()
    try:
        if compiles is False:
            _warm(mods)
        else:
            # One process of the machine compiles; the others wait, then load what it cached (a
            # dask cluster's workers, concurrent runs).
            with machine_lock("raster-kernels"):
                if _compile_needed(mods) is False:
                    compiles = False
                _warm(mods)
    finally:
        if timer is not None:
            timer.cancel()
    return time.perf_counter() - t, bool(compiles)


def _warm(mods) -> None:
    mods[0].warmup(parallel=False)
    mods[1].warmup()


def ensure_kernels() -> float:
    """Make sure this process has the kernels before its first raster pass: wait for a warm-up
    thread that is loading them, else load them (or compile them, one process of the machine at
    a time: the others then load them from the cache). Returns the seconds this call loaded them
    for (0 when a warm-up thread did, or they were there)."""
    global _ready
    if _ready:
        return 0.0
    w = _warming
    if w is not None:
        w.join()
    seconds = 0.0 if w is not None and w.error is None else warm_kernels()[0]
    _ready = True
    return seconds


_ready = False


class KernelWarmup:
    """`warm_kernels` in a background thread, started as early as possible: loading the kernels
    from the cache (numba's import and first-use set-up: 0.6 to 1 s a process) overlaps the
    process's other work instead of delaying its first frame (a raster call meanwhile waits for
    it on numba's compiler lock). `compiles()` says, once known, whether they are being compiled
    (a machine's first run: then the caller waits for `join()` before any worker starts a frame,
    so that they load the kernels from the cache instead of each compiling them)."""

    def __init__(self, notify: Callable[[str], None] | None = None):
        self._notify = notify
        self._decided = threading.Event()
        self._compiles: bool | None = None
        self.seconds = 0.0
        self.error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, name="strokekit-raster-kernels", daemon=True)
        global _warming
        _warming = self
        self._thread.start()

    def _run(self) -> None:
        t = time.perf_counter()
        try:
            self._compiles = _compile_needed(_modules())
            self._decided.set()
            warm_kernels(self._notify, compiles=self._compiles)
        except BaseException as e:  # said by the frames that need the kernels
            self.error = e
        finally:
            self._decided.set()
            self.seconds = time.perf_counter() - t

    def done(self) -> bool:
        return not self._thread.is_alive()

    def compiles(self) -> bool | None:
        self._decided.wait()
        return self._compiles

    def join(self) -> float:
        self._thread.join()
        return self.seconds


_warming: KernelWarmup | None = None


# --- sample sources ------------------------------------------------------------------------------

class ZBufferHits:
    """The z-buffer's first hits of one frame: vertices projected once, faces set up once (the
    near-plane clipping), then any number of grid or pixel passes.

    Parallel projections are orthographic views; the oblique ones (cavalier, cabinet) project
    along camera.ray_dir, which is orthographic projection after a shear: each vertex is moved
    by (kx right + ky up) times its view depth z (Camera.shear), which puts it where the oblique
    camera draws it, keeps z (the depth along fwd the rays report) and, being affine, keeps
    every barycentric coordinate."""

    def __init__(self, scene: Scene, camera: Camera, work=None):
        zb = kernels()
        self.camera = camera
        self.near = camera.near_distance(scene.radius)
        v = scene.vertices
        if camera.is_oblique:
            right, up, fwd = camera.basis
            kx, ky = camera.shear
            z = (v - camera.eye_array) @ fwd
            v = v + z[:, None] * (kx * right + ky * up)
        self.proj = zb.project(v, scene.faces_int32, zb.view_from_camera(camera, self.near))
        self._zb = zb
        self.work = work

    @property
    def vertices_px(self) -> tuple[np.ndarray, np.ndarray]:
        """((V, 2) pixel coordinates, (V,) view depth z) of the scene's vertices (NaN / inf
        pixels where a perspective z <= 0)."""
        return self.proj.xy, self.proj.cam[:, 2]

    def grid(self, K: int, own: bool = False):
        """(face, bary, depth) of the K x K grid; `own`: in new arrays, not the workspace's (a
        second grid of the frame, which must not take the first one's buffers)."""
        h = self._zb.rasterize_grid(self.proj, K, work=None if own else self.work)
        return h.face, h.bary, h.depth

    def pixels(self, pixels: np.ndarray, R: int):
        h = self._zb.rasterize_pixels(self.proj, pixels, R, work=self.work)
        return h.face, h.bary, h.depth


class RayHits:
    """The same from Embree rays (raster.rays.cast_pixels / cast_samples): the reference."""

    def __init__(self, scene: Scene, camera: Camera, occluder):
        self.camera = camera
        self.occluder = occluder
        self.scene = scene

    @property
    def vertices_px(self) -> tuple[np.ndarray, np.ndarray]:
        return self.camera.project(self.scene.vertices)

    def grid(self, K: int, own: bool = False):
        h = cast_pixels(self.camera, self.occluder, K)
        return h.face, h.bary, h.depth

    def pixels(self, pixels: np.ndarray, R: int):
        cam = self.camera
        W, H, f = int(cam.width), int(cam.height), cam.focal_px
        py, px = np.divmod(np.asarray(pixels, np.int64), W)
        sub = (np.arange(R) + 0.5) / R
        x = (px[:, None] + np.tile(sub, R)[None, :]).ravel()
        y = (py[:, None] + np.repeat(sub, R)[None, :]).ravel()
        h = cast_samples(cam, self.occluder, (x - W / 2.0) / f, (H / 2.0 - y) / f)
        P = len(px)
        return (h["face"].reshape(P, R * R), h["bary"].reshape(P, R * R, 2), h["depth"].reshape(P, R * R))


#: One z-buffer workspace per thread (the run's frame tasks reuse its buffers frame after frame).
_local = threading.local()


def thread_workspace():
    """This thread's zbuffer.Workspace: buffers reused from frame to frame. What a pass returns
    with it lives until the next pass of this thread."""
    w = getattr(_local, "work", None)
    if w is None:
        w = _local.work = kernels().Workspace()
    return w
