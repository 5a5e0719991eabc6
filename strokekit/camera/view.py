"""A frame's view (`Camera`: eye, target, up, lens, image size; perspective or orthographic)
and a sequence of them (`CameraPath`). Image space: x to the right, y down, origin at the
top-left corner, in pixels (BRIEF 1.1)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from strokekit.errors import InputError

_FALLBACK_UPS = (np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]))
# Limits of what a camera file (JSON or glTF) may ask for: beyond them a run would fail late (a
# width of 1e30 px overflows the writers) or never end (a frame_count of 1e12).
MAX_IMAGE_PX = 100_000  # per side
#: `up` counts as parallel to the view direction when |fwd x up| <= this x |up| (fwd a unit
#: vector): Camera.basis then picks a fallback up, and a camera file refuses it.
UP_PARALLEL_TOL = 1e-6


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v)
    return v / n


@dataclass(frozen=True)
class Camera:
    """One frame's camera. Lengths in world units, fov in degrees, image size in pixels."""

    eye: tuple[float, float, float]
    target: tuple[float, float, float]
    up: tuple[float, float, float] = (0.0, 1.0, 0.0)
    fov_y: float = 40.0
    width: int = 1024
    height: int = 1024
    projection: str = "perspective"  # or "orthographic"
    ortho_height: float = 1.0
    near: float | None = None  # world units; None: a small fraction of the eye-target distance

    def __post_init__(self):
        for name in ("eye", "target", "up"):
            v = np.asarray(getattr(self, name), dtype=float)
            if v.shape != (3,) or not np.all(np.isfinite(v)):
                raise InputError(f"camera {name} must be 3 finite numbers, got {_show(getattr(self, name))}")
            object.__setattr__(self, name, tuple(float(x) for x in v))
        if self.projection not in ("perspective", "orthographic"):
            raise InputError(f"camera projection must be 'perspective' or 'orthographic', got {self.projection!r}")
        if self.projection == "perspective" and not (0.0 < float(self.fov_y) < 180.0):
            raise InputError(f"camera fov_y must be in (0, 180) degrees, got {self.fov_y!r}")
        if self.projection == "orthographic" and not (math.isfinite(self.ortho_height) and self.ortho_height > 0):
            raise InputError(f"camera ortho_height must be > 0, got {self.ortho_height!r}")
        if self.near is not None and not (math.isfinite(self.near) and self.near > 0):
            raise InputError(f"camera near must be a distance > 0, got {self.near!r}")
        if int(self.width) <= 0 or int(self.height) <= 0:
            raise InputError(f"image size must be positive, got {self.width} x {self.height}")
        if np.linalg.norm(np.subtract(self.target, self.eye)) == 0.0:
            raise InputError("camera target equals eye: the view direction has zero length")

    # --- frame -------------------------------------------------------------------------------
    @cached_property  # frozen: computed once per camera (the tracker asks for it often)
    def basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(right, up', fwd) unit vectors, float64. A stable fallback up is used when up is
        (nearly) parallel to the view direction."""
        fwd = _unit(np.subtract(self.target, self.eye))
        candidates = [np.asarray(self.up, float)] + list(_FALLBACK_UPS)
        for up in candidates:
            r = np.cross(fwd, up)
            nr = np.linalg.norm(r)
            if np.linalg.norm(up) > 0 and nr > UP_PARALLEL_TOL * np.linalg.norm(up):
                right = r / nr
                return right, np.cross(right, fwd), fwd
        raise AssertionError("unreachable: one fallback up is never parallel")

    @property
    def up_along_view(self) -> bool:
        """True when `up` is (0, 0, 0) or (nearly, see UP_PARALLEL_TOL) parallel to the view
        direction: it fixes no roll, and `basis` uses a fallback up instead."""
        up = np.asarray(self.up, float)
        fwd = _unit(np.subtract(self.target, self.eye))
        n = np.linalg.norm(up)
        return not (n > 0 and np.linalg.norm(np.cross(fwd, up)) > UP_PARALLEL_TOL * n)

    @cached_property
    def eye_array(self) -> np.ndarray:
        """The eye as a (3,) float64 array."""
        return np.asarray(self.eye, float)

    @cached_property
    def focal_px(self) -> float:
        """f = (H/2) / tan(fov_y/2) for perspective, pixels per world unit for orthographic."""
        if self.projection == "perspective":
            return (self.height / 2.0) / math.tan(math.radians(self.fov_y) / 2.0)
        return self.height / self.ortho_height

    @property
    def is_ortho(self) -> bool:
        return self.projection == "orthographic"

    def depth(self, points: np.ndarray) -> np.ndarray:
        """z = (P - eye).fwd for (N, 3) points; shape (N,)."""
        _, _, fwd = self.basis
        return (np.asarray(points, float) - np.asarray(self.eye)) @ fwd

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Project (N, 3) world points to (N, 2) pixel coordinates and (N,) depths z.
        Perspective points with z <= 0 give non-finite pixels: clip before projecting."""
        right, up, fwd = self.basis
        q = np.asarray(points, float) - self.eye_array
        z = q @ fwd
        xr, yu = q @ right, q @ up
        f = self.focal_px
        if self.is_ortho:
            return np.stack([self.width / 2.0 + f * xr, self.height / 2.0 - f * yu], axis=-1), z
        if q.ndim != 2:
            with np.errstate(divide="ignore", invalid="ignore"):
                return np.stack([self.width / 2.0 + f * xr / z, self.height / 2.0 - f * yu / z], axis=-1), z
        xy = np.empty((len(z), 2))  # filled by column: np.stack costs more than the arithmetic here
        with np.errstate(divide="ignore", invalid="ignore"):
            xy[:, 0] = self.width / 2.0 + f * xr / z
            xy[:, 1] = self.height / 2.0 - f * yu / z
        return xy, z

    def project_fused(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """`project` for a perspective camera in fewer passes (one product with the camera axes):
        the same pixels up to float64 rounding. The draft visibility path's projection."""
        right, up, fwd = self.basis
        M = np.stack([right, -up, fwd], axis=1)
        C = points @ M  # then minus the eye's coordinates, column by column (no (N, 3) broadcast)
        e = self.eye_array @ M
        z = C[:, 2] - e[2]
        with np.errstate(divide="ignore", invalid="ignore"):
            s = self.focal_px / z
        xy = np.empty((len(points), 2))
        xy[:, 0] = (C[:, 0] - e[0]) * s + self.width / 2.0
        xy[:, 1] = (C[:, 1] - e[1]) * s + self.height / 2.0
        return xy, z

    def near_distance(self, scene_radius: float) -> float:
        """Near plane distance along fwd (world units): `near` if given, else 1e-4 of the smaller of
        the scene radius and the eye-target distance (a huge scene must not clip a close-up)."""
        if self.near is not None:
            return float(self.near)
        dist = float(np.linalg.norm(np.subtract(self.target, self.eye)))
        return 1e-4 * max(min(scene_radius, dist), 1e-300)

    def to_json(self) -> dict:
        d = {"eye": list(self.eye), "target": list(self.target), "up": list(self.up), "fov_y": self.fov_y,
             "width": int(self.width), "height": int(self.height), "projection": self.projection}
        if self.is_ortho:
            d["ortho_height"] = self.ortho_height
        if self.near is not None:
            d["near"] = self.near
        return d


MAX_PATH_FRAMES = 100_000


@dataclass(frozen=True)
class CameraPath:
    """A sequence of cameras; frame k (0-based) is output frame k+1."""

    cameras: tuple[Camera, ...]
    fps: float = 24.0
    source: str = ""

    def __len__(self) -> int:
        return len(self.cameras)

    def to_json(self) -> dict:
        first = self.cameras[0]
        frames = []
        for c in self.cameras:
            d = c.to_json()
            d.pop("width"), d.pop("height")
            frames.append(d)
        return {"width": int(first.width), "height": int(first.height), "fps": self.fps, "frames": frames}

    def select(self, frames: list[int]) -> list[tuple[int, Camera]]:
        """[(output frame number (1-based), camera)] for 1-based frame numbers."""
        out = []
        for n in frames:
            if not 1 <= n <= len(self.cameras):
                raise InputError(f"frame {n} is outside the camera path (1-{len(self.cameras)})", self.source or None)
            out.append((n, self.cameras[n - 1]))
        return out


def _show(value) -> str:
    """A camera value for a message: (1, nan, 2), not (np.float64(1.0), np.float64(nan), ...)."""
    try:
        return "(" + ", ".join(f"{float(x):g}" for x in value) + ")"
    except (TypeError, ValueError):
        return repr(value)
