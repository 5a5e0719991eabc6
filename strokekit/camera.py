"""Cameras (BRIEF 1.1) and camera paths (BRIEF 1.2).

Image space: x right, y down, origin top-left, pixel (i, j) covers [i, i+1] x [j, j+1].
All camera maths is float64.
"""

from __future__ import annotations

import json
import math
from functools import cached_property
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from .errors import InputError

_FALLBACK_UPS = (np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]))


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
                raise InputError(f"camera {name} must be 3 finite numbers, got {getattr(self, name)!r}")
            object.__setattr__(self, name, tuple(float(x) for x in v))
        if self.projection not in ("perspective", "orthographic"):
            raise InputError(f"camera projection must be 'perspective' or 'orthographic', got {self.projection!r}")
        if self.projection == "perspective" and not (0.0 < float(self.fov_y) < 180.0):
            raise InputError(f"camera fov_y must be in (0, 180) degrees, got {self.fov_y!r}")
        if self.projection == "orthographic" and not (math.isfinite(self.ortho_height) and self.ortho_height > 0):
            raise InputError(f"camera ortho_height must be > 0, got {self.ortho_height!r}")
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
            if np.linalg.norm(up) > 0 and nr > 1e-6 * np.linalg.norm(up):
                right = r / nr
                return right, np.cross(right, fwd), fwd
        raise AssertionError("unreachable: one fallback up is never parallel")

    @property
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
        q = np.asarray(points, float) - np.asarray(self.eye)
        z = q @ fwd
        xr, yu = q @ right, q @ up
        f = self.focal_px
        if self.is_ortho:
            xy = np.stack([self.width / 2.0 + f * xr, self.height / 2.0 - f * yu], axis=-1)
        else:
            with np.errstate(divide="ignore", invalid="ignore"):
                xy = np.stack([self.width / 2.0 + f * xr / z, self.height / 2.0 - f * yu / z], axis=-1)
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


# --- rotations: look-at frames slerped as quaternions -------------------------------------------

def _matrix_to_quat(m: np.ndarray) -> np.ndarray:
    tr = m[0, 0] + m[1, 1] + m[2, 2]
    if tr > 0:
        s = math.sqrt(tr + 1.0) * 2
        q = [0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s]
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2]) * 2
        q = [(m[2, 1] - m[1, 2]) / s, 0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s]
    elif m[1, 1] > m[2, 2]:
        s = math.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2]) * 2
        q = [(m[0, 2] - m[2, 0]) / s, (m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s]
    else:
        s = math.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1]) * 2
        q = [(m[1, 0] - m[0, 1]) / s, (m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s]
    q = np.array(q)
    return q / np.linalg.norm(q)


def _quat_to_matrix(q: np.ndarray) -> np.ndarray:
    w, x, y, z = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def _slerp(q0: np.ndarray, q1: np.ndarray, t: float) -> np.ndarray:
    d = float(np.dot(q0, q1))
    if d < 0:
        q1, d = -q1, -d
    if d > 0.9995:
        q = q0 + t * (q1 - q0)
        return q / np.linalg.norm(q)
    th = math.acos(d)
    return (math.sin((1 - t) * th) * q0 + math.sin(t * th) * q1) / math.sin(th)


def _lookat_quat(cam: Camera) -> np.ndarray:
    right, up, fwd = cam.basis
    return _matrix_to_quat(np.stack([right, up, -fwd], axis=1))


def interpolate_keyframes(keys: list[tuple[int, Camera]], frame_count: int, smooth: bool = False) -> list[Camera]:
    """Cameras for frames 0..frame_count-1 from (frame, camera) keyframes: eye linear or
    Catmull-Rom (smooth), orientation by slerp of the look-at frames, target distance and fov linear."""
    keys = sorted(keys, key=lambda k: k[0])
    kf = np.array([k for k, _ in keys], float)
    eyes = np.array([c.eye for _, c in keys])
    quats = [_lookat_quat(c) for _, c in keys]
    dists = np.array([np.linalg.norm(np.subtract(c.target, c.eye)) for _, c in keys])
    out = []
    for f in range(frame_count):
        if f <= kf[0]:
            i, t = 0, 0.0
        elif f >= kf[-1]:
            i, t = len(keys) - 1, 0.0
        else:
            i = int(np.searchsorted(kf, f, side="right") - 1)
            t = (f - kf[i]) / (kf[i + 1] - kf[i])
        a = keys[i][1]
        if t == 0.0:
            out.append(a)
            continue
        b = keys[i + 1][1]
        if smooth:
            p0 = eyes[max(i - 1, 0)]
            p1, p2 = eyes[i], eyes[i + 1]
            p3 = eyes[min(i + 2, len(keys) - 1)]
            t2, t3 = t * t, t * t * t
            eye = 0.5 * ((2 * p1) + (-p0 + p2) * t + (2 * p0 - 5 * p1 + 4 * p2 - p3) * t2 + (-p0 + 3 * p1 - 3 * p2 + p3) * t3)
        else:
            eye = (1 - t) * eyes[i] + t * eyes[i + 1]
        rot = _quat_to_matrix(_slerp(quats[i], quats[i + 1], t))
        fwd, up = -rot[:, 2], rot[:, 1]
        dist = (1 - t) * dists[i] + t * dists[i + 1]
        out.append(replace(a, eye=tuple(eye), target=tuple(eye + dist * fwd), up=tuple(up),
                           fov_y=(1 - t) * a.fov_y + t * b.fov_y,
                           ortho_height=(1 - t) * a.ortho_height + t * b.ortho_height))
    return out


# --- camera path files ----------------------------------------------------------------------------

def _camera_from_dict(d: dict, width: int, height: int, where: str, source: str) -> Camera:
    if not isinstance(d, dict):
        raise InputError(f"{where} must be an object", source)
    for key in ("eye", "target"):
        if key not in d:
            raise InputError(f"{where} has no '{key}'", source)
    try:
        cam = Camera(eye=tuple(d["eye"]), target=tuple(d["target"]), up=tuple(d.get("up", (0.0, 1.0, 0.0))),
                     fov_y=float(d.get("fov_y", 40.0)), width=int(d.get("width", width)),
                     height=int(d.get("height", height)), projection=d.get("projection", "perspective"),
                     ortho_height=float(d.get("ortho_height", 1.0)),
                     near=(float(d["near"]) if d.get("near") is not None else None))
    except InputError as e:
        raise InputError(f"{where}: {e}", source) from None
    except (TypeError, ValueError) as e:
        raise InputError(f"{where}: bad value ({e})", source) from None
    return cam


def camera_path_from_json(data: dict, source: str = "") -> CameraPath:
    """Parse either form of BRIEF 1.2 into a CameraPath."""
    if not isinstance(data, dict):
        raise InputError("camera file must hold a JSON object", source)
    try:
        width, height = int(data.get("width", 1024)), int(data.get("height", 1024))
        fps = float(data.get("fps", 24))
    except (TypeError, ValueError) as e:
        raise InputError(f"bad width/height/fps ({e})", source) from None
    if width <= 0 or height <= 0:
        raise InputError(f"image size must be positive, got {width} x {height}", source)
    # Entries are named as output frames are, from 1 (BRIEF 1.2: entry k is output frame k+1).
    if "frames" in data:
        frames = data["frames"]
        if not isinstance(frames, list) or not frames:
            raise InputError("'frames' must be a non-empty list", source)
        cams = [_camera_from_dict(f, width, height, f"frame {i + 1}", source) for i, f in enumerate(frames)]
    elif "keyframes" in data:
        keys = data["keyframes"]
        if not isinstance(keys, list) or not keys:
            raise InputError("'keyframes' must be a non-empty list", source)
        if "frame_count" not in data:
            raise InputError("keyframe form needs 'frame_count'", source)
        interp = data.get("interpolation", "linear")
        if interp not in ("linear", "smooth"):
            raise InputError(f"interpolation must be 'linear' or 'smooth', got {interp!r}", source)
        parsed = []
        for i, k in enumerate(keys):
            if not isinstance(k, dict) or "frame" not in k:
                raise InputError(f"keyframe {i + 1} has no 'frame'", source)
            parsed.append((int(k["frame"]), _camera_from_dict(k, width, height, f"keyframe {i + 1}", source)))
        count = int(data["frame_count"])
        if count <= 0:
            raise InputError("frame_count must be positive", source)
        cams = interpolate_keyframes(parsed, count, smooth=(interp == "smooth"))
    else:
        raise InputError("camera file needs 'frames' or 'keyframes'", source)
    return CameraPath(cameras=tuple(cams), fps=fps, source=source)


def load_camera_path(path: str | Path) -> CameraPath:
    """Read a camera path JSON file (BRIEF 1.2) or a glTF/GLB file's camera node."""
    p = Path(path)
    if not p.exists():
        raise InputError("camera file not found", p)
    if p.suffix.lower() in (".glb", ".gltf"):
        return gltf_camera_path(p)
    try:
        data = json.loads(p.read_text())
    except UnicodeDecodeError:
        raise InputError("camera file is not text", p) from None
    except json.JSONDecodeError as e:
        raise InputError(f"camera file is not valid JSON ({e.msg}: line {e.lineno}, column {e.colno})", p) from None
    return camera_path_from_json(data, str(p))



def orbit_path(center: np.ndarray, radius: float, frames: int, *, elevation: float = 15.0, fov_y: float = 40.0,
               width: int = 1024, height: int = 1024, fps: float = 24.0, degrees_per_frame: float | None = None,
               up_axis: str = "y", start_azimuth: float = 0.0, distance_factor: float = 1.0) -> CameraPath:
    """A turntable orbit around `center` that keeps a sphere of `radius` in view.

    `degrees_per_frame` defaults to 360 / frames (a full turn). `up_axis` is 'y' or 'z'."""
    if frames <= 0:
        raise InputError(f"orbit needs a positive frame count, got {frames}")
    if not (np.isfinite(radius) and radius > 0):
        raise InputError("cannot orbit an empty or degenerate scene")
    step = 360.0 / frames if degrees_per_frame is None else degrees_per_frame
    dist = distance_factor * 1.15 * radius / math.sin(math.radians(fov_y) / 2.0)
    el = math.radians(elevation)
    up = np.array([0.0, 1.0, 0.0]) if up_axis == "y" else np.array([0.0, 0.0, 1.0])
    cams = []
    for k in range(frames):
        az = math.radians(start_azimuth + k * step)
        if up_axis == "y":
            d = np.array([math.sin(az) * math.cos(el), math.sin(el), math.cos(az) * math.cos(el)])
        else:
            d = np.array([math.sin(az) * math.cos(el), -math.cos(az) * math.cos(el), math.sin(el)])
        eye = np.asarray(center, float) + dist * d
        cams.append(Camera(eye=tuple(eye), target=tuple(np.asarray(center, float)), up=tuple(up), fov_y=fov_y,
                           width=width, height=height))
    return CameraPath(cameras=tuple(cams), fps=fps, source="orbit")


def dolly_path(center: np.ndarray, radius: float, frames: int, *, start: float = 1.0, end: float = 8.0,
               fov_y: float = 40.0, width: int = 1024, height: int = 1024, elevation: float = 15.0,
               azimuth: float = 0.0, up_axis: str = "y") -> CameraPath:
    """The camera moves from `start` to `end` times the framing distance, geometrically."""
    base = orbit_path(center, radius, 1, elevation=elevation, fov_y=fov_y, width=width, height=height,
                      up_axis=up_axis, start_azimuth=azimuth)
    cam0 = base.cameras[0]
    c = np.asarray(center, float)
    d = np.subtract(cam0.eye, c)
    cams = []
    for k in range(frames):
        s = start * (end / start) ** (k / max(frames - 1, 1))
        cams.append(replace(cam0, eye=tuple(c + s * d)))
    return CameraPath(cameras=tuple(cams), source="dolly")


def gltf_camera_count(path) -> int:
    """Number of cameras a glTF/GLB file defines (0 when it cannot be read)."""
    import pygltflib

    try:
        return len(pygltflib.GLTF2().load(str(path)).cameras or [])
    except Exception:  # info only: the scene loader reports broken files
        return 0


def gltf_camera_path(path: Path, width: int | None = None, height: int | None = None) -> CameraPath:
    """The first camera node of a glTF/GLB file, placed by its world transform.

    glTF cameras look down their local -Z with +Y up. Node animation is not followed: the
    node's rest transform gives one frame."""
    import pygltflib

    try:
        g = pygltflib.GLTF2().load(str(path))
    except Exception as e:  # pygltflib raises many kinds on bad files
        raise InputError(f"cannot read glTF ({e})", path) from None
    if not g.cameras:
        raise InputError("glTF file has no camera", path)
    parents = {}
    for i, n in enumerate(g.nodes):
        for c in n.children or []:
            parents[c] = i

    def local(n) -> np.ndarray:
        if n.matrix:
            return np.array(n.matrix, float).reshape(4, 4).T
        m = np.eye(4)
        if n.scale:
            m = np.diag(list(n.scale) + [1.0]) @ m
        if n.rotation:
            x, y, z, w = n.rotation
            r = np.eye(4)
            r[:3, :3] = _quat_to_matrix(np.array([w, x, y, z]) / np.linalg.norm([w, x, y, z]))
            m = r @ m
        if n.translation:
            t = np.eye(4)
            t[:3, 3] = n.translation
            m = t @ m
        return m

    for i, n in enumerate(g.nodes):
        if n.camera is None:
            continue
        m = local(n)
        j = i
        while j in parents:
            j = parents[j]
            m = local(g.nodes[j]) @ m
        cam = g.cameras[n.camera]
        rot = m[:3, :3]
        scale = np.linalg.norm(rot, axis=0)
        rot = rot / np.where(scale > 0, scale, 1)
        eye = m[:3, 3]
        fwd, up = -rot[:, 2], rot[:, 1]
        if cam.type == "orthographic" and cam.orthographic is not None:
            h = height or 1024
            w = width or int(round(h * cam.orthographic.xmag / cam.orthographic.ymag))
            c = Camera(eye=tuple(eye), target=tuple(eye + fwd), up=tuple(up), projection="orthographic",
                       ortho_height=2 * cam.orthographic.ymag, width=w, height=h)
        else:
            p = cam.perspective
            h = height or 1024
            aspect = (p.aspectRatio if p is not None and p.aspectRatio else 1.0)
            w = width or int(round(h * aspect))
            c = Camera(eye=tuple(eye), target=tuple(eye + fwd), up=tuple(up),
                       fov_y=math.degrees(p.yfov) if p is not None else 40.0, width=w, height=h,
                       near=(p.znear if p is not None and p.znear else None))
        return CameraPath(cameras=(c,), source=str(path))
    raise InputError("glTF file has cameras but no node uses one", path)
