"""A frame's view (`Camera`: eye, target, up, lens, image size; perspective, orthographic, or one
of the parallel projections of technical drawing) and a sequence of them (`CameraPath`). Image
space: x to the right, y down, origin at the top-left corner, in pixels (BRIEF 1.1).

Parallel projections (seed 001, 3.2): the observer is at infinity, every projection ray has one
direction. `orthographic` takes its direction from eye -> target. The axonometric projections
(the image plane perpendicular to the rays) take theirs from angles measured on the world axes,
with `up` the vertical axis: `azimuth` turns the view about `up` (0: from the front axis, +z for
a y up, -y for a z up, as `orbit_path`), `elevation` lifts it above the horizontal plane:
`isometric` (the three axes equally foreshortened: elevation atan(1/sqrt 2) = 35.26 degrees,
azimuth 45 + k 90), `dimetric` (the two horizontal axes alike: azimuth 45 + k 90, elevation
given), `trimetric` (both given). The oblique projections (`cavalier`, `cabinet`) keep the image
plane perpendicular to the view of `azimuth` / `elevation` (default: the front view) and slant
the rays: a point `z` deeper than the target is drawn `scale * z` along the receding axis, at
`oblique_angle` (default 45 degrees) above the image's horizontal, scale 1 (cavalier) or 1/2
(cabinet, "les distances fuyantes sont divisees par 2"). For these five, the camera stands
`distance` before the target along the projection rays (the eye, on the ray through the target,
which stays at the image centre); the eye sets the near plane as for an orthographic camera."""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from strokekit.camera.limits import ANGLED, MAX_IMAGE_PX, MAX_PATH_FRAMES, PROJECTIONS  # noqa: F401 (the view's names)
from strokekit.errors import InputError

FALLBACK_UPS = (np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]))
#: The largest size of a camera coordinate (eye, target, up) or length (ortho_height, near, an
#: angled projection's distance), world units. Far beyond any scene strokekit can draw (float64
#: spacing there is 0.125), far below what overflows float64 once squared, multiplied or
#: projected (1e154): a camera beyond it is refused instead of turning into inf and NaN.
MAX_COORD = 1e15
#: `up` counts as parallel to the view direction when |fwd x up| <= this x |up| (fwd a unit
#: vector): Camera.basis then picks a fallback up, and a camera file refuses it.
UP_PARALLEL_TOL = 1e-6

OBLIQUE_SCALE = {"cavalier": 1.0, "cabinet": 0.5}
#: The isometric elevation: atan(1 / sqrt(2)), in degrees (35.264...).
ISOMETRIC_ELEVATION = math.degrees(math.atan(1.0 / math.sqrt(2.0)))


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
    # The angled parallel projections (ANGLED; see the module doc), degrees. None: the default.
    azimuth: float | None = None
    elevation: float | None = None
    oblique_angle: float | None = None

    def __post_init__(self):
        for name in ("eye", "target", "up"):
            v = np.asarray(getattr(self, name), dtype=float)
            if v.shape != (3,) or not np.all(np.isfinite(v)):
                raise InputError(f"camera {name} must be 3 finite numbers, got {_show(getattr(self, name))}")
            if np.any(np.abs(v) > MAX_COORD):
                raise InputError(f"camera {name} {_show(v)} is out of range: coordinates must be within "
                                 f"+-{MAX_COORD:g} world units")
            object.__setattr__(self, name, tuple(float(x) for x in v))
        if self.projection not in PROJECTIONS:
            raise InputError(f"camera projection must be one of {', '.join(PROJECTIONS)}, got {self.projection!r}")
        if self.projection == "perspective" and not (0.0 < float(self.fov_y) < 180.0):
            raise InputError(f"camera fov_y must be in (0, 180) degrees, got {self.fov_y!r}")
        if self.projection != "perspective" and not (math.isfinite(self.ortho_height) and self.ortho_height > 0):
            raise InputError(f"camera ortho_height must be > 0, got {self.ortho_height!r}")
        if self.projection != "perspective" and self.ortho_height > MAX_COORD:
            raise InputError(f"camera ortho_height {self.ortho_height:g} is out of range: at most {MAX_COORD:g} "
                             "world units")
        if self.near is not None and not (math.isfinite(self.near) and self.near > 0):
            raise InputError(f"camera near must be a distance > 0, got {self.near!r}")
        if self.near is not None and self.near > MAX_COORD:
            raise InputError(f"camera near {self.near:g} is out of range: at most {MAX_COORD:g} world units")
        if int(self.width) <= 0 or int(self.height) <= 0:
            raise InputError(f"image size must be positive, got {self.width} x {self.height}")
        if np.linalg.norm(np.subtract(self.target, self.eye)) == 0.0:
            raise InputError("camera target equals eye: the view direction has zero length")
        if self.projection in ANGLED:
            self._set_angles()
        else:
            for name in ("azimuth", "elevation", "oblique_angle"):
                if getattr(self, name) is not None:
                    raise InputError(f"camera {name} belongs to the projections {', '.join(ANGLED)}, not to a "
                                     f"{self.projection} camera")

    def _set_angles(self) -> None:
        """An angled parallel projection: check and complete its angles, then put the eye on the
        projection ray through the target at its depth (target - eye).fwd (keyframes move eye and
        target; the angles, not their line, give the direction)."""
        az, el, ob = _complete_angles(self.projection, self.azimuth, self.elevation, self.oblique_angle)
        object.__setattr__(self, "azimuth", az)
        object.__setattr__(self, "elevation", el)
        object.__setattr__(self, "oblique_angle", ob)
        depth = float(np.subtract(self.target, self.eye) @ self.basis[2])
        if depth == 0.0:
            raise InputError("camera eye and target are at the same depth: the camera has no distance")
        eye = np.asarray(self.target, float) - depth * self.ray_dir
        object.__setattr__(self, "eye", tuple(float(x) for x in eye))

    @staticmethod
    def parallel(projection: str, target, distance: float, *, up=(0.0, 1.0, 0.0), ortho_height: float = 1.0,
                 width: int = 1024, height: int = 1024, azimuth: float | None = None,
                 elevation: float | None = None, oblique_angle: float | None = None,
                 near: float | None = None) -> "Camera":
        """A camera of an angled parallel projection (ANGLED) `distance` (> 0, world units, along
        the view) before `target`."""
        if projection not in ANGLED:
            raise InputError(f"parallel projections are {', '.join(ANGLED)}, got {projection!r}")
        if isinstance(distance, bool) or not (isinstance(distance, (int, float)) and math.isfinite(distance)
                                              and distance > 0):
            raise InputError(f"camera distance must be a number > 0, got {distance!r}")
        if distance > MAX_COORD:
            raise InputError(f"camera distance {distance:g} is out of range: at most {MAX_COORD:g} world units")
        t = np.asarray(target, float)
        if t.shape != (3,) or not np.all(np.isfinite(t)):
            raise InputError(f"camera target must be 3 finite numbers, got {_show(target)}")
        u = np.asarray(up, float)
        if u.shape != (3,) or not np.all(np.isfinite(u)) or not np.any(u):
            raise InputError(f"camera up must be 3 finite numbers, not all 0, got {_show(up)}")
        for name, v in (("target", t), ("up", u)):  # (before any product: 1e200 squared overflows)
            if np.any(np.abs(v) > MAX_COORD):
                raise InputError(f"camera {name} {_show(v)} is out of range: coordinates must be within "
                                 f"+-{MAX_COORD:g} world units")
        az, el, ob = _complete_angles(projection, azimuth, elevation, oblique_angle)
        _, _, fwd = angled_basis(u, az, el)
        return Camera(eye=tuple(t - float(distance) * fwd), target=tuple(t), up=tuple(u), projection=projection,
                      ortho_height=ortho_height, width=width, height=height, azimuth=az, elevation=el,
                      oblique_angle=ob, near=near)

    @staticmethod
    def from_json(d: dict) -> "Camera":
        """The camera `to_json` wrote (an angled parallel projection gives its distance, not its eye)."""
        d = {k: (tuple(v) if isinstance(v, list) else v) for k, v in d.items()}
        if "distance" in d:
            dist = d.pop("distance")
            d.pop("fov_y", None)
            return Camera.parallel(d.pop("projection"), d.pop("target"), dist, **d)
        return Camera(**d)

    # --- frame -------------------------------------------------------------------------------
    @cached_property  # frozen: computed once per camera (the tracker asks for it often)
    def basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(right, up', fwd) unit vectors, float64. A stable fallback up is used when up is
        (nearly) parallel to the view direction."""
        if self.projection in ANGLED:
            return angled_basis(self.up, self.azimuth, self.elevation)
        fwd = _unit(np.subtract(self.target, self.eye))
        candidates = [np.asarray(self.up, float)] + list(FALLBACK_UPS)
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
        """Every parallel projection (orthographic, axonometric, oblique): one ray direction."""
        return self.projection != "perspective"

    @property
    def is_oblique(self) -> bool:
        return self.projection in OBLIQUE_SCALE

    @cached_property
    def shear(self) -> tuple[float, float]:
        """(kx, ky): a parallel camera draws a point z deeper (along fwd) kx z px / focal_px
        further right and ky z further up than its image-plane position; (0, 0) but for the oblique
        projections (scale x (cos, sin) of the receding axis angle)."""
        if not self.is_oblique:
            return 0.0, 0.0
        s, a = OBLIQUE_SCALE[self.projection], math.radians(self.oblique_angle)
        return s * math.cos(a), s * math.sin(a)

    @cached_property
    def ray_dir(self) -> np.ndarray:
        """The direction of a parallel camera's projection rays, into the scene, with a unit
        component along fwd: fwd itself but for the oblique projections (fwd - kx right - ky up)."""
        right, up, fwd = self.basis
        if not self.is_oblique:
            return fwd
        kx, ky = self.shear
        return fwd - kx * right - ky * up

    @cached_property
    def view_dir(self) -> np.ndarray:
        """The unit direction of a parallel camera's rays into the scene (fwd but for oblique)."""
        d = self.ray_dir
        return d if not self.is_oblique else d / np.linalg.norm(d)

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
            if self.is_oblique:
                kx, ky = self.shear
                xr, yu = xr + kx * z, yu + ky * z
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
        """The camera as a camera file's frame (plus width and height). An angled parallel
        projection gives its distance and angles instead of an eye (which they fix)."""
        if self.projection in ANGLED:
            d = {"target": list(self.target), "up": list(self.up), "width": int(self.width),
                 "height": int(self.height), "projection": self.projection, "ortho_height": self.ortho_height,
                 "distance": float(np.subtract(self.target, self.eye) @ self.basis[2]),
                 "azimuth": self.azimuth, "elevation": self.elevation}
            if self.is_oblique:
                d["oblique_angle"] = self.oblique_angle
            if self.near is not None:
                d["near"] = self.near
            return d
        d = {"eye": list(self.eye), "target": list(self.target), "up": list(self.up), "fov_y": self.fov_y,
             "width": int(self.width), "height": int(self.height), "projection": self.projection}
        if self.is_ortho:
            d["ortho_height"] = self.ortho_height
        if self.near is not None:
            d["near"] = self.near
        return d


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
            if c.is_ortho:  # (Camera.to_json keeps it; a camera file's parallel frame refuses it)
                d.pop("fov_y", None)
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


def _a(word: str) -> str:
    return ("an " if word[0] in "aeiou" else "a ") + word


def _complete_angles(p: str, az, el, ob) -> tuple[float, float, float | None]:
    """(azimuth, elevation, oblique_angle) of an angled parallel projection `p`, defaults filled
    in; InputError for a value the projection does not allow."""
    for k, v in (("azimuth", az), ("elevation", el), ("oblique_angle", ob)):
        if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v)):
            raise InputError(f"camera {k} must be a finite number of degrees, got {v!r}")
    if p in ("isometric", "dimetric"):
        az = 45.0 if az is None else float(az)
        if (az - 45.0) % 90.0 != 0.0:
            raise InputError(f"{_a(p)} camera's azimuth must be 45, 135, 225 or 315 degrees (the two horizontal "
                             f"axes equally foreshortened), got {az:g}")
    if p == "isometric":
        if el is not None and abs(abs(el) - ISOMETRIC_ELEVATION) > 1e-9:
            raise InputError(f"an isometric camera's elevation is +-{ISOMETRIC_ELEVATION:.6f} degrees (the three "
                             f"axes equally foreshortened), got {el:g}: a dimetric camera takes another")
        el = ISOMETRIC_ELEVATION if el is None else math.copysign(ISOMETRIC_ELEVATION, el)
    elif p in ("dimetric", "trimetric"):
        missing = [k for k, v in (("azimuth", az), ("elevation", el)) if v is None]
        if missing:
            raise InputError(f"{_a(p)} camera needs {' and '.join(missing)} (degrees)")
        if not 0.0 < abs(el) < 90.0:
            raise InputError(f"{_a(p)} camera's elevation must be strictly between -90 and 90 degrees and not 0 "
                             f"(an axis would collapse to a point), got {el:g}")
    else:  # oblique: the front view unless said
        az = 0.0 if az is None else az
        el = 0.0 if el is None else el
        ob = 45.0 if ob is None else float(ob)
        if not abs(el) < 90.0:
            raise InputError(f"{_a(p)} camera's elevation must be strictly between -90 and 90 degrees, got {el:g}")
    if p not in OBLIQUE_SCALE and ob is not None:
        raise InputError(f"oblique_angle belongs to the oblique projections (cavalier, cabinet), not to {p}")
    return float(az), float(el), ob


def angled_basis(up, azimuth: float, elevation: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(right, up', fwd) of a view from `azimuth` / `elevation` degrees about the unit `up`: the
    front axis is the first of +z, -y, +x not along up (orbit_path's convention: y up looks from
    +z at azimuth 0, z up from -y), the side axis up x front (+x for both)."""
    U = _unit(np.asarray(up, float))
    for F0 in (np.array([0.0, 0.0, 1.0]), np.array([0.0, -1.0, 0.0]), np.array([1.0, 0.0, 0.0])):
        F = F0 - (F0 @ U) * U
        if np.linalg.norm(F) > 1e-6:
            F = _unit(F)
            break
    X = np.cross(U, F)
    az, el = math.radians(azimuth), math.radians(elevation)
    toward_eye = math.cos(el) * (math.sin(az) * X + math.cos(az) * F) + math.sin(el) * U
    fwd = -toward_eye
    right = _unit(np.cross(fwd, U))
    return right, np.cross(right, fwd), fwd


def _show(value) -> str:
    """A camera value for a message: (1, nan, 2), not (np.float64(1.0), np.float64(nan), ...)."""
    try:
        return "(" + ", ".join(f"{float(x):g}" for x in value) + ")"
    except (TypeError, ValueError):
        return repr(value)
