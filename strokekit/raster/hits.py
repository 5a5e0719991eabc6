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

The kernels (`strokekit.raster.zbuffer`, `strokekit.raster.compiled`) are loaded on first use
(`strokekit.numba_cache`): lines-only runs never import numba.
"""

from __future__ import annotations

import threading

import numpy as np

from strokekit.camera.view import Camera
from strokekit.numba_cache import KernelGroup, LazyKernels
from strokekit.raster.rays import cast_pixels, cast_samples
from strokekit.raster.workspace import Workspace
from strokekit.scene.load import Scene

#: The z-buffer and the raster pass's own loops.
ZBUFFER, PASS = LazyKernels("strokekit.raster.zbuffer"), LazyKernels("strokekit.raster.compiled")
RASTER = KernelGroup("raster", (ZBUFFER, PASS), compile_seconds=20)

#: The z-buffer's parallel kernels: runs that draw their frames one at a time use the cores in
#: each frame's z-buffer instead (`RunSpec.raster_threads`).
RASTER_THREADS = KernelGroup("raster threads", (ZBUFFER,), compile_seconds=6, parallel=True)

#: The z-buffer module, its kernels loaded on first use.
kernels = ZBUFFER.kernels
#: The raster pass's own compiled loops, loaded on first use.
compiled = PASS.kernels
#: Load (or compile) the raster kernels before any frame: (seconds, compiled).
warm_kernels = RASTER.warm
#: Make sure this process has them before its first raster pass: the seconds it loaded them for.
ensure_kernels = RASTER.ensure


# --- sample sources ------------------------------------------------------------------------------

class ZBufferHits:
    """The z-buffer's first hits of one frame: vertices projected once, faces set up once (the
    near-plane clipping), then any number of grid or pixel passes.

    Parallel projections are orthographic views; the oblique ones (cavalier, cabinet) project
    along camera.ray_dir, which is orthographic projection after a shear: each vertex is moved
    by (kx right + ky up) times its view depth z (Camera.shear), which puts it where the oblique
    camera draws it, keeps z (the depth along fwd the rays report) and, being affine, keeps
    every barycentric coordinate."""

    def __init__(self, scene: Scene, camera: Camera, work=None, threads: int = 1):
        zb = kernels()
        self.threads = threads
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
        h = self._zb.rasterize_grid(self.proj, K, threads=self.threads, work=None if own else self.work)
        return h.face, h.bary, h.depth

    def pixels(self, pixels: np.ndarray, R: int):
        h = self._zb.rasterize_pixels(self.proj, pixels, R, threads=self.threads, work=self.work)
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
    with it lives until the next pass of this thread. Made without the kernels (a frame task asks
    before its lines, while they may still be loading)."""
    w = getattr(_local, "work", None)
    if w is None:
        w = _local.work = Workspace()
    return w
