"""A small raster pass with the same visibility as the lines: one Embree ray per pixel.

Rays go through pixel centres (BRIEF 1.1) of the output image refined `supersample` times: the
sample (i, j) of a K-times supersampled image sits at output pixel coordinates
((i + 0.5) / K, (j + 0.5) / K). The rays are cast against the `Occluder` the line pass already
built, so masks and lines share one BVH and one notion of "seen".

Perspective rays start on the near plane and have a direction whose component along the view
axis is 1, so the hit distance along the ray is directly the view depth z (BRIEF 1.1).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from .camera import Camera
from .visibility import Occluder

SUPERSAMPLES = (1, 2, 4, 8)


@dataclass(frozen=True, eq=False)
class RasterHits:
    """Per-sample first hits of one frame at the supersampled resolution (H*K, W*K).

    face (HK, WK) int64: hit triangle, -1 for background;
    bary (HK, WK, 2) float32: open3d barycentrics (u, v) of the hit, P = (1-u-v) A + u B + v C;
    depth (HK, WK) float64: view depth z in world units (inf for background);
    position (HK, WK, 3) float64 (computed on first use): world hit point (NaN for background).
    `supersample` K; `width`, `height` are the output (not supersampled) size in pixels."""

    face: np.ndarray
    bary: np.ndarray
    depth: np.ndarray
    camera: Camera
    supersample: int
    ray_origin: np.ndarray  # (3,) world, perspective eye-side origin (ortho: image-centre origin)
    ray_dir_x: np.ndarray  # (WK,) per-column offset along camera right (world units per unit z, or world units)
    ray_dir_y: np.ndarray  # (HK,) per-row offset along camera up'

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
        z = np.where(self.hit, self.depth, np.nan)
        xr = self.ray_dir_x[None, :]
        yu = self.ray_dir_y[:, None]
        if self.camera.is_ortho:
            # Origin moves across the image plane, direction is fwd.
            a = np.broadcast_to(xr, z.shape)
            b = np.broadcast_to(yu, z.shape)
            c = z
        else:
            # Direction (fwd + x right + y up) scaled by z.
            a, b, c = xr * z, yu * z, z
        eye = np.asarray(self.camera.eye, float)
        return (eye + a[..., None] * right + b[..., None] * up + c[..., None] * fwd)

    def view_dirs(self) -> np.ndarray:
        """(HK, WK, 3) unit world directions from the camera into the scene per sample."""
        right, up, fwd = self.camera.basis
        if self.camera.is_ortho:
            return np.broadcast_to(fwd, self.shape + (3,))
        d = fwd + self.ray_dir_x[None, :, None] * right + self.ray_dir_y[:, None, None] * up
        return d / np.linalg.norm(d, axis=-1, keepdims=True)


def cast_pixels(camera: Camera, occluder: Occluder, supersample: int = 1) -> RasterHits:
    """Cast one ray per supersampled pixel centre and return the first hits.

    camera: output size W x H pixels; supersample K in SUPERSAMPLES; cost grows with W*H*K^2."""
    K = int(supersample)
    if K not in SUPERSAMPLES:
        raise ValueError(f"supersample must be one of {SUPERSAMPLES}, got {supersample}")
    W, H = int(camera.width), int(camera.height)
    WK, HK = W * K, H * K
    right, up, fwd = camera.basis
    f = camera.focal_px
    # Offsets of each sample centre from the image centre, in output pixels, then in camera units.
    px = (np.arange(WK) + 0.5) / K - W / 2.0
    py = H / 2.0 - (np.arange(HK) + 0.5) / K
    ax, ay = px / f, py / f
    eye = np.asarray(camera.eye, float)
    near = 0.0 if camera.is_ortho else camera.near_distance(occluder.radius)
    # Only the samples inside the scene's projected bounding box can hit anything: the others
    # are background without a ray (the cost is in the rays).
    c0, c1, r0, r1 = _scene_window(camera, occluder, K, near)
    face = np.full((HK, WK), -1, np.int64)
    bary = np.zeros((HK, WK, 2), np.float32)
    depth = np.full((HK, WK), np.inf)
    if c1 > c0 and r1 > r0:
        h, w = r1 - r0, c1 - c0
        # Rays in the occluder's centred float32 frame, one component at a time: no (N, 3)
        # float64 temporaries (they cost as much as the BVH traversal at 1024 x 1024).
        rays = np.empty((h, w, 6), np.float32)
        base = eye - occluder.origin
        for c in range(3):
            if camera.is_ortho:
                rays[..., c] = (base[c] + ay[r0:r1] * up[c])[:, None] + (ax[c0:c1] * right[c])[None, :]
                rays[..., 3 + c] = fwd[c]
            else:
                # Perspective: d = fwd + x right + y up has unit component along fwd, so the hit
                # distance is the view depth; the ray starts on the near plane.
                rays[..., 3 + c] = (fwd[c] + ay[r0:r1] * up[c])[:, None] + (ax[c0:c1] * right[c])[None, :]
                rays[..., c] = base[c] + near * rays[..., 3 + c]
        hits = _cast(occluder, rays.reshape(-1, 6))
        fw = hits["primitive_ids"].reshape(h, w)
        face[r0:r1, c0:c1] = fw
        bary[r0:r1, c0:c1] = hits["primitive_uvs"].reshape(h, w, 2)
        depth[r0:r1, c0:c1] = np.where(fw >= 0, hits["t_hit"].reshape(h, w).astype(np.float64) + near, np.inf)
    return RasterHits(face=face, bary=bary, depth=depth, camera=camera,
                      supersample=K, ray_origin=eye, ray_dir_x=ax, ray_dir_y=ay)


def _scene_window(camera: Camera, occluder: Occluder, K: int, near: float) -> tuple[int, int, int, int]:
    """(col0, col1, row0, row1) half-open window of supersampled samples that can see the scene:
    the projection of the scene's bounding box grown by one sample; the whole image when a box
    corner is behind the near plane (its projection is then unbounded)."""
    W, H = int(camera.width) * K, int(camera.height) * K
    lo, hi = occluder.scene.bounds
    pad = 1e-6 * occluder.radius  # float32 BVH slack
    corners = np.array([[x, y, z] for x in (lo[0] - pad, hi[0] + pad) for y in (lo[1] - pad, hi[1] + pad)
                        for z in (lo[2] - pad, hi[2] + pad)])
    xy, z = camera.project(corners)
    if not camera.is_ortho and (z <= near).any():
        return 0, W, 0, H
    x0, y0 = np.floor(xy.min(axis=0) * K).astype(int) - 1
    x1, y1 = np.ceil(xy.max(axis=0) * K).astype(int) + 1
    return max(x0, 0), min(x1, W), max(y0, 0), min(y1, H)


def _cast(occluder: Occluder, rays_local: np.ndarray) -> dict:
    """First hits of (N, 6) float32 rays given in the occluder's centred frame.

    Occluder.first_hits takes world origins; passing them through it would cost two (N, 3)
    float64 temporaries per frame, so the centred rays go to the same RaycastingScene here."""
    rs = getattr(occluder, "_rs", None)
    if rs is None:
        o = rays_local[:, :3].astype(np.float64) + occluder.origin
        return occluder.first_hits(o, rays_local[:, 3:].astype(np.float64))
    r = rs.cast_rays(occluder._o3c.Tensor.from_numpy(np.ascontiguousarray(rays_local)))
    ids = r["primitive_ids"].numpy().astype(np.int64)
    ids[ids == np.iinfo(np.uint32).max] = -1
    return {"t_hit": r["t_hit"].numpy(), "primitive_ids": ids, "primitive_uvs": r["primitive_uvs"].numpy()}


def box_filter(img: np.ndarray, k: int) -> np.ndarray:
    """Mean over k x k blocks: (H*k, W*k, ...) -> (H, W, ...) float64."""
    if k == 1:
        return img.astype(np.float64)
    HK, WK = img.shape[:2]
    return img.reshape(HK // k, k, WK // k, k, *img.shape[2:]).mean(axis=(1, 3))
