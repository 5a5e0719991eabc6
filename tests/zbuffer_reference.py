"""Helpers of tests/test_zbuffer.py (from the z-buffer's standalone development, issue 17):
strokekit-like views and the open3d ray-cast reference.

`o3d_cast` reproduces strokekit's raster.cast_samples (the current ray-cast raster pass): rays in
the scene's centred, unit-radius float32 frame, starting on the near plane, perspective
directions with unit component along the view axis; depth = t_hit + near (view depth z).
"""

from __future__ import annotations

import math

import numpy as np

from strokekit.raster.zbuffer import View


def look_at(eye, target, up=(0.0, 1.0, 0.0), fov_y=40.0, width=1024, height=1024, ortho=False,
            ortho_height=1.0, near=1e-4) -> View:
    """A View as strokekit's Camera builds it (Camera.basis, Camera.focal_px)."""
    eye = np.asarray(eye, float)
    fwd = np.subtract(target, eye)
    fwd = fwd / np.linalg.norm(fwd)
    r = np.cross(fwd, up)
    right = r / np.linalg.norm(r)
    upp = np.cross(right, fwd)
    f = height / ortho_height if ortho else (height / 2.0) / math.tan(math.radians(fov_y) / 2.0)
    return View(eye=eye, right=right, up=upp, fwd=fwd, focal_px=f, width=width, height=height, ortho=ortho,
                near=float(near))


def bounds_sphere(vertices):
    """(center, radius) as strokekit's Scene: bounding-box centre, farthest vertex."""
    v = np.asarray(vertices, float)
    c = (v.min(axis=0) + v.max(axis=0)) / 2.0
    return c, float(np.linalg.norm(v - c, axis=1).max())


class O3DReference:
    """open3d RaycastingScene of a mesh in the centred unit-radius float32 frame (as strokekit's
    Occluder)."""

    def __init__(self, vertices, faces):
        import open3d as o3d

        self.o3c = o3d.core
        self.center, self.radius = bounds_sphere(vertices)
        self.k = 1.0 / self.radius
        local = ((np.asarray(vertices, float) - self.center) * self.k).astype(np.float32)
        self.rs = o3d.t.geometry.RaycastingScene()
        self.rs.add_triangles(o3d.core.Tensor(local), o3d.core.Tensor(np.asarray(faces).astype(np.uint32)))

    def rays(self, view: View, x_px, y_px) -> np.ndarray:
        """(M, 6) float32 rays through output pixel coordinates, as cast_samples builds them."""
        f = view.focal_px
        ax = ((np.asarray(x_px, float) - view.width / 2.0) / f).astype(np.float32)
        ay = ((view.height / 2.0 - np.asarray(y_px, float)) / f).astype(np.float32)
        k = self.k
        base = ((view.eye - self.center) * k).astype(np.float32)
        right, up, fwd = view.right * k, view.up * k, view.fwd * k
        near = view.near
        rays = np.empty((len(ax), 6), np.float32)
        for c in range(3):
            if view.ortho:
                rays[:, c] = base[c] + ay * np.float32(up[c]) + ax * np.float32(right[c]) + np.float32(near * fwd[c])
                rays[:, 3 + c] = fwd[c]
            else:
                rays[:, 3 + c] = np.float32(fwd[c]) + ay * np.float32(up[c]) + ax * np.float32(right[c])
                rays[:, c] = base[c] + np.float32(near) * rays[:, 3 + c]
        return rays

    def cast_rays(self, rays: np.ndarray, near: float) -> dict:
        r = self.rs.cast_rays(self.o3c.Tensor.from_numpy(np.ascontiguousarray(rays)))
        face = r["primitive_ids"].numpy().view(np.int32)
        depth = np.where(face >= 0, r["t_hit"].numpy() + np.float32(near), np.float32(np.inf)).astype(np.float32)
        return {"face": face, "bary": r["primitive_uvs"].numpy(), "depth": depth}

    def cast(self, view: View, x_px, y_px) -> dict:
        """{'face' (M,) int32, 'bary' (M, 2) float32, 'depth' (M,) float32} at output pixel
        coordinates (M,), (M,)."""
        return self.cast_rays(self.rays(view, x_px, y_px), view.near)


def grid_positions(view: View, K: int):
    """Pixel coordinates (HK*WK,) of the K x K grid samples, row-major (cast_pixels' samples)."""
    xs = (np.arange(view.width * K) + 0.5) / K
    ys = (np.arange(view.height * K) + 0.5) / K
    X, Y = np.meshgrid(xs, ys)
    return X.ravel(), Y.ravel()


def pixel_positions(view: View, pixels, R: int):
    """Pixel coordinates (P*R*R,) of R x R samples in each listed pixel (bands._edge_coverage's)."""
    py, px = np.divmod(np.asarray(pixels), view.width)
    sub = (np.arange(R) + 0.5) / R
    x = (px[:, None] + np.tile(sub, R)[None, :]).ravel()
    y = (py[:, None] + np.repeat(sub, R)[None, :]).ravel()
    return x, y


def exact_hits(vertices, faces, view: View, face_ids, x_px, y_px):
    """float64 (depth z, u, v, distance in px to the nearest edge of the face's visible part,
    near plane included) of the given faces at the given pixel positions (the ray against the
    face's plane); rows with face -1 give NaN. For telling samples near an edge."""
    fi = np.asarray(face_ids)
    ok = fi >= 0
    out = np.full((4, len(fi)), np.nan)
    if not ok.any():
        return out
    basis = np.stack([view.right, view.up, view.fwd], axis=1)
    cam = (np.asarray(vertices, float) - view.eye) @ basis
    tri = cam[np.asarray(faces)[fi[ok]]]  # (M, 3, 3)
    A, B, C = tri[:, 0], tri[:, 1], tri[:, 2]
    f = view.focal_px

    def at(x, y):
        sx = (x - view.width / 2.0) / f
        sy = (view.height / 2.0 - y) / f
        if view.ortho:
            o = np.stack([sx, sy, np.zeros_like(sx)], axis=1)
            d = np.broadcast_to([0.0, 0.0, 1.0], o.shape)
        else:
            o = np.zeros((len(sx), 3))
            d = np.stack([sx, sy, np.ones_like(sx)], axis=1)
        e1, e2 = B - A, C - A
        p = np.cross(d, e2)
        det = np.einsum("ij,ij->i", e1, p)
        t = o - A
        u = np.einsum("ij,ij->i", t, p) / det
        q = np.cross(t, e1)
        v = np.einsum("ij,ij->i", d, q) / det
        tt = np.einsum("ij,ij->i", e2, q) / det
        z = o[:, 2] + tt * d[:, 2]
        return z, u, v

    x, y = np.asarray(x_px, float)[ok], np.asarray(y_px, float)[ok]
    z, u, v = at(x, y)
    h = 1e-3
    zx, ux, vx = at(x + h, y)
    zy, uy, vy = at(x, y + h)
    dist = np.full(len(x), np.inf)
    for val, gx, gy in ((u, (ux - u) / h, (uy - u) / h), (v, (vx - v) / h, (vy - v) / h),
                        (1 - u - v, (v + u - ux - vx) / h, (v + u - uy - vy) / h),
                        (z - view.near, (zx - z) / h, (zy - z) / h)):
        g = np.hypot(gx, gy)
        with np.errstate(divide="ignore", invalid="ignore"):
            dist = np.minimum(dist, np.where(g > 0, np.abs(val) / g, np.inf))
    out[0, ok], out[1, ok], out[2, ok], out[3, ok] = z, u, v, dist
    return out


