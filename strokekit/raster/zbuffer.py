"""A z-buffer rasterizer for the raster pass: face id, view depth and barycentrics of
the first surface behind the near plane, per sample, for perspective and orthographic cameras.

Imports numpy and numba only (and its buffers, `raster.workspace`). It returns what the ray-cast
pass (strokekit's `cast_pixels` / `cast_samples`) returns, for the same sample positions:

* image space as `Camera`: x right, y down, origin top-left, output pixel (i, j) covers
  [i, i+1] x [j, j+1];
* `rasterize_grid(proj, K)`: sample (i, j) of the K-times supersampled grid sits at output pixel
  coordinates ((i + 0.5) / K, (j + 0.5) / K), as in cast_pixels(camera, occluder, K);
* `rasterize_pixels(proj, pixels, R)`: output pixel p = py * W + px gets R x R samples at
  (px + (a + 0.5) / R, py + (b + 0.5) / R), sample b * R + a (row-major inside the pixel), as
  bands._edge_coverage hands them to cast_samples;
* face int32 (-1: background); depth float32, view depth z = (P - eye) . fwd in world units
  (inf: background), which is what the ray caster returns (t_hit + near); bary float32 (u, v)
  with P = (1 - u - v) A + u B + v C (open3d's primitive_uvs), perspective-correct (0, 0 for
  background).

What the rays see is what lies at view depth z >= near (perspective and orthographic rays start
on the near plane), so triangles are clipped against the plane z = near in camera space
(Sutherland-Hodgman: a triangle with one or two corners before the plane becomes a triangle or a
quad), not dropped. Both sides of a triangle are drawn (no culling), like the rays.

Exactness and determinism
-------------------------
Coverage: a sample is inside a triangle by the three edge functions in float64, evaluated per
sample (no incremental stepping) with each edge's end points in a canonical order (the
lexicographically smaller (x, y) first), so the two triangles of a shared edge compute bitwise the
same value and see it with opposite signs. A sample exactly on an edge (value 0) belongs to the
triangle for which it is a top or a left edge (the D3D / OpenGL top-left rule, y down): a sample
on an edge shared by two triangles on either side of it is covered exactly once, never twice,
never zero times. Clip points on a shared edge are computed from the edge's outside end to its
inside end, so the two faces agree on them bitwise too. Scaling to the sample grid multiplies
coordinates by K or R, exact for powers of two. No fastmath (FMA contraction or reassociation
would break the bitwise agreement).

Depth test: the nearer sample wins; at equal depth the lower face id (faces are drawn in
increasing id order with a strict test). So each sample gets the minimum of (depth, face id)
over the faces covering it, whatever the thread: the sample grid is cut into TILE x TILE tiles,
each drawn whole by one thread, and any thread count gives bit-identical arrays.

Depth and barycentrics of the winning face are computed per sample from the face's own
(unclipped) plane in float64: 1/z, u/z and v/z are affine in screen space (z and u, v for
orthographic), so z = 1 / (1/z) and u = (u/z) * z are the ray-plane intersection in float64,
then stored as float32 (the tests find them within float32 rounding of an independent float64
ray-triangle intersection: depth 6e-8 relative, barycentrics 3e-8).

Use
---
    proj = project(vertices, faces, view_from_camera(camera, camera.near_distance(radius)))
    grid = rasterize_grid(proj, 2)               # (2H, 2W) face / depth, (2H, 2W, 2) bary
    edge = rasterize_pixels(proj, pixels, 4)     # (P, 16) face / depth, (P, 16, 2) bary

Per frame, `project` does the vertex transform once (numpy); the first rasterize call on a
Projected sets up every face once (clipping, screen planes), and later calls on the same
Projected (other sample counts, the edge pixels) reuse that. threads=1 (default) runs serial
kernels and never starts numba's thread pool; threads=n > 1 runs the parallel ones.

The kernels are compiled once per machine and cached on disk (`strokekit.numba_cache`; the
parallel ones on their first threaded use).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np
from numba import njit, prange

from strokekit.numba_cache import kernel
from strokekit.raster.workspace import Workspace

__all__ = ["View", "Projected", "ZHits", "Workspace", "view_from_camera", "project", "rasterize_grid",
           "rasterize_pixels", "sample_offsets", "TILE"]

#: Side of the square tiles the sample grid is drawn in, in samples: a tile's depth buffer
#: (TILE^2 float64 + int32) stays in cache, and tiles are what threads share out.
TILE = 64


# --- camera parameters ------------------------------------------------------------------------

@dataclass(frozen=True)
class View:
    """Plain camera parameters (what the kernels need of a strokekit Camera).

    eye, right, up, fwd: (3,) float64, the camera position and its orthonormal frame
    (Camera.basis: right, up', fwd). focal_px: pixels per unit of x/z (perspective) or per world
    unit (orthographic) (Camera.focal_px). width, height: output image, pixels. near: view depth
    of the near plane, world units (Camera.near_distance(scene radius))."""

    eye: np.ndarray
    right: np.ndarray
    up: np.ndarray
    fwd: np.ndarray
    focal_px: float
    width: int
    height: int
    ortho: bool
    near: float


def view_from_camera(camera, near: float) -> View:
    """View of a strokekit Camera (duck-typed: .eye, .basis, .focal_px, .width, .height,
    .is_ortho) with its near distance (camera.near_distance(scene.radius))."""
    right, up, fwd = camera.basis
    return View(eye=np.asarray(camera.eye, np.float64), right=np.asarray(right, np.float64),
                up=np.asarray(up, np.float64), fwd=np.asarray(fwd, np.float64), focal_px=float(camera.focal_px),
                width=int(camera.width), height=int(camera.height), ortho=bool(camera.is_ortho), near=float(near))


@dataclass(frozen=True, eq=False)
class Projected:
    """One frame's vertices, projected once (numpy), and its faces.

    vert (V, 8) float64, one 64-byte row a vertex (one cache line a gather): output pixel
    coordinates x, y (NaN / inf where z <= 0 in perspective: those vertices' triangles are clipped
    in camera space), camera coordinates along right, up', fwd (the last is the view depth z), 3
    unused; faces (F, 3) int32. The per-face set-up of the first rasterize call is kept here (or
    in its Workspace) for the frame's later calls."""

    view: View
    vert: np.ndarray
    faces: np.ndarray
    _cache: dict = field(default_factory=dict, repr=False)

    @property
    def xy(self) -> np.ndarray:
        """(V, 2) output pixel coordinates (a view)."""
        return self.vert[:, 0:2]

    @property
    def cam(self) -> np.ndarray:
        """(V, 3) camera coordinates (a view)."""
        return self.vert[:, 2:5]


def project(vertices: np.ndarray, faces: np.ndarray, view: View) -> Projected:
    """Project (V, 3) world vertices for `view`, with (F, 3) faces (copied to int32 unless they
    already are int32 and C-contiguous: convert once per scene, not per frame)."""
    v = np.asarray(vertices, np.float64)
    n = len(v)
    raw = np.empty(n * 8 + 8, np.float64)
    k = (-raw.ctypes.data % 64) // 8  # 64-byte aligned rows
    vert = raw[k:k + n * 8].reshape(n, 8)
    q = v - view.eye
    # Column by column, not q @ basis: a (V, 3) x (3, 3) product wakes BLAS threads that then
    # spin on the other core.
    for c, axis in enumerate((view.right, view.up, view.fwd)):
        vert[:, 2 + c] = q[:, 0] * axis[0] + q[:, 1] * axis[1] + q[:, 2] * axis[2]
    vert[:, 5:] = 0.0
    cam = vert[:, 2:5]
    f = view.focal_px
    if view.ortho:
        vert[:, 0] = view.width / 2.0 + f * cam[:, 0]
        vert[:, 1] = view.height / 2.0 - f * cam[:, 1]
    else:
        with np.errstate(divide="ignore", invalid="ignore"):
            vert[:, 0] = view.width / 2.0 + f * cam[:, 0] / cam[:, 2]
            vert[:, 1] = view.height / 2.0 - f * cam[:, 1] / cam[:, 2]
    fc = np.asarray(faces)
    if fc.dtype != np.int32 or not fc.flags.c_contiguous:
        fc = np.ascontiguousarray(fc, dtype=np.int32).reshape(-1, 3)
    return Projected(view=view, vert=vert, faces=fc)


def sample_offsets(view: View, samples: int) -> tuple[np.ndarray, np.ndarray]:
    """(ray_dir_x (W*K,), ray_dir_y (H*K,)) float64 of the K-times supersampled grid, exactly as
    raster.cast_pixels computes them (RasterHits.ray_dir_x / ray_dir_y)."""
    K = int(samples)
    W, H, f = int(view.width), int(view.height), view.focal_px
    px = (np.arange(W * K) + 0.5) / K - W / 2.0
    py = H / 2.0 - (np.arange(H * K) + 0.5) / K
    return px / f, py / f


# --- results and buffers ----------------------------------------------------------------------

@dataclass(frozen=True)
class ZHits:
    """Per-sample first hits. Grid: face (HK, WK), depth (HK, WK), bary (HK, WK, 2); pixels:
    face (P, R*R), depth (P, R*R), bary (P, R*R, 2). face int32 (-1 background), depth float32
    view depth (inf background), bary float32 open3d (u, v) (0 background)."""

    face: np.ndarray
    depth: np.ndarray
    bary: np.ndarray


def _get(work: Workspace | None, name: str, shape: tuple, dtype) -> np.ndarray:
    return np.empty(shape, dtype) if work is None else work.get(name, shape, dtype)


def _threads(threads: int | None) -> int:
    import numba

    n = numba.config.NUMBA_NUM_THREADS if threads is None else int(threads)
    return max(1, min(n, numba.config.NUMBA_NUM_THREADS))


# --- entry points -----------------------------------------------------------------------------

def rasterize_grid(proj: Projected, samples: int = 1, *, threads: int | None = 1,
                   work: Workspace | None = None) -> ZHits:
    """First hits on the regular K x K-per-pixel grid (K = samples >= 1; powers of two keep
    the sample coordinates exact): arrays (H*K, W*K) row-major, as RasterHits.

    threads: 1 (default) serial; n > 1 (None: numba's thread count) n threads, same result."""
    K = int(samples)
    if K < 1:
        raise ValueError(f"samples must be >= 1, got {samples}")
    v = proj.view
    shape = (int(v.height) * K, int(v.width) * K)
    face, depth, bary = (_get(work, "face", shape, np.int32), _get(work, "depth", shape, np.float32),
                         _get(work, "bary", shape + (2,), np.float32))
    none = np.empty((0, 0), np.int32)
    _pass(proj, K, none, none, face, depth, bary, _threads(threads), work)
    return ZHits(face=face, depth=depth, bary=bary)


def rasterize_pixels(proj: Projected, pixels: np.ndarray, R: int, *, threads: int | None = 1,
                     work: Workspace | None = None) -> ZHits:
    """First hits on R x R samples in each listed output pixel: pixels (P,) flat indices
    py * W + px, each at most once, any order; arrays (P, R*R), sample b * R + a at
    (px + (a + 0.5) / R, py + (b + 0.5) / R). Flattened to (P * R * R,), the order of the
    current code's `_edge_coverage` samples."""
    R = int(R)
    if R < 1:
        raise ValueError(f"R must be >= 1, got {R}")
    v = proj.view
    W, H = int(v.width), int(v.height)
    pix = np.ascontiguousarray(pixels, dtype=np.int64).reshape(-1)
    P = len(pix)
    if P and (pix.min() < 0 or pix.max() >= W * H):
        raise ValueError("pixel index outside the image")
    shape = (P, R * R)
    face, depth, bary = (_get(work, "pface", shape, np.int32), _get(work, "pdepth", shape, np.float32),
                         _get(work, "pbary", shape + (2,), np.float32))
    if P == 0:
        return ZHits(face=face, depth=depth, bary=bary)
    slots = _get(work, "slots", (H, W), np.int32)
    slots.fill(-1)
    slots.reshape(-1)[pix] = np.arange(P, dtype=np.int32)
    sat = _get(work, "sat", (H + 1, W + 1), np.int32)
    if _slot_table(slots, sat) != P:
        raise ValueError("a pixel is listed twice")
    _pass(proj, R, slots, sat, face, depth, bary, _threads(threads), work)
    return ZHits(face=face, depth=depth, bary=bary)




# --- driver -----------------------------------------------------------------------------------

def _parallel_call(fn, threads, *args):
    """fn(*args) on `threads` numba threads (the TBB layer warning open3d's older TBB causes is
    silenced: numba then picks OpenMP or its workqueue)."""
    import numba

    with warnings.catch_warnings():  # (get_num_threads starts the pool: it warns)
        warnings.filterwarnings("ignore", message=".*TBB.*")
        old = numba.get_num_threads()
        numba.set_num_threads(threads)
        try:
            return fn(*args)
        finally:
            numba.set_num_threads(old)


def _setup(proj: Projected, threads: int, work: Workspace | None):
    """Per-face set-up of the frame, in output pixel units, once per Projected: (fbox (F, 4)
    float64 xmin, xmax, ymin, ymax of the drawn part, fn (F,) int8 its triangle count (0: none),
    ftri (F, 2, 6) float64 the triangles' corners, fplane (F, 9) float64 key, U, V planes)."""
    holder = proj._cache if work is None else work._bufs
    if holder.get("setup_of") is proj:
        return holder["setup"]
    v = proj.view
    F = max(len(proj.faces), 1)
    arrays = (_get(work, "fbox", (F, 4), np.float64), _get(work, "fn", (F,), np.int8),
              _get(work, "ftri", (F, 2, 6), np.float64), _get(work, "fplane", (F, 9), np.float64))
    args = (proj.vert, proj.faces, int(v.width), int(v.height), float(v.focal_px), v.width / 2.0,
            v.height / 2.0, bool(v.ortho), float(v.near)) + arrays
    if threads > 1:
        _parallel_call(_setup_parallel, threads, *args)
    else:
        _setup_serial(*args)
    holder["setup"] = arrays
    holder["setup_of"] = proj
    return arrays


def _pass(proj, S, slots, sat, face, depth, bary, threads, work):
    v = proj.view
    fbox, fn, ftri, fplane = _setup(proj, threads, work)
    WS, HS = int(v.width) * S, int(v.height) * S
    T = S * max(1, -(-TILE // S))  # tile side in samples, a multiple of S
    F = len(proj.faces)
    keep = _get(work, "keep", (max(F, 1),), np.bool_)
    active, off = _plan(fbox[:F], fn[:F], S, WS, HS, T, sat, keep)
    n = int(off[-1])
    if work is None:
        rec, rid = np.empty((max(n, 1), 16), np.float64), np.empty(max(n, 1), np.int32)
    else:
        rec = work._bufs.get("rec")
        if rec is None or len(rec) < n:  # grown by half when short
            work._bufs["rec"] = rec = np.empty((max(n + n // 2, 1), 16), np.float64)
            work._bufs["rid"] = np.empty(len(rec), np.int32)
        rid = work._bufs["rid"]
    args = (fbox[:F], fn[:F], ftri, fplane, keep, S, WS, HS, T, bool(v.ortho), slots, active, off, rec, rid,
            face.reshape(-1), depth.reshape(-1), bary.reshape(-1, 2))
    if threads > 1:
        _parallel_call(_draw_parallel, threads, *args)
    else:
        _draw_serial(*args)


# --- kernels ----------------------------------------------------------------------------------
# Set-up (per frame, pixel units): _setup_range clips each face, and stores its screen box, its
# triangle(s) and its key, U and V planes. Per pass (sample grid scaled S = K or R): _plan counts
# each tile's records (one per face triangle per tile its box touches; listed pixels only for the
# edge pass), _fill writes them in face id order (rec (N, 16) float64: the triangle's corners in
# sample coordinates, then key, U and V planes; rid (N,) face id), and each tile is drawn into a
# small local buffer (_tris), resolved (_resolve) and written out (_do_tile).
# Key: a face's "nearness" at a sample, 1/z (perspective) or -z (orthographic): affine in screen
# coordinates over the face's plane; larger is nearer.

_LIM = 1e9  # coordinates are clamped to +-_LIM before int()


@njit(cache=True, error_model="numpy")
def _cut(ox, oy, oz, ix, iy, iz, near, f, cx, cy, ortho):
    """Pixel coordinates of the point where the edge from o (z < near) to i (z >= near), camera
    coordinates, crosses z = near. Always computed from the outside end, whichever face asks:
    the two faces of an edge get it bitwise equal."""
    t = (near - oz) / (iz - oz)
    qx = ox + t * (ix - ox)
    qy = oy + t * (iy - oy)
    if ortho:
        return cx + f * qx, cy - f * qy
    return cx + f * qx / near, cy - f * qy / near


@njit(cache=True, error_model="numpy")
def _clip1(Ix, Iy, Iz, Ipx, Ipy, Px, Py, Pz, Qx, Qy, Qz, near, f, cx, cy, ortho):
    """Sutherland-Hodgman, one corner I in front (then P, Q in the face's order): the triangle
    I, I-P cut, Q-I cut (pixel coordinates)."""
    x1, y1 = _cut(Px, Py, Pz, Ix, Iy, Iz, near, f, cx, cy, ortho)
    x2, y2 = _cut(Qx, Qy, Qz, Ix, Iy, Iz, near, f, cx, cy, ortho)
    return Ipx, Ipy, x1, y1, x2, y2


@njit(cache=True, error_model="numpy")
def _clip2(Ox, Oy, Oz, Px, Py, Pz, Ppx, Ppy, Qx, Qy, Qz, Qpx, Qpy, near, f, cx, cy, ortho):
    """Sutherland-Hodgman, one corner O behind (then P, Q in front, in the face's order): the
    quad P, Q, Q-O cut, O-P cut (pixel coordinates)."""
    x2, y2 = _cut(Ox, Oy, Oz, Qx, Qy, Qz, near, f, cx, cy, ortho)
    x3, y3 = _cut(Ox, Oy, Oz, Px, Py, Pz, near, f, cx, cy, ortho)
    return Ppx, Ppy, Qpx, Qpy, x2, y2, x3, y3


@njit(cache=True, error_model="numpy")
def _plane(Ax, Ay, Az, Bx, By, Bz, Cx, Cy, Cz, f, cx, cy, ortho):
    """(ok, (gx, gy, g0, ux, uy, u0, vx, vy, v0)): the key, U and V of the face with camera-space
    corners A, B, C as affine functions of output pixel coordinates (see below); ok False for a
    degenerate face or one seen edge-on."""
    # Plane of the face in camera space, n . P = d, and its barycentrics u = P . g1 - a1,
    # v = P . g2 - a2 (g1 = (e2 x n) / |n|^2, g2 = (n x e1) / |n|^2, a = A . g).
    e1x, e1y, e1z = Bx - Ax, By - Ay, Bz - Az
    e2x, e2y, e2z = Cx - Ax, Cy - Ay, Cz - Az
    nx = e1y * e2z - e1z * e2y
    ny = e1z * e2x - e1x * e2z
    nz = e1x * e2y - e1y * e2x
    d = nx * Ax + ny * Ay + nz * Az
    nn = nx * nx + ny * ny + nz * nz
    if (nz == 0.0 if ortho else d == 0.0) or nn == 0.0:
        return False, (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    inn = 1.0 / nn
    iF = 1.0 / f
    g1x = (e2y * nz - e2z * ny) * inn
    g1y = (e2z * nx - e2x * nz) * inn
    g1z = (e2x * ny - e2y * nx) * inn
    g2x = (ny * e1z - nz * e1y) * inn
    g2y = (nz * e1x - nx * e1z) * inn
    g2z = (nx * e1y - ny * e1x) * inn
    a1 = Ax * g1x + Ay * g1y + Az * g1z
    a2 = Ax * g2x + Ay * g2y + Az * g2z
    # At pixel coordinates (px, py) the ray's camera-plane offsets are sx = (px - cx) * iF,
    # sy = (cy - py) * iF. Everything below is affine in (px, py): the key (gx, gy, g0),
    # U (ux, uy, u0), V (vx, vy, v0).
    if ortho:
        # Ray (sx, sy, t): z = (d - nx sx - ny sy) / nz; key = -z; u = sx g1x + sy g1y + z g1z - a1.
        q = 1.0 / (nz * f)
        gx = nx * q
        gy = -ny * q
        g0 = -(d * f + nx * cx - ny * cy) * q
        # U = u, V = v (with z = -key).
        ux = g1x * iF - g1z * gx
        uy = -g1y * iF - g1z * gy
        u0 = (g1y * cy - g1x * cx) * iF - g1z * g0 - a1
        vx = g2x * iF - g2z * gx
        vy = -g2y * iF - g2z * gy
        v0 = (g2y * cy - g2x * cx) * iF - g2z * g0 - a2
    else:
        # Ray t (sx, sy, 1): key = w = 1/z = (nx sx + ny sy + nz) / d; perspective-correct
        # u = U / w with U = sx g1x + sy g1y + g1z - a1 w, the same for v.
        q = 1.0 / (d * f)
        gx = nx * q
        gy = -ny * q
        g0 = (nz * f - nx * cx + ny * cy) * q
        ux = g1x * iF - a1 * gx
        uy = -g1y * iF - a1 * gy
        u0 = (g1y * cy - g1x * cx) * iF + g1z - a1 * g0
        vx = g2x * iF - a2 * gx
        vy = -g2y * iF - a2 * gy
        v0 = (g2y * cy - g2x * cx) * iF + g2z - a2 * g0
    return True, (gx, gy, g0, ux, uy, u0, vx, vy, v0)


@njit(cache=True, error_model="numpy")
def _setup_range(f0, f1, vp, faces, W, H, f, cx, cy, ortho, near, fbox, fn, ftri, fplane):
    """Set up faces f0..f1-1 (pixel units): fn[fi] the triangle count after clipping against
    z >= near (0: nothing to draw: before the near plane, off the image, degenerate or seen
    edge-on), fbox[fi] the box of the drawn part, ftri[fi, k] its triangles' corners (x0, y0,
    x1, y1, x2, y2; a clipped quad is the fan from its first corner), fplane[fi] its planes.
    Scalars only below (helpers taking arrays would cost reference counting per face)."""
    for fi in range(f0, f1):
        fn[fi] = 0
        i0 = faces[fi, 0]
        i1 = faces[fi, 1]
        i2 = faces[fi, 2]
        ax, ay, az, apx, apy = vp[i0, 2], vp[i0, 3], vp[i0, 4], vp[i0, 0], vp[i0, 1]
        bx, by, bz, bpx, bpy = vp[i1, 2], vp[i1, 3], vp[i1, 4], vp[i1, 0], vp[i1, 1]
        qx, qy, qz, qpx, qpy = vp[i2, 2], vp[i2, 3], vp[i2, 4], vp[i2, 0], vp[i2, 1]
        ina = az >= near
        inb = bz >= near
        inq = qz >= near
        m = 3
        x3 = y3 = 0.0
        if ina and inb and inq:
            x0, y0, x1, y1, x2, y2 = apx, apy, bpx, bpy, qpx, qpy
        elif not (ina or inb or inq):
            continue
        elif ina and not (inb or inq):
            x0, y0, x1, y1, x2, y2 = _clip1(ax, ay, az, apx, apy, bx, by, bz, qx, qy, qz, near, f, cx, cy, ortho)
        elif inb and not (inq or ina):
            x0, y0, x1, y1, x2, y2 = _clip1(bx, by, bz, bpx, bpy, qx, qy, qz, ax, ay, az, near, f, cx, cy, ortho)
        elif inq and not (ina or inb):
            x0, y0, x1, y1, x2, y2 = _clip1(qx, qy, qz, qpx, qpy, ax, ay, az, bx, by, bz, near, f, cx, cy, ortho)
        else:
            m = 4
            if not ina:
                x0, y0, x1, y1, x2, y2, x3, y3 = _clip2(ax, ay, az, bx, by, bz, bpx, bpy, qx, qy, qz, qpx, qpy,
                                                        near, f, cx, cy, ortho)
            elif not inb:
                x0, y0, x1, y1, x2, y2, x3, y3 = _clip2(bx, by, bz, qx, qy, qz, qpx, qpy, ax, ay, az, apx, apy,
                                                        near, f, cx, cy, ortho)
            else:
                x0, y0, x1, y1, x2, y2, x3, y3 = _clip2(qx, qy, qz, ax, ay, az, apx, apy, bx, by, bz, bpx, bpy,
                                                        near, f, cx, cy, ortho)
        xmin = min(x0, x1, x2)
        xmax = max(x0, x1, x2)
        ymin = min(y0, y1, y2)
        ymax = max(y0, y1, y2)
        if m == 4:
            xmin = min(xmin, x3)
            xmax = max(xmax, x3)
            ymin = min(ymin, y3)
            ymax = max(ymax, y3)
        if not (xmax >= 0.0 and xmin <= W and ymax >= 0.0 and ymin <= H):
            continue  # off the image (or NaN)
        ok, pl = _plane(ax, ay, az, bx, by, bz, qx, qy, qz, f, cx, cy, ortho)
        if not ok:
            continue
        for c in range(9):
            fplane[fi, c] = pl[c]
        ftri[fi, 0, 0] = x0
        ftri[fi, 0, 1] = y0
        ftri[fi, 0, 2] = x1
        ftri[fi, 0, 3] = y1
        ftri[fi, 0, 4] = x2
        ftri[fi, 0, 5] = y2
        if m == 4:
            ftri[fi, 1, 0] = x0
            ftri[fi, 1, 1] = y0
            ftri[fi, 1, 2] = x2
            ftri[fi, 1, 3] = y2
            ftri[fi, 1, 4] = x3
            ftri[fi, 1, 5] = y3
        fbox[fi, 0] = xmin
        fbox[fi, 1] = xmax
        fbox[fi, 2] = ymin
        fbox[fi, 3] = ymax
        fn[fi] = m - 2


@kernel("(f8[:, ::1], i4[:, ::1], i8, i8, f8, f8, f8, b1, f8, f8[:, ::1], i1[::1], f8[:, :, ::1], f8[:, ::1])",
        error_model="numpy")
def _setup_serial(vp, faces, W, H, f, cx, cy, ortho, near, fbox, fn, ftri, fplane):
    _setup_range(0, faces.shape[0], vp, faces, W, H, f, cx, cy, ortho, near, fbox, fn, ftri, fplane)


@kernel("(f8[:, ::1], i4[:, ::1], i8, i8, f8, f8, f8, b1, f8, f8[:, ::1], i1[::1], f8[:, :, ::1], f8[:, ::1])",
        parallel=True, error_model="numpy")
def _setup_parallel(vp, faces, W, H, f, cx, cy, ortho, near, fbox, fn, ftri, fplane):
    F = faces.shape[0]
    CH = 4096
    for c in prange((F + CH - 1) // CH):
        _setup_range(c * CH, min(F, (c + 1) * CH), vp, faces, W, H, f, cx, cy, ortho, near, fbox, fn, ftri, fplane)


@kernel("(i4[:, ::1], i4[:, ::1])", error_model="numpy")
def _slot_table(slots, sat):
    """sat (H + 1, W + 1): summed-area table of slots >= 0 (sat[r, c]: listed pixels above row
    r and left of column c). Returns the number of listed pixels."""
    H, W = slots.shape
    sat[0, :] = 0
    for r in range(H):
        sat[r + 1, 0] = 0
        run = 0
        for c in range(W):
            run += 1 if slots[r, c] >= 0 else 0
            sat[r + 1, c + 1] = sat[r, c + 1] + run
    return sat[H, W]


@njit(cache=True, error_model="numpy")
def _nslots(sat, r0, r1, c0, c1):
    """Listed pixels in rows r0..r1, columns c0..c1 (inclusive, clamped to the table)."""
    H = sat.shape[0] - 1
    W = sat.shape[1] - 1
    r0 = max(r0, 0)
    c0 = max(c0, 0)
    r1 = min(r1, H - 1)
    c1 = min(c1, W - 1)
    if r0 > r1 or c0 > c1:
        return 0
    return sat[r1 + 1, c1 + 1] - sat[r0, c1 + 1] - sat[r1 + 1, c0] + sat[r0, c0]


@njit(cache=True, error_model="numpy")
def _sample_box(xmin, xmax, ymin, ymax, S, WS, HS):
    """(X0, X1, Y0, Y1): the samples (X, Y) at (X + 0.5, Y + 0.5) of the S-times scaled grid
    inside the pixel box (empty: X0 > X1 or Y0 > Y1)."""
    X0 = max(0, int(math.ceil(min(xmin * S, _LIM) - 0.5)))
    X1 = min(WS - 1, int(math.floor(max(xmax * S, -_LIM) - 0.5)))
    Y0 = max(0, int(math.ceil(min(ymin * S, _LIM) - 0.5)))
    Y1 = min(HS - 1, int(math.floor(max(ymax * S, -_LIM) - 0.5)))
    return X0, X1, Y0, Y1


@kernel("(f8[:, ::1], i1[::1], i8, i8, i8, i8, i4[:, ::1], b1[::1])", error_model="numpy")
def _plan(fbox, fn, S, WS, HS, T, sat, keep):
    """(active (ntiles,) bool, off (ntiles + 1,) int64): the tiles to draw (all for the full grid,
    sat empty; those with a listed pixel otherwise) and the offsets of each tile's records.
    keep[fi]: face fi has samples (under a listed pixel)."""
    ntx = (WS + T - 1) // T
    nty = (HS + T - 1) // T
    nt = ntx * nty
    sparse = sat.shape[0] > 0
    active = np.ones(nt, np.bool_)
    if sparse:
        Tp = T // S
        for ty in range(nty):
            for tx in range(ntx):
                active[ty * ntx + tx] = _nslots(sat, ty * Tp, ty * Tp + Tp - 1, tx * Tp, tx * Tp + Tp - 1) > 0
    off = np.zeros(nt + 1, np.int64)
    for fi in range(fn.shape[0]):
        keep[fi] = False
        n = fn[fi]
        if n == 0:
            continue
        X0, X1, Y0, Y1 = _sample_box(fbox[fi, 0], fbox[fi, 1], fbox[fi, 2], fbox[fi, 3], S, WS, HS)
        if X0 > X1 or Y0 > Y1:
            continue
        if sparse:  # any listed pixel under the box? (the box is inside the image)
            r0, r1, c0, c1 = Y0 // S, Y1 // S + 1, X0 // S, X1 // S + 1
            if sat[r1, c1] - sat[r0, c1] - sat[r1, c0] + sat[r0, c0] == 0:
                continue
        keep[fi] = True
        for ty in range(Y0 // T, Y1 // T + 1):
            for tx in range(X0 // T, X1 // T + 1):
                t = ty * ntx + tx
                if active[t]:
                    off[t + 1] += n
    for t in range(nt):
        off[t + 1] += off[t]
    return active, off


@njit(cache=True, error_model="numpy")
def _fill(fbox, fn, ftri, fplane, keep, S, WS, HS, T, active, off, rec, rid):
    """Write each kept face's triangle(s), scaled to the sample grid, and its planes into the
    records of the tiles its box touches, in face id order. Reads the per-face arrays in order."""
    ntx = (WS + T - 1) // T
    iS = 1.0 / S
    pos = off[:-1].copy()
    for fi in range(fn.shape[0]):
        if not keep[fi]:
            continue
        n = fn[fi]
        X0, X1, Y0, Y1 = _sample_box(fbox[fi, 0], fbox[fi, 1], fbox[fi, 2], fbox[fi, 3], S, WS, HS)
        for ty in range(Y0 // T, Y1 // T + 1):
            for tx in range(X0 // T, X1 // T + 1):
                t = ty * ntx + tx
                if not active[t]:
                    continue
                for k in range(n):
                    j = pos[t]
                    pos[t] = j + 1
                    for c in range(6):
                        rec[j, c] = ftri[fi, k, c] * S
                    # Planes per pixel -> per sample: gradients / S, offsets unchanged.
                    for c in range(0, 9, 3):
                        rec[j, 6 + c] = fplane[fi, c] * iS
                        rec[j, 7 + c] = fplane[fi, c + 1] * iS
                        rec[j, 8 + c] = fplane[fi, c + 2]
                    rid[j] = fi


@njit(cache=True, error_model="numpy")
def _edge(xa, ya, xb, yb, o):
    """Canonical form of the triangle edge a -> b, triangle orientation o = +-1: (x0, y0, dx,
    dy, s, tl, inv, kind). Inside: e = s * (dx * (py - y0) - dy * (px - x0)) > 0, or e == 0 on a
    top-left edge (tl). (x0, y0) is the lexicographically smaller end point, so the face on the
    other side of the edge computes bitwise the same value, with the opposite s. inv = 1 / dy;
    kind: how the edge bounds a row's span of samples: 1 from the left (px >= x0 + r inv with
    r = dx (py - y0)), 2 from the right, 3 horizontal (the whole row is in or out), 0 not used
    (dy too small to invert; the exact test alone decides)."""
    s = o
    if xa > xb or (xa == xb and ya > yb):
        xa, ya, xb, yb = xb, yb, xa, ya
        s = -o
    dx = xb - xa
    dy = yb - ya
    # Direction of the edge with the inside on its e > 0 side, y down: a top edge is horizontal
    # going right (inside below), a left edge goes up (dy < 0, inside to the right).
    ox, oy = s * dx, s * dy
    tl = oy < 0.0 or (oy == 0.0 and ox > 0.0)
    inv = 0.0
    kind = 0
    if dy == 0.0:
        kind = 3
    else:
        inv = 1.0 / dy
        if abs(inv) < 1e300:
            kind = 1 if s * dy < 0.0 else 2
        else:
            inv = 0.0
    return xa, ya, dx, dy, s, tl, inv, kind


@njit(cache=True, error_model="numpy")
def _tris(rec, j0, j1, TX0, TX1, TY0, TY1, T, Si, lslots, lsat, lrec, lkey):
    """Draw the screen triangles of records j0..j1-1 (sample coordinates), in order, into the
    tile of sample columns [TX0, TX1) and rows [TY0, TY1): every sample inside a triangle
    (top-left rule) whose key beats the tile buffer's (lkey, lrec: T * T, row-major from
    (TX0, TY0)) takes its record j. lslots (T / Si, T / Si) int32, the tile's pixels' slots,
    empty for the full grid: only samples in pixels with a slot >= 0 are drawn (lsat: their
    summed-area table, to skip triangles over none).

    Full grid: each row is narrowed to the span between the edges' crossings, widened by eps
    (far more than their rounding), then every sample of the span gets the exact edge test: the
    span only saves tests, it decides nothing."""
    for j in range(j0, j1):
        x0, y0, x1, y1, x2, y2 = rec[j, 0], rec[j, 1], rec[j, 2], rec[j, 3], rec[j, 4], rec[j, 5]
        gx, gy, g0 = rec[j, 6], rec[j, 7], rec[j, 8]
        area = (x1 - x0) * (y2 - y0) - (y1 - y0) * (x2 - x0)
        if not (area > 0.0 or area < 0.0):  # degenerate or NaN
            continue
        o = 1.0 if area > 0.0 else -1.0
        xmin = min(x0, x1, x2)
        xmax = max(x0, x1, x2)
        ymin = min(y0, y1, y2)
        ymax = max(y0, y1, y2)
        X0 = max(TX0, int(math.ceil(max(-_LIM, min(_LIM, xmin - 0.5)))))
        X1 = min(TX1 - 1, int(math.floor(max(-_LIM, min(_LIM, xmax - 0.5)))))
        Y0 = max(TY0, int(math.ceil(max(-_LIM, min(_LIM, ymin - 0.5)))))
        Y1 = min(TY1 - 1, int(math.floor(max(-_LIM, min(_LIM, ymax - 0.5)))))
        if X0 > X1 or Y0 > Y1:
            continue
        full = lslots.shape[0] == 0
        PX0 = TX0 // Si
        PY0 = TY0 // Si
        if not full:  # any listed pixel under the box (inside the tile)?
            r0, r1, c0, c1 = Y0 // Si - PY0, Y1 // Si - PY0 + 1, X0 // Si - PX0, X1 // Si - PX0 + 1
            if lsat[r1, c1] - lsat[r0, c1] - lsat[r1, c0] + lsat[r0, c0] == 0:
                continue
        ax0, ay0, adx, ady, as_, atl, ainv, ka = _edge(x1, y1, x2, y2, o)
        bx0, by0, bdx, bdy, bs, btl, binv, kb = _edge(x2, y2, x0, y0, o)
        cx0, cy0, cdx, cdy, cs, ctl, cinv, kc = _edge(x0, y0, x1, y1, o)
        if not full:
            # Listed pixels only. A pixel whose sample block is wholly inside every edge (or wholly
            # outside one) by more than the edge functions' rounding skips the exact test (it could
            # not change the answer); the others get it sample by sample.
            mag = 2.0 * (abs(xmin) + abs(xmax) + abs(ymin) + abs(ymax)) + 1.0
            ma = 1e-12 * (abs(adx) + abs(ady)) * mag
            mb = 1e-12 * (abs(bdx) + abs(bdy)) * mag
            mc = 1e-12 * (abs(cdx) + abs(cdy)) * mag
            for pr in range(Y0 // Si, Y1 // Si + 1):
                ya = max(Y0, pr * Si)
                yb = min(Y1, pr * Si + Si - 1)
                for pc in range(X0 // Si, X1 // Si + 1):
                    if lslots[pr - PY0, pc - PX0] < 0:
                        continue
                    xa = max(X0, pc * Si)
                    xb = min(X1, pc * Si + Si - 1)
                    # Edge functions over the block's samples (affine): the value at its centre plus
                    # or minus the half extents times the gradient's magnitudes (rounding: ma, mb, mc).
                    hx = 0.5 * (xb - xa)
                    hy = 0.5 * (yb - ya)
                    qx = xa + 0.5 + hx
                    qy = ya + 0.5 + hy
                    ea = as_ * (adx * (qy - ay0) - ady * (qx - ax0))
                    wa = abs(adx) * hy + abs(ady) * hx
                    if ea + wa < -ma:
                        continue  # wholly outside an edge
                    eb = bs * (bdx * (qy - by0) - bdy * (qx - bx0))
                    wb = abs(bdx) * hy + abs(bdy) * hx
                    if eb + wb < -mb:
                        continue
                    ec = cs * (cdx * (qy - cy0) - cdy * (qx - cx0))
                    wc = abs(cdx) * hy + abs(cdy) * hx
                    if ec + wc < -mc:
                        continue
                    sure = ea - wa > ma and eb - wb > mb and ec - wc > mc  # wholly inside
                    for Y in range(ya, yb + 1):
                        py = Y + 0.5
                        ra = adx * (py - ay0)
                        rb = bdx * (py - by0)
                        rc = cdx * (py - cy0)
                        kr = gy * py + g0
                        base = (Y - TY0) * T - TX0
                        for X in range(xa, xb + 1):
                            px = X + 0.5
                            # The depth test first: it rejects more samples than the edges, and
                            # is cheaper (both must pass: their order changes nothing).
                            k = gx * px + kr
                            i = base + X
                            if not (k > lkey[i]):
                                continue
                            if not sure:
                                ea = as_ * (ra - ady * (px - ax0))
                                eb = bs * (rb - bdy * (px - bx0))
                                ec = cs * (rc - cdy * (px - cx0))
                                if not ((ea > 0.0 or (ea == 0.0 and atl)) and (eb > 0.0 or (eb == 0.0 and btl))
                                        and (ec > 0.0 or (ec == 0.0 and ctl))):
                                    continue
                            lkey[i] = k
                            lrec[i] = j
            continue
        hz = ka == 3 or kb == 3 or kc == 3
        # Rounding of a crossing x0 + r inv: a few ulps of the coordinates' magnitude.
        eps = 1e-7 + 4e-12 * (abs(xmin) + abs(xmax) + 1.0)
        ninf = -np.inf
        pinf = np.inf
        flo = X0 + 0.5
        fhi = X1 + 0.5
        for Y in range(Y0, Y1 + 1):
            py = Y + 0.5
            ra = adx * (py - ay0)
            rb = bdx * (py - by0)
            rc = cdx * (py - cy0)
            if hz:  # a horizontal edge: this row is wholly inside it or wholly outside
                if ka == 3:
                    e = as_ * ra
                    if e < 0.0 or (e == 0.0 and not atl):
                        continue
                if kb == 3:
                    e = bs * rb
                    if e < 0.0 or (e == 0.0 and not btl):
                        continue
                if kc == 3:
                    e = cs * rc
                    if e < 0.0 or (e == 0.0 and not ctl):
                        continue
            ca = ax0 + ra * ainv
            cb = bx0 + rb * binv
            cc = cx0 + rc * cinv
            lo = max(flo, max(ca - eps if ka == 1 else ninf, max(cb - eps if kb == 1 else ninf,
                                                                 cc - eps if kc == 1 else ninf)))
            hi = min(fhi, min(ca + eps if ka == 2 else pinf, min(cb + eps if kb == 2 else pinf,
                                                                 cc + eps if kc == 2 else pinf)))
            if not (lo <= hi):
                continue
            Xa = int(math.ceil(lo - 0.5))
            Xb = int(math.floor(hi - 0.5))
            kr = gy * py + g0
            base = (Y - TY0) * T - TX0
            for X in range(Xa, Xb + 1):
                px = X + 0.5
                k = gx * px + kr
                i = base + X
                if not (k > lkey[i]):  # the depth test first (as above)
                    continue
                ea = as_ * (ra - ady * (px - ax0))
                eb = bs * (rb - bdy * (px - bx0))
                ec = cs * (rc - cdy * (px - cx0))
                if ((ea > 0.0 or (ea == 0.0 and atl)) and (eb > 0.0 or (eb == 0.0 and btl))
                        and (ec > 0.0 or (ec == 0.0 and ctl))):
                    lkey[i] = k
                    lrec[i] = j


@njit(cache=True, error_model="numpy")
def _resolve(gx, gy, g0, ux, uy, u0, vx, vy, v0, px, py, ortho):
    """(z, u, v) of a face with planes (key, U, V) at sample coordinates (px, py): view depth and
    open3d barycentrics where the sample's ray meets the face's (unclipped) plane."""
    w = gx * px + gy * py + g0
    U = ux * px + uy * py + u0
    V = vx * px + vy * py + v0
    if ortho:
        return -w, U, V
    z = 1.0 / w
    return z, U * z, V * z

@njit(cache=True, error_model="numpy")
def _store(j, i, px, py, rec, rid, ortho, face, depth, bary):
    """Write sample i of the output from the tile's winning record j (-1: background) at sample
    coordinates (px, py): its face, view depth and barycentrics."""
    if j < 0:
        face[i] = -1
        depth[i] = np.inf
        bary[i, 0] = 0.0
        bary[i, 1] = 0.0
    else:
        face[i] = rid[j]
        z, u, v = _resolve(rec[j, 6], rec[j, 7], rec[j, 8], rec[j, 9], rec[j, 10], rec[j, 11], rec[j, 12],
                           rec[j, 13], rec[j, 14], px, py, ortho)
        depth[i] = z
        bary[i, 0] = u
        bary[i, 1] = v



@njit(cache=True, error_model="numpy")
def _do_tile(t, ntx, T, Si, WS, HS, ortho, slots, off, rec, rid, lrec, lkey, face, depth, bary):
    """Draw tile t's records into the local buffers (lrec: winning record, lkey: its key), then
    write its samples' face, depth and barycentrics out (grid: row-major (HS, WS); pixels:
    (P, S * S) by slot)."""
    ty = t // ntx
    TX0 = (t - ty * ntx) * T
    TY0 = ty * T
    TX1 = min(WS, TX0 + T)
    TY1 = min(HS, TY0 + T)
    if slots.shape[0] == 0:
        lrec[:] = -1
        lkey[:] = -np.inf
        lslots = slots
        lsat = slots
    else:  # the tile's slots and their summed-area table, in cache
        Tp = T // Si
        lslots = np.full((Tp, Tp), -1, np.int32)
        lslots[:(TY1 - TY0) // Si, :(TX1 - TX0) // Si] = slots[TY0 // Si:TY1 // Si, TX0 // Si:TX1 // Si]
        lsat = np.empty((Tp + 1, Tp + 1), np.int32)
        _slot_table(lslots, lsat)
        # Only the listed pixels' samples are drawn and read: only they are cleared.
        for pr in range(Tp):
            for pc in range(Tp):
                if lslots[pr, pc] >= 0:
                    for sy in range(pr * Si, pr * Si + Si):
                        b = sy * T + pc * Si
                        for sx in range(Si):
                            lrec[b + sx] = -1
                            lkey[b + sx] = -np.inf
    _tris(rec, off[t], off[t + 1], TX0, TX1, TY0, TY1, T, Si, lslots, lsat, lrec, lkey)
    if slots.shape[0] == 0:
        for Y in range(TY0, TY1):
            lb = (Y - TY0) * T - TX0
            gb = Y * WS
            py = Y + 0.5
            for X in range(TX0, TX1):
                _store(lrec[lb + X], gb + X, X + 0.5, py, rec, rid, ortho, face, depth, bary)
        return
    SS = Si * Si
    for pr in range(TY0 // Si, TY1 // Si):
        for pc in range(TX0 // Si, TX1 // Si):
            slot = slots[pr, pc]
            if slot < 0:
                continue
            for sub in range(SS):
                Y = pr * Si + sub // Si
                X = pc * Si + sub % Si
                _store(lrec[(Y - TY0) * T + X - TX0], slot * SS + sub, X + 0.5, Y + 0.5, rec, rid, ortho, face, depth,
                       bary)


@kernel(("(f8[:, ::1], i1[::1], f8[:, :, ::1], f8[:, ::1], b1[::1], i8, i8, i8, i8, b1, i4[:, ::1], b1[::1], "
        "i8[::1], f8[:, ::1], i4[::1], i4[::1], f4[::1], f4[:, ::1])"), error_model="numpy")
def _draw_serial(fbox, fn, ftri, fplane, keep, S, WS, HS, T, ortho, slots, active, off, rec, rid, face, depth,
                 bary):
    _fill(fbox, fn, ftri, fplane, keep, S, WS, HS, T, active, off, rec, rid)
    ntx = (WS + T - 1) // T
    lrec = np.empty(T * T, np.int32)
    lkey = np.empty(T * T, np.float64)
    for t in range(active.shape[0]):
        if active[t]:
            _do_tile(t, ntx, T, S, WS, HS, ortho, slots, off, rec, rid, lrec, lkey, face, depth, bary)


@kernel(("(f8[:, ::1], i1[::1], f8[:, :, ::1], f8[:, ::1], b1[::1], i8, i8, i8, i8, b1, i4[:, ::1], b1[::1], "
        "i8[::1], f8[:, ::1], i4[::1], i4[::1], f4[::1], f4[:, ::1])"), parallel=True, error_model="numpy")
def _draw_parallel(fbox, fn, ftri, fplane, keep, S, WS, HS, T, ortho, slots, active, off, rec, rid, face, depth,
                   bary):
    _fill(fbox, fn, ftri, fplane, keep, S, WS, HS, T, active, off, rec, rid)
    ntx = (WS + T - 1) // T
    ids = np.flatnonzero(active)
    n = ids.shape[0]
    # The drawn tiles dealt out in turn to G groups (one local buffer a group): a thread's share
    # of them spreads over the whole image, not one band of it (the scene's tiles cost more).
    # A tile's result does not depend on its thread.
    G = 64
    for g in prange(G):
        lrec = np.empty(T * T, np.int32)
        lkey = np.empty(T * T, np.float64)
        for q in range(g, n, G):
            _do_tile(ids[q], ntx, T, S, WS, HS, ortho, slots, off, rec, rid, lrec, lkey, face, depth, bary)
