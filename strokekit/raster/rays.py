"""The ray-cast raster samples: one Embree ray per sample, the reference the z-buffer
(`raster.hits`, `raster.zbuffer`) is held against in tests and `strokekit bench`
(`render_raster(..., reference=True)`), and the surface depth under the ribbons.

Rays go through pixel centres (BRIEF 1.1) of the output image refined `supersample` times: the
sample (i, j) of a K-times supersampled image sits at output pixel coordinates
((i + 0.5) / K, (j + 0.5) / K). The rays are cast against the `Occluder` the line pass already
built, so masks and lines share one BVH and one notion of "seen".

Perspective rays start on the near plane and have a direction whose component along the view
axis is 1, so the hit distance along the ray is directly the view depth z (BRIEF 1.1).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from strokekit.camera.view import Camera
from strokekit.errors import UsageError
from strokekit.scene.occluder import Occluder

SUPERSAMPLES = (1, 2, 4, 8)


@dataclass(frozen=True, eq=False)
class RasterHits:
    """Per-sample first hits of one frame at the supersampled resolution (H*K, W*K).

    face (HK, WK) int32: hit triangle, -1 for background;
    bary (HK, WK, 2) float32: open3d barycentrics (u, v) of the hit, P = (1-u-v) A + u B + v C;
    depth (HK, WK) float32: view depth z in world units (inf for background);
    position (HK, WK, 3) float64 (computed on first use): world hit point (NaN for background).
    `supersample` K; `width`, `height` are the output (not supersampled) size in pixels."""

    face: np.ndarray
    bary: np.ndarray
    depth: np.ndarray
    camera: Camera
    supersample: int
    # Per column / row offsets of the sample rays along camera right / up': perspective ray
    # direction fwd + x right + y up (x, y per unit depth); orthographic ray origin eye + x right
    # + y up (world units) with direction fwd.
    ray_dir_x: np.ndarray  # (WK,)
    ray_dir_y: np.ndarray  # (HK,)

    @property
    def width(self) -> int:
        return int(self.camera.width)

    @property
    def height(self) -> int:
        return int(self.camera.height)

    @property
    def shape(self) -> tuple[int, int]:
        """(HK, WK) supersampled shape."""
        return self.face.shape

    @cached_property
    def hit(self) -> np.ndarray:
        """(HK, WK) bool: a triangle was hit."""
        return self.face >= 0

    @cached_property
    def position(self) -> np.ndarray:
        """(HK, WK, 3) world hit points, NaN on background. Rebuilt from the ray and the depth in
        float64 (the BVH itself is float32 in scene-centred coordinates)."""
        right, up, fwd = self.camera.basis
        z = np.where(self.hit, self.depth.astype(np.float64), np.nan)
        xr = self.ray_dir_x[None, :]
        yu = self.ray_dir_y[:, None]
        if self.camera.is_ortho:
            # Origin moves across the image plane, direction is fwd (oblique: sheared).
            a = np.broadcast_to(xr, z.shape)
            b = np.broadcast_to(yu, z.shape)
            c = z
            if self.camera.is_oblique:
                kx, ky = self.camera.shear
                a, b = a - kx * z, b - ky * z
        else:
            # Direction (fwd + x right + y up) scaled by z.
            a, b, c = xr * z, yu * z, z
        eye = np.asarray(self.camera.eye, float)
        return (eye + a[..., None] * right + b[..., None] * up + c[..., None] * fwd)


def cast_pixels(camera: Camera, occluder: Occluder, supersample: int = 1) -> RasterHits:
    """Cast one ray per supersampled pixel centre and return the first hits.

    camera: output size W x H pixels; supersample K in SUPERSAMPLES; cost grows with W*H*K^2."""
    K = int(supersample)
    if K not in SUPERSAMPLES:
        raise ValueError(f"supersample must be one of {SUPERSAMPLES}, got {supersample}")
    W, H = int(camera.width), int(camera.height)
    WK, HK = W * K, H * K
    f = camera.focal_px
    # Offsets of each sample centre from the image centre, in output pixels, then in camera units.
    px = (np.arange(WK) + 0.5) / K - W / 2.0
    py = H / 2.0 - (np.arange(HK) + 0.5) / K
    ax, ay = px / f, py / f
    near = camera.near_distance(occluder.radius)
    # Only samples in blocks that some triangle's screen bounding box touches can hit anything;
    # the others are background without a ray (the cost is in the rays).
    sel = _candidate_samples(camera, occluder.scene, K, near)
    face = np.full(HK * WK, -1, np.int32)
    bary = np.zeros((HK * WK, 2), np.float32)
    depth = np.full(HK * WK, np.inf, np.float32)
    if len(sel):
        rows, cols = np.divmod(sel, WK)
        hits = cast_samples(camera, occluder, ax[cols], ay[rows])
        face[sel], bary[sel], depth[sel] = hits["face"], hits["bary"], hits["depth"]
    return RasterHits(face=face.reshape(HK, WK), bary=bary.reshape(HK, WK, 2), depth=depth.reshape(HK, WK),
                      camera=camera, supersample=K, ray_dir_x=ax, ray_dir_y=ay)


def cast_samples(camera: Camera, occluder: Occluder, ax: np.ndarray, ay: np.ndarray) -> dict:
    """First hits of rays through arbitrary image points given by their camera-plane offsets
    ax, ay (M,) (ax = (x - W/2) / f, ay = (H/2 - y) / f for pixel coordinates x, y).
    Rays start on the near plane (Camera.near_distance), orthographic ones too: what lies before it
    is clipped out of the lines (a section view), so the raster pass does not show it either.

    Returns {'face' (M,) int32 (-1: none), 'bary' (M, 2) float32, 'depth' (M,) float32 view z
    (inf: none)}."""
    right, up, fwd = camera.basis
    eye = np.asarray(camera.eye, float)
    near = camera.near_distance(occluder.radius)
    # Rays in the occluder's centred, unit-radius float32 frame, one component at a time: no
    # (N, 3) float64 temporaries (they cost as much as the BVH traversal at 1024 x 1024). Origin
    # and direction are both scaled, so t_hit keeps its units (view depth for perspective).
    rays = np.empty((len(ax), 6), np.float32)
    k = occluder.inv_scale
    base = ((eye - occluder.origin) * k).astype(np.float32)
    right, up, fwd = right * k, up * k, fwd * k
    axc, ayr = np.asarray(ax, np.float32), np.asarray(ay, np.float32)
    if camera.is_oblique:
        # The rays run along the projection direction (fwd - kx right - ky up, unit component
        # along fwd: t_hit is still the view depth past the near plane); the ray of image point
        # (ax, ay) crosses the near plane at (ax - kx near, ay - ky near) in the plane.
        kx, ky = camera.shear
        d = camera.ray_dir * k
        o = base.astype(float) + (np.asarray(ax, float) - kx * near)[:, None] * right \
            + (np.asarray(ay, float) - ky * near)[:, None] * up + near * fwd
        rays[:, :3] = o
        rays[:, 3:] = d
        hits = occluder.cast_rays(rays)
        fw = hits["primitive_ids"]
        depth = np.where(fw >= 0, hits["t_hit"] + np.float32(near), np.float32(np.inf)).astype(np.float32)
        return {"face": fw, "bary": hits["primitive_uvs"], "depth": depth}
    for c in range(3):
        if camera.is_ortho:
            # Orthographic: ax, ay are world offsets; t_hit is in units of |fwd| = 1 world unit.
            rays[:, c] = base[c] + ayr * np.float32(up[c]) + axc * np.float32(right[c]) + np.float32(near * fwd[c])
            rays[:, 3 + c] = fwd[c]
        else:
            # Perspective: d = fwd + x right + y up has unit component along fwd, so the hit
            # distance is the view depth; the ray starts on the near plane.
            rays[:, 3 + c] = np.float32(fwd[c]) + ayr * np.float32(up[c]) + axc * np.float32(right[c])
            rays[:, c] = base[c] + np.float32(near) * rays[:, 3 + c]
    hits = occluder.cast_rays(rays)
    fw = hits["primitive_ids"]
    depth = np.where(fw >= 0, hits["t_hit"] + np.float32(near), np.float32(np.inf)).astype(np.float32)
    return {"face": fw, "bary": hits["primitive_uvs"], "depth": depth}


def surface_depth_at(occluder: Occluder):
    """f(camera, pixels (V, 2) px) -> (V,) float64 view depth of the first surface seen at those
    image points (inf where none), for ribbons.build_ribbons."""
    def depth(camera: Camera, pixels: np.ndarray) -> np.ndarray:
        f = camera.focal_px
        ax = (pixels[:, 0] - camera.width / 2.0) / f
        ay = (camera.height / 2.0 - pixels[:, 1]) / f
        return cast_samples(camera, occluder, ax, ay)["depth"].astype(float)
    return depth


#: Side, in samples, of the blocks used to skip rays that cannot hit.
BLOCK = 8


def _candidate_samples(camera: Camera, scene, K: int, near: float) -> np.ndarray:
    """Flat indices (row-major, supersampled image) of the samples whose ray may hit a triangle:
    those in BLOCK x BLOCK blocks touched by the screen bounding box of some triangle, grown by
    one sample for float32 slack. Conservative: every sample when a triangle crosses the near
    plane (its projection is unbounded)."""
    W, H = int(camera.width) * K, int(camera.height) * K
    xy, z = camera.project(scene.vertices)
    f = scene.faces
    if not camera.is_ortho:
        zf = z[f]
        front = zf.min(axis=1) > near
        if (~front & (zf.max(axis=1) > near)).any():
            return np.arange(W * H)
        f = f[front]
    x = xy[:, 0][f] * K
    y = xy[:, 1][f] * K
    nbx, nby = -(-W // BLOCK), -(-H // BLOCK)
    bx0 = np.floor((x.min(axis=1) - 1.0) / BLOCK)
    bx1 = np.floor((x.max(axis=1) + 1.0) / BLOCK)
    by0 = np.floor((y.min(axis=1) - 1.0) / BLOCK)
    by1 = np.floor((y.max(axis=1) + 1.0) / BLOCK)
    on = (bx1 >= 0) & (bx0 < nbx) & (by1 >= 0) & (by0 < nby)
    bx0, by0 = np.clip(bx0[on], 0, nbx - 1).astype(np.int64), np.clip(by0[on], 0, nby - 1).astype(np.int64)
    bx1, by1 = np.clip(bx1[on], 0, nbx - 1).astype(np.int64) + 1, np.clip(by1[on], 0, nby - 1).astype(np.int64) + 1
    # Rectangles by a 2D difference array: +1/-1 at the corners, then prefix sums.
    stride = nbx + 1
    corners = np.concatenate([by0 * stride + bx0, by0 * stride + bx1, by1 * stride + bx0, by1 * stride + bx1])
    weights = np.concatenate([np.ones(len(bx0)), -np.ones(len(bx0)), -np.ones(len(bx0)), np.ones(len(bx0))])
    diff = np.bincount(corners, weights, minlength=(nby + 1) * stride).reshape(nby + 1, stride)
    blocks = diff.cumsum(axis=0).cumsum(axis=1)[:nby, :nbx] > 0.5
    mask = np.repeat(np.repeat(blocks, BLOCK, axis=0), BLOCK, axis=1)[:H, :W]
    return np.flatnonzero(mask)


# --- the raster pass's memory estimate ------------------------------------------------------------

def raster_memory_bytes(width: int, height: int, supersample: int, fill: bool = False) -> int:
    """About the peak memory (bytes) of one frame's raster pass (the z-buffer's, bands.render_raster
    and the PNGs) at width x height px and supersample K: per output pixel ~60 bytes (images, PNG
    rows, the edge pixels' samples) plus ~35 per sample (face, depth, barycentrics, label, key),
    and ~150 more with the fill (its float64 fields). Measured with tracemalloc on spot and the
    bunny at 512 and 1024 px, masks, ids and depth on: 38-72 bytes per pixel at K = 1 with the
    edge pixels resampled 4 x 4 (150 on the bunny at 512 px, where the scene's own tables weigh),
    103-123 at K = 2 (+ edge 4 x 4), 531-550 at K = 4; the fill adds 70-120 at 1024 px."""
    return int(width) * int(height) * (60 + 35 * int(supersample) ** 2 + (150 if fill else 0))


def check_raster_fits(width: int, height: int, supersample: int, fill: bool = False) -> None:
    """UsageError when one frame's raster pass would need more memory than the machine has (a
    --size of 100000x100000 with --bands failed at frame time with a 37 GiB MemoryError)."""

    try:
        total = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, ValueError, OSError):
        return  # not known here (not POSIX): the frame will say
    need = raster_memory_bytes(width, height, supersample, fill)
    if need > total:
        raise UsageError(f"the raster pass at {width}x{height} px, supersample {supersample}, needs about "
                         f"{need / 2**30:.0f} GiB per frame; this machine has {total / 2**30:.0f} GiB "
                         "(a smaller --size or --supersample)")
