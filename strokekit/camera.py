"""Cameras (BRIEF 1.1) and camera paths (BRIEF 1.2).

Image space: x right, y down, origin top-left, pixel (i, j) covers [i, i+1] x [j, j+1].
All camera maths is float64.
"""

from __future__ import annotations

import json
import math
from functools import cached_property
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from .errors import InputError, UsageError

_FALLBACK_UPS = (np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]))
# Limits of what a camera file (JSON or glTF) may ask for: beyond them a run would fail late (a
# width of 1e30 px overflows the writers) or never end (a frame_count of 1e12).
MAX_IMAGE_PX = 100_000  # per side
MAX_PATH_FRAMES = 100_000


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


# --- keyframes ----------------------------------------------------------------------------------

def _turn(u0: np.ndarray, u1: np.ndarray, t: float, spare_axis: np.ndarray) -> np.ndarray:
    """The unit vector a fraction t of the way from unit u0 to unit u1 along the great circle
    (slerp of directions). Opposite vectors turn about `spare_axis` (made perpendicular to u0)."""
    axis = np.cross(u0, u1)
    angle = math.atan2(np.linalg.norm(axis), float(u0 @ u1))
    if np.linalg.norm(axis) < 1e-9:
        if angle < 1.0:  # the same direction
            return u0
        axis = spare_axis - (spare_axis @ u0) * u0
        if np.linalg.norm(axis) < 1e-9:
            axis = np.cross(u0, _FALLBACK_UPS[0] if abs(u0[1]) < 0.9 else _FALLBACK_UPS[2])
    k = axis / np.linalg.norm(axis)
    a = t * angle  # Rodrigues; k is perpendicular to u0
    return u0 * math.cos(a) + np.cross(k, u0) * math.sin(a)


def _key_up(cam: Camera) -> np.ndarray:
    up = np.asarray(cam.up, float)
    n = np.linalg.norm(up)
    return up / n if n > 0 else cam.basis[1]


def interpolate_keyframes(keys: list[tuple[int, Camera]], frame_count: int, smooth: bool = False,
                          source: str = "") -> list[Camera]:
    """Cameras for frames 0..frame_count-1 from (frame, camera) keyframes.

    Keyframes give eye, target and up (BRIEF 1.2), and those are what is interpolated: eye and
    target linearly, or along Catmull-Rom curves (smooth), so a target that two keys share stays at
    the image centre between them; the up vector turns at an even rate from one key's to the
    next's and the camera frame re-orthogonalizes it against the view direction (Camera.basis).
    fov_y (perspective), ortho_height (orthographic) and near are linear. Before the first key and
    after the last the nearest key holds; a keyframe's frame is that key's camera exactly.

    Keys must all have one projection and give near all or none (an InputError naming `source`
    and the two frames otherwise: a perspective-to-orthographic jump or a near plane that exists
    on one side only has no in-between)."""
    keys = sorted(keys, key=lambda k: k[0])
    for (fa, a), (fb, b) in zip(keys, keys[1:]):
        if a.projection != b.projection:
            raise InputError(f"keyframes at frame {fa} ({a.projection}) and frame {fb} ({b.projection}) mix "
                             f"projections: every keyframe of a path needs the same one", source or None)
        if (a.width, a.height) != (b.width, b.height):
            raise InputError(f"keyframes at frame {fa} ({a.width} x {a.height} px) and frame {fb} ({b.width} x "
                             f"{b.height} px) have different image sizes: a path has one size", source or None)
        if (a.near is None) != (b.near is None):
            has, hasnt = (fa, fb) if a.near is not None else (fb, fa)
            raise InputError(f"the keyframe at frame {has} gives 'near' and the one at frame {hasnt} does not: "
                             f"give 'near' on every keyframe or on none", source or None)
    kf = np.array([k for k, _ in keys], float)
    eyes = np.array([c.eye for _, c in keys])
    targets = np.array([c.target for _, c in keys])
    ups = [_key_up(c) for _, c in keys]

    def curve(p: np.ndarray, i: int, t: float) -> np.ndarray:
        if not smooth:
            return (1 - t) * p[i] + t * p[i + 1]
        p0, p1, p2, p3 = p[max(i - 1, 0)], p[i], p[i + 1], p[min(i + 2, len(p) - 1)]
        t2, t3 = t * t, t * t * t
        return 0.5 * ((2 * p1) + (-p0 + p2) * t + (2 * p0 - 5 * p1 + 4 * p2 - p3) * t2
                      + (-p0 + 3 * p1 - 3 * p2 + p3) * t3)

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
        eye, target = curve(eyes, i, t), curve(targets, i, t)
        up = _turn(ups[i], ups[i + 1], t, spare_axis=a.basis[2])
        if a.is_ortho:  # (only the lens of the path's projection: the other is never checked)
            lens = {"ortho_height": (1 - t) * a.ortho_height + t * b.ortho_height}
        else:
            lens = {"fov_y": (1 - t) * a.fov_y + t * b.fov_y}
        near = None if a.near is None else (1 - t) * a.near + t * b.near
        try:
            out.append(replace(a, eye=tuple(eye), target=tuple(target), up=tuple(up), near=near, **lens))
        except InputError as e:  # the eye passes through the target
            raise InputError(f"frame {f}, between the keyframes at frame {keys[i][0]} and frame {keys[i + 1][0]}: "
                             f"{e}", source or None) from None
    return out


# --- camera path files ----------------------------------------------------------------------------

def _whole_number(value, what: str) -> int:
    """A whole number from a JSON value: an int, or a float with an integral value (3.0). Anything
    else (2.7, "3", null, true, 1e400) is an InputError naming `what`; the caller adds the file."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError(f"{what} must be a whole number, got {json.dumps(value)}")
    if isinstance(value, float) and not (math.isfinite(value) and value.is_integer()):
        raise InputError(f"{what} must be a whole number, got {value!r}")
    return int(value)


def _image_side(value, what: str) -> int:
    n = _whole_number(value, what)
    if not 0 < n <= MAX_IMAGE_PX:
        raise InputError(f"image size must be positive and at most {MAX_IMAGE_PX} px, got {what} {n}")
    return n


#: The keys of a camera path file (BRIEF 1.2): the file, and each frame or keyframe. Keys that
#: start with "_" (comments) and "extras" are the user's own and are not read.
_PATH_KEYS = ("width", "height", "fps", "frames", "keyframes", "frame_count", "interpolation")
_CAMERA_KEYS = ("eye", "target", "up", "fov_y", "projection", "ortho_height", "near", "width", "height")


def _check_keys(d: dict, known: tuple[str, ...], where: str, source: str) -> None:
    """InputError for a key the reader does not know: a typo ("fovy") would silently give the
    default instead (40 degrees)."""
    unknown = [k for k in d if k not in known and not (isinstance(k, str) and (k.startswith("_") or k == "extras"))]
    if unknown:
        import difflib

        k = unknown[0]
        close = difflib.get_close_matches(str(k), known, n=1)
        hint = f"did you mean '{close[0]}'? " if close else ""
        raise InputError(f"{where}unknown key {json.dumps(k)} ({hint}known: {', '.join(known)}; "
                         "keys starting with '_' are comments)", source)


def _camera_from_dict(d: dict, width: int, height: int, where: str, source: str, extra_keys=()) -> Camera:
    if not isinstance(d, dict):
        raise InputError(f"{where} must be an object", source)
    _check_keys(d, _CAMERA_KEYS + tuple(extra_keys), f"{where}: ", source)
    for key in ("eye", "target"):
        if key not in d:
            raise InputError(f"{where} has no '{key}'", source)
    if d.get("projection") == "orthographic" and "ortho_height" not in d:
        # (it would silently be 1 world unit: the size of the drawing would be a guess)
        raise InputError(f"{where}: an orthographic camera needs 'ortho_height' (world units across the image height)",
                         source)
    try:
        cam = Camera(eye=tuple(d["eye"]), target=tuple(d["target"]), up=tuple(d.get("up", (0.0, 1.0, 0.0))),
                     fov_y=float(d.get("fov_y", 40.0)), width=_image_side(d.get("width", width), "width"),
                     height=_image_side(d.get("height", height), "height"),
                     projection=d.get("projection", "perspective"),
                     ortho_height=float(d.get("ortho_height", 1.0)),
                     near=(float(d["near"]) if d.get("near") is not None else None))
    except InputError as e:
        raise InputError(f"{where}: {e}", source) from None
    except (TypeError, ValueError, OverflowError) as e:  # OverflowError: an integer beyond float range
        raise InputError(f"{where}: bad value ({e})", source) from None
    if "up" in d and not np.any(cam.up):
        raise InputError(f"{where}: 'up' is (0, 0, 0): it gives no direction", source)
    return cam


def _show(value) -> str:
    """A camera value for a message: (1, nan, 2), not (np.float64(1.0), np.float64(nan), ...)."""
    try:
        return "(" + ", ".join(f"{float(x):g}" for x in value) + ")"
    except (TypeError, ValueError):
        return repr(value)


def camera_path_from_json(data: dict, source: str = "") -> CameraPath:
    """Parse either form of BRIEF 1.2 into a CameraPath."""
    if not isinstance(data, dict):
        raise InputError("camera file must hold a JSON object", source)
    _check_keys(data, _PATH_KEYS, "", source)
    if "frames" in data and "keyframes" in data:
        raise InputError("camera file has both 'frames' and 'keyframes': give one form", source)
    try:
        width = _image_side(data.get("width", 1024), "width")
        height = _image_side(data.get("height", 1024), "height")
        fps = float(data.get("fps", 24))
    except InputError as e:
        raise InputError(str(e), source) from None
    except (TypeError, ValueError, OverflowError) as e:
        raise InputError(f"bad fps ({e})", source) from None
    if not (math.isfinite(fps) and fps > 0):
        raise InputError(f"fps must be a number > 0, got {fps:g}", source)
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
        try:
            count = _whole_number(data["frame_count"], "frame_count")
        except InputError as e:
            raise InputError(str(e), source) from None
        if not 0 < count <= MAX_PATH_FRAMES:
            raise InputError(f"frame_count must be between 1 and {MAX_PATH_FRAMES}, got {count}", source)
        parsed = []
        for i, k in enumerate(keys):
            if not isinstance(k, dict) or "frame" not in k:
                raise InputError(f"keyframe {i + 1} has no 'frame'", source)
            try:
                frame = _whole_number(k["frame"], f"keyframe {i + 1}: 'frame'")
            except InputError as e:
                raise InputError(f"{e} (keyframes sit on output frames, counted from 0)", source) from None
            if abs(frame) > 2 ** 53:
                raise InputError(f"keyframe {i + 1}: 'frame' {frame} is out of range", source)
            parsed.append((frame, _camera_from_dict(k, width, height, f"keyframe {i + 1}", source, ("frame",))))
        seen = [f for f, _ in parsed]
        if len(set(seen)) < len(seen):
            dup = sorted(f for f in set(seen) if seen.count(f) > 1)
            raise InputError(f"two keyframes for frame {dup[0]}", source)
        cams = interpolate_keyframes(parsed, count, smooth=(interp == "smooth"), source=source)
    else:
        raise InputError("camera file needs 'frames' or 'keyframes'", source)
    return CameraPath(cameras=tuple(cams), fps=fps, source=source)


def load_camera_path(path: str | Path) -> CameraPath:
    """Read a camera path JSON file (BRIEF 1.2) or a glTF/GLB file's camera node (animated: one
    camera per frame at 24 fps, see gltf_camera_path)."""
    p = Path(path)
    if not p.exists():
        raise InputError("camera file not found", p)
    if p.is_dir():
        raise InputError("is a folder, not a camera file", p)
    if p.suffix.lower() in (".glb", ".gltf"):
        return gltf_camera_path(p)
    try:
        data = json.loads(p.read_text())
    except OSError as e:
        raise InputError(f"cannot read camera file ({e.strerror or e})", p) from None
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
    for name, v in (("elevation", elevation), ("fov_y", fov_y), ("degrees_per_frame", degrees_per_frame),
                    ("start_azimuth", start_azimuth), ("distance_factor", distance_factor), ("fps", fps)):
        if v is not None and not math.isfinite(v):
            raise UsageError(f"orbit {name} must be a finite number, got {v}")
    if not 0.0 < fov_y < 180.0:
        raise UsageError(f"orbit fov_y must be in (0, 180) degrees, got {fov_y:g}")
    if not (distance_factor > 0 and fps > 0):
        raise UsageError(f"orbit distance_factor and fps must be > 0, got {distance_factor:g} and {fps:g}")
    step = 360.0 / frames if degrees_per_frame is None else degrees_per_frame
    dist = distance_factor * 1.15 * radius / math.sin(math.radians(fov_y) / 2.0)
    el = math.radians(elevation)
    up = np.array([0.0, 1.0, 0.0]) if up_axis == "y" else np.array([0.0, 0.0, 1.0])
    cams = []
    for k in range(frames):
        az = math.radians(start_azimuth + k * step)
        if up_axis == "y":
            d = np.array([math.sin(az) * math.cos(el), math.sin(el), math.cos(az) * math.cos(el)])
            ground = np.array([math.sin(az), 0.0, math.cos(az)])
        else:
            d = np.array([math.sin(az) * math.cos(el), -math.cos(az) * math.cos(el), math.sin(el)])
            ground = np.array([math.sin(az), -math.cos(az), 0.0])
        eye = np.asarray(center, float) + dist * d
        # Straight above or below (elevation +-90): the up axis is the view axis, so the image's
        # up turns with the azimuth (away from the eye's side), or every frame would be the same.
        # (Camera.basis gives up on an up within 1e-6 of the view axis; 1e-5 stays clear of it.)
        frame_up = up if abs(math.cos(el)) > 1e-5 else -math.copysign(1.0, el) * ground
        cams.append(Camera(eye=tuple(eye), target=tuple(np.asarray(center, float)), up=tuple(frame_up), fov_y=fov_y,
                           width=width, height=height))
    return CameraPath(cameras=tuple(cams), fps=fps, source="orbit")


def dolly_path(center: np.ndarray, radius: float, frames: int, *, start: float = 1.0, end: float = 8.0,
               fov_y: float = 40.0, width: int = 1024, height: int = 1024, elevation: float = 15.0,
               azimuth: float = 0.0, up_axis: str = "y") -> CameraPath:
    """The camera moves from `start` to `end` times the framing distance, geometrically."""
    if not all(math.isfinite(v) and v > 0 for v in (start, end)):
        raise UsageError(f"dolly start and end must be finite numbers > 0, got {start:g} and {end:g}")
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
    """Number of camera nodes (nodes placing a camera) of a glTF/GLB file: what `--camera FILE`
    can use (0 when the file cannot be read)."""
    import pygltflib

    try:
        g = pygltflib.GLTF2().load(str(path))
    except Exception:  # info only: the scene loader reports broken files
        return 0
    return sum(1 for n in g.nodes or [] if n.camera is not None)


# --- glTF camera nodes and their animation -------------------------------------------------------

_GLTF_FLOAT = 5126
# componentType -> (numpy dtype, divisor when normalized; None: not a normalized type)
_GLTF_COMPONENTS = {5126: ("<f4", None), 5120: ("<i1", 127.0), 5121: ("<u1", 255.0), 5122: ("<i2", 32767.0),
                    5123: ("<u2", 65535.0), 5125: ("<u4", None)}
_GLTF_INDEX_TYPES = {5121: "<u1", 5123: "<u2", 5125: "<u4"}
_GLTF_NCOMP = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
_GLTF_TRS = {"translation": 3, "rotation": 4, "scale": 3}
_GLTF_INTERPOLATIONS = ("LINEAR", "STEP", "CUBICSPLINE")
_GLTF_MAX_FRAMES = MAX_PATH_FRAMES


def _field(obj, name, default=None):
    """Attribute of a pygltflib object, or key of a plain dict (nested parts may stay dicts)."""
    if obj is None:
        return default
    if isinstance(obj, dict):
        return obj.get(name, default)
    return getattr(obj, name, default)


def _is_index(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool) and v >= 0


class _GltfData:
    """Buffers and accessors of one glTF file, read as float64 arrays. Every problem is an
    InputError naming the file."""

    def __init__(self, gltf, path: Path):
        self.g, self.path = gltf, Path(path)
        self._buffers: dict[int, bytes] = {}

    def error(self, msg: str) -> InputError:
        return InputError(msg, self.path)

    def _item(self, kind: str, i, what: str):
        items = getattr(self.g, kind) or []
        if not _is_index(i) or i >= len(items):
            raise self.error(f"{what} refers to {kind[:-1]} {i!r}, which does not exist")
        return items[i]

    def buffer(self, i: int, what: str) -> bytes:
        if i in self._buffers:
            return self._buffers[i]
        b = self._item("buffers", i, what)
        uri = _field(b, "uri")
        if uri is None:
            data = self.g.binary_blob()
            if data is None:
                raise self.error(f"buffer {i} has no uri and the file has no binary chunk")
        elif uri.startswith("data:"):
            import base64
            import binascii

            head, sep, payload = uri.partition(",")
            if not sep or not head.endswith(";base64"):
                raise self.error(f"buffer {i}: data URI is not base64")
            try:
                data = base64.b64decode(payload, validate=False)
            except (binascii.Error, ValueError) as e:
                raise self.error(f"buffer {i}: bad base64 data URI ({e})") from None
        else:
            from urllib.parse import unquote

            f = self.path.parent / unquote(uri)
            try:
                data = f.read_bytes()
            except OSError as e:
                raise self.error(f"buffer {i}: cannot read {f} ({e.strerror or e})") from None
        length = _field(b, "byteLength")
        if not _is_index(length) or len(data) < length:
            raise self.error(f"buffer {i} holds {len(data)} bytes, fewer than its byteLength {length!r}")
        self._buffers[i] = bytes(data[:length])
        return self._buffers[i]

    def _read(self, view_i, offset, count: int, ncomp: int, dtype: str, what: str, strided: bool = True):
        """(count, ncomp) array of `dtype` from buffer view `view_i` at byte `offset`."""
        bv = self._item("bufferViews", view_i, what)
        buf = self.buffer(_field(bv, "buffer"), f"buffer view {view_i}")
        v_off, v_len = _field(bv, "byteOffset") or 0, _field(bv, "byteLength")
        if not _is_index(v_off) or not _is_index(v_len) or v_off + v_len > len(buf):
            raise self.error(f"buffer view {view_i} lies outside its buffer")
        item = np.dtype(dtype).itemsize
        esize = ncomp * item
        stride = (_field(bv, "byteStride") or esize) if strided else esize
        if not _is_index(offset) or not _is_index(stride) or stride < esize:
            raise self.error(f"{what}: bad byteOffset {offset!r} or byteStride {stride!r}")
        if count == 0:
            return np.zeros((0, ncomp), dtype)
        if offset + stride * (count - 1) + esize > v_len:
            raise self.error(f"{what} reads past the end of buffer view {view_i}")
        return np.ndarray((count, ncomp), dtype=dtype, buffer=buf, offset=v_off + offset,
                          strides=(stride, item)).copy()

    def accessor(self, i, what: str) -> np.ndarray:
        """Accessor i as a (count, components) float64 array: float, or normalized integers
        scaled to [0, 1] / [-1, 1]; sparse substitution applied; all values finite."""
        a = self._item("accessors", i, what)
        name = f"accessor {i}"
        ncomp, ctype, count = _GLTF_NCOMP.get(_field(a, "type")), _field(a, "componentType"), _field(a, "count")
        if ncomp is None:
            raise self.error(f"{name} has unknown type {_field(a, 'type')!r}")
        if ctype not in _GLTF_COMPONENTS:
            raise self.error(f"{name} has unknown componentType {ctype!r}")
        dtype, scale = _GLTF_COMPONENTS[ctype]
        if ctype != _GLTF_FLOAT and not (_field(a, "normalized") and scale is not None):
            raise self.error(f"{name}: componentType {ctype} is neither float nor a normalized integer")
        if not _is_index(count):
            raise self.error(f"{name} has a bad count {count!r}")
        view = _field(a, "bufferView")
        if view is None:
            out = np.zeros((count, ncomp))
        else:
            out = self._read(view, _field(a, "byteOffset") or 0, count, ncomp, dtype, name).astype(np.float64)
        sparse = _field(a, "sparse")
        if sparse is not None:
            n = _field(sparse, "count")
            idx, vals = _field(sparse, "indices"), _field(sparse, "values")
            itype = _GLTF_INDEX_TYPES.get(_field(idx, "componentType"))
            if not _is_index(n) or idx is None or vals is None or itype is None:
                raise self.error(f"{name} has a malformed sparse block")
            where = self._read(_field(idx, "bufferView"), _field(idx, "byteOffset") or 0, n, 1, itype,
                               f"{name} sparse indices", strided=False)[:, 0].astype(np.int64)
            if n and where.max() >= count:
                raise self.error(f"{name}: sparse index beyond the accessor's count {count}")
            out[where] = self._read(_field(vals, "bufferView"), _field(vals, "byteOffset") or 0, n, ncomp, dtype,
                                    f"{name} sparse values", strided=False).astype(np.float64)
        if scale is not None and ctype != _GLTF_FLOAT:
            out = out / scale
            if dtype.startswith("<i"):
                out = np.maximum(out, -1.0)
        if not np.all(np.isfinite(out)):
            raise self.error(f"{name} holds non-finite values")
        return out


def _quats_to_matrices(q: np.ndarray) -> np.ndarray:
    """(N, 3, 3) rotation matrices of (N, 4) unit quaternions in glTF order (x, y, z, w)."""
    x, y, z, w = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
    ], 1)


def _slerp_many(q0: np.ndarray, q1: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Row-wise shortest-path slerp of unit quaternions (N, 4) at fractions s (N,). The angle
    comes from atan2 of |q0 - q1| and |q0 + q1|, accurate for tiny and large angles alike."""
    flip = np.sum(q0 * q1, axis=1) < 0
    q1 = np.where(flip[:, None], -q1, q1)
    half = np.arctan2(np.linalg.norm(q0 - q1, axis=1), np.linalg.norm(q0 + q1, axis=1))
    th = 2.0 * half  # angle between q0 and q1 on the 4D sphere
    sin_th = np.sin(th)
    tiny = sin_th < 1e-12
    with np.errstate(divide="ignore", invalid="ignore"):
        a = np.where(tiny, 1.0 - s, np.sin((1.0 - s) * th) / np.where(tiny, 1.0, sin_th))
        b = np.where(tiny, s, np.sin(s * th) / np.where(tiny, 1.0, sin_th))
    q = a[:, None] * q0 + b[:, None] * q1
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def _sample_channel(keys: np.ndarray, values: np.ndarray, interp: str, rotation: bool, t: np.ndarray) -> np.ndarray:
    """Values (len(t), components) of one animation sampler at times t. Before the first key the
    first value holds, after the last key the last. A time within float32 rounding of a key counts
    as that key (key times are stored as float32, frame times are float64)."""
    n = len(keys)
    if interp == "CUBICSPLINE":
        tan_in, vals, tan_out = values[0::3], values[1::3], values[2::3]
    else:
        vals = values
    if rotation:
        vals = vals / np.linalg.norm(vals, axis=1, keepdims=True)
    if n == 1:
        return np.repeat(vals[:1], len(t), axis=0)
    tol = 1e-6 * np.maximum(1.0, np.abs(t))
    i = np.clip(np.searchsorted(keys, t + tol, side="right") - 1, 0, n - 1)
    if interp == "STEP":
        return vals[i]
    j = np.minimum(i, n - 2)  # segment [keys[j], keys[j + 1]]
    td = keys[j + 1] - keys[j]
    s = np.clip((t - keys[j]) / td, 0.0, 1.0)  # 0 before the first key
    s = np.where(i == n - 1, 1.0, s)  # at or after the last key
    s = np.where((i == j) & (t - keys[j] <= tol), 0.0, s)  # on key j
    if interp == "LINEAR":
        if rotation:
            return _slerp_many(vals[j], vals[j + 1], s)
        return (1.0 - s)[:, None] * vals[j] + s[:, None] * vals[j + 1]
    s2, s3 = s * s, s * s * s
    h00, h10, h01, h11 = 2 * s3 - 3 * s2 + 1, s3 - 2 * s2 + s, -2 * s3 + 3 * s2, s3 - s2
    out = (h00[:, None] * vals[j] + (h10 * td)[:, None] * tan_out[j] + h01[:, None] * vals[j + 1]
           + (h11 * td)[:, None] * tan_in[j + 1])
    if rotation:
        out = out / np.linalg.norm(out, axis=1, keepdims=True)
    return out


def _node_matrix(n, what: str, data: _GltfData) -> np.ndarray | None:
    """The node's 4 x 4 matrix (column-major in the file), None when it has none."""
    m = _field(n, "matrix")
    if not m:
        return None
    try:
        a = np.array(m, float)
    except (TypeError, ValueError, OverflowError):
        a = np.zeros(0)
    if a.shape != (16,):
        raise data.error(f"{what} has a malformed matrix: glTF needs 16 numbers, got {json.dumps(m)[:80]}")
    return a.reshape(4, 4).T


def _trs_matrices(t: np.ndarray, r: np.ndarray, s: np.ndarray) -> np.ndarray:
    """(F, 4, 4) matrices T @ R @ S from (F, 3) translations, (F, 4) unit quaternions (x, y, z, w)
    and (F, 3) scales."""
    m = np.zeros((len(t), 4, 4))
    m[:, :3, :3] = _quats_to_matrices(r) * s[:, None, :]
    m[:, :3, 3] = t
    m[:, 3, 3] = 1.0
    return m


def _rest_trs(n, path: str, what: str, data: _GltfData) -> np.ndarray:
    default = {"translation": [0.0, 0.0, 0.0], "rotation": [0.0, 0.0, 0.0, 1.0], "scale": [1.0, 1.0, 1.0]}[path]
    v = _field(n, path) or default
    try:
        a = np.asarray(v, float).reshape(_GLTF_TRS[path])
    except (TypeError, ValueError):
        raise data.error(f"{what} has a malformed {path} {v!r}") from None
    if not np.all(np.isfinite(a)):
        raise data.error(f"{what} has a non-finite {path}")
    if path == "rotation":
        norm = np.linalg.norm(a)
        if norm == 0:
            raise data.error(f"{what} has a zero rotation quaternion")
        a = a / norm
    return a


def _gltf_width(height: int, aspect: float, what: str) -> int:
    """Image width height x aspect of a glTF lens, refused outside 1..MAX_IMAGE_PX."""
    w = height * aspect
    if not 0.5 <= w < MAX_IMAGE_PX + 0.5:
        raise InputError(f"{what} gives an image {w:.4g} x {height} px: the width must be 1 to {MAX_IMAGE_PX} px")
    return int(round(w))


def _camera_at(m: np.ndarray, cam, width: int | None, height: int | None) -> Camera:
    """The Camera of glTF camera object `cam` placed by world matrix m (local -Z forward, +Y up)."""
    rot = m[:3, :3]
    scale = np.linalg.norm(rot, axis=0)
    rot = rot / np.where(scale > 0, scale, 1)
    eye = m[:3, 3]
    fwd, up = -rot[:, 2], rot[:, 1]
    if cam.type == "orthographic":  # (gltf_camera_path checked that the block is there)
        xmag, ymag = cam.orthographic.xmag, cam.orthographic.ymag
        if not all(isinstance(v, (int, float)) and math.isfinite(v) and v > 0 for v in (xmag, ymag)):
            raise InputError(f"orthographic xmag and ymag must be > 0, got {xmag!r} and {ymag!r}")
        h = height or 1024
        w = width or _gltf_width(h, xmag / ymag, f"orthographic xmag / ymag ({xmag:g} / {ymag:g})")
        return Camera(eye=tuple(eye), target=tuple(eye + fwd), up=tuple(up), projection="orthographic",
                      ortho_height=2 * cam.orthographic.ymag, width=w, height=h)
    p = cam.perspective
    if not (isinstance(p.yfov, (int, float)) and math.isfinite(p.yfov) and 0 < p.yfov < math.pi):
        raise InputError(f"perspective camera needs a yfov in (0, pi) radians, got {p.yfov!r}")
    h = height or 1024
    aspect = p.aspectRatio if p.aspectRatio is not None else 1.0
    if not (isinstance(aspect, (int, float)) and math.isfinite(aspect) and aspect > 0):
        raise InputError(f"perspective aspectRatio must be a number > 0, got {aspect!r}")
    w = width or _gltf_width(h, aspect, f"perspective aspectRatio {aspect:g}")
    return Camera(eye=tuple(eye), target=tuple(eye + fwd), up=tuple(up),
                  fov_y=math.degrees(p.yfov), width=w, height=h, near=(p.znear or None))


def gltf_camera_path(path: Path, width: int | None = None, height: int | None = None,
                     fps: float = 24.0) -> CameraPath:
    """The first camera node of a glTF/GLB file (in node order), placed by its world transform,
    following its node animation when there is one.

    glTF cameras look down their local -Z with +Y up. Perspective: fov_y = yfov (radians in the
    file, degrees in Camera), width = height x aspectRatio unless given; orthographic: ortho_height
    = 2 ymag. Height defaults to 1024.

    Animation: the first animation (in file order) with a translation, rotation or scale channel
    targeting the camera node or one of its ancestors drives the camera; other animations are
    ignored, and so are properties no channel of it targets (they keep their rest values). The
    channels (LINEAR, with slerp for rotations; STEP; CUBICSPLINE) are sampled at `fps`: frame k at
    time t0 + k / fps for k = 0, 1, ... while the time is at most t1 (up to float32 rounding of the
    key times), t0 and t1 the earliest and latest key times of that animation's channels that affect
    the camera. So the last key time is a frame whenever t1 - t0 is a whole number of frames.
    Before its first key a channel holds its first value, after its last key its last value. The
    world transform is composed per frame; the lens does not animate (glTF cannot without
    extensions). Without such an animation the node's rest transform gives one frame.

    Accessors may be float or normalized integers, in a GLB binary chunk, a data URI or an external
    file, strided or sparse. Anything malformed is one InputError naming the file."""
    import pygltflib

    path = Path(path)
    if not (isinstance(fps, (int, float)) and math.isfinite(fps) and fps > 0):
        raise InputError(f"fps must be > 0, got {fps!r}", path)
    try:
        g = pygltflib.GLTF2().load(str(path))
    except Exception as e:  # pygltflib raises many kinds on bad files
        raise InputError(f"cannot read glTF ({e})", path) from None
    if g is None:
        raise InputError("cannot read glTF (not a glTF or GLB file)", path)
    if not g.cameras:
        raise InputError("glTF file has no camera", path)
    nodes = g.nodes or []
    data = _GltfData(g, path)
    cam_i = next((i for i, n in enumerate(nodes) if n.camera is not None), None)
    if cam_i is None:
        raise InputError("glTF file has cameras but no node uses one", path)
    cam_obj = data._item("cameras", nodes[cam_i].camera, f"node {cam_i}")
    # The lens is the block named by the type; without it the camera would be a guess (an
    # orthographic camera without one was drawn in perspective at 40 degrees).
    kind = _field(cam_obj, "type")
    if kind not in ("perspective", "orthographic"):
        raise data.error(f"camera {nodes[cam_i].camera} has type {kind!r}: glTF cameras are 'perspective' or "
                         f"'orthographic'")
    if _field(cam_obj, kind) is None:
        needs = "yfov" if kind == "perspective" else "xmag, ymag"
        raise data.error(f"camera {nodes[cam_i].camera} is {kind} but has no '{kind}' block ({needs})")
    parents = {}
    for i, n in enumerate(nodes):
        for c in n.children or []:
            if not _is_index(c) or c >= len(nodes):
                raise data.error(f"node {i} has child {json.dumps(c)}, but there is no such node "
                                 f"(the file has {len(nodes)})")
            parents[c] = i
    chain = [cam_i]  # camera node, its parent, ..., the root
    while chain[-1] in parents:
        p = parents[chain[-1]]
        if p in chain:
            raise InputError(f"node hierarchy has a cycle through node {p}", path)
        chain.append(p)

    channels = _camera_channels(g, data, set(chain))
    if channels:
        t0 = min(k[0] for k, _, _ in channels.values())
        t1 = max(k[-1] for k, _, _ in channels.values())
        count = int(math.floor((t1 - t0) * fps + 1e-4 + 1e-6 * max(abs(t0), abs(t1)) * fps)) + 1
        if count > _GLTF_MAX_FRAMES:
            raise InputError(f"camera animation spans {t1 - t0:g} s: {count} frames at {fps:g} fps "
                             f"(more than {_GLTF_MAX_FRAMES})", path)
        times = t0 + np.arange(count) / fps
    else:
        times = np.zeros(1)
    frames = len(times)

    world = np.broadcast_to(np.eye(4), (frames, 4, 4))
    for ni in reversed(chain):  # root first: world = L_root @ ... @ L_camera
        n = nodes[ni]
        what = f"node {ni}"
        animated = {p for (node, p) in channels if node == ni}
        fixed = _node_matrix(n, what, data)
        if fixed is not None:
            if animated:
                raise InputError(f"animation targets {what}, which has a matrix (glTF allows only TRS there)", path)
            if not np.all(np.isfinite(fixed)):
                raise InputError(f"{what} has a non-finite matrix", path)
            local = np.broadcast_to(fixed, (frames, 4, 4))
        else:
            trs = {}
            for p in ("translation", "rotation", "scale"):
                if p in animated:
                    keys, values, interp = channels[(ni, p)]
                    trs[p] = _sample_channel(keys, values, interp, p == "rotation", times)
                else:
                    trs[p] = np.broadcast_to(_rest_trs(n, p, what, data), (frames, _GLTF_TRS[p]))
            local = _trs_matrices(trs["translation"], trs["rotation"], trs["scale"])
        world = world @ local

    cams = []
    for k, m in enumerate(world):
        try:
            cams.append(_camera_at(m, cam_obj, width, height))
        except InputError as e:
            where = f"frame {k + 1} (t = {times[k]:g} s)" if channels else f"node {cam_i}"
            raise InputError(f"camera at {where}: {e}", path) from None
    return CameraPath(cameras=tuple(cams), fps=float(fps), source=str(path))


def _camera_channels(g, data: _GltfData, chain: set[int]) -> dict:
    """{(node, path): (key times (n,), values, interpolation)} of the first animation with a TRS
    channel on a node of `chain`; {} when none has one. Checked: indices, key counts, strictly
    increasing finite key times, value shapes, interpolation names."""
    for ai, anim in enumerate(g.animations or []):
        hits = [ch for ch in (anim.channels or [])
                if _field(_field(ch, "target"), "node") in chain and _field(_field(ch, "target"), "path") in _GLTF_TRS]
        if not hits:
            continue
        out = {}
        samplers = anim.samplers or []
        for ch in hits:
            tgt = _field(ch, "target")
            node, prop = _field(tgt, "node"), _field(tgt, "path")
            si = _field(ch, "sampler")
            what = f"animation {ai} sampler {si}"
            if not _is_index(si) or si >= len(samplers):
                raise data.error(f"animation {ai}: a channel refers to sampler {si!r}, which does not exist")
            if (node, prop) in out:
                raise data.error(f"animation {ai} has two channels for node {node} {prop}")
            smp = samplers[si]
            interp = _field(smp, "interpolation") or "LINEAR"
            if interp not in _GLTF_INTERPOLATIONS:
                raise data.error(f"{what}: interpolation {interp!r} is not supported (LINEAR, STEP or CUBICSPLINE)")
            keys = data.accessor(_field(smp, "input"), f"{what} input")
            if keys.shape[1] != 1:
                raise data.error(f"{what}: key times must be a SCALAR accessor")
            keys = keys[:, 0]
            if len(keys) == 0:
                raise data.error(f"{what} has no keyframes")
            if np.any(np.diff(keys) <= 0):
                raise data.error(f"{what}: key times must increase strictly")
            values = data.accessor(_field(smp, "output"), f"{what} output")
            want = _GLTF_TRS[prop]
            per_key = 3 if interp == "CUBICSPLINE" else 1
            if values.shape[1] != want or len(values) != per_key * len(keys):
                raise data.error(f"{what}: {prop} needs {per_key * len(keys)} VEC{want} values for {len(keys)} "
                                 f"{interp} keys, got {len(values)} of {values.shape[1]} components")
            if prop == "rotation":
                v = values[1::3] if interp == "CUBICSPLINE" else values
                if np.any(np.linalg.norm(v, axis=1) == 0):
                    raise data.error(f"{what}: a rotation key is the zero quaternion")
            out[(node, prop)] = (keys, values, interp)
        return out
    return {}
