"""Cameras (BRIEF 1.1) and camera paths (BRIEF 1.2).

Image space: x right, y down, origin top-left, pixel (i, j) covers [i, i+1] x [j, j+1].
All camera maths is float64.
"""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np

from strokekit.camera.gltf import gltf_camera_path
from strokekit.camera.view import ANGLED, FALLBACK_UPS, MAX_IMAGE_PX, MAX_PATH_FRAMES, Camera, CameraPath, angled_basis
from strokekit.errors import InputError, UsageError, did_you_mean

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
            axis = np.cross(u0, FALLBACK_UPS[0] if abs(u0[1]) < 0.9 else FALLBACK_UPS[2])
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
            if a.projection in ANGLED:  # the angles that give the direction turn linearly too
                lens.update({k: (1 - t) * getattr(a, k) + t * getattr(b, k) for k in ("azimuth", "elevation")
                             if getattr(a, k) != getattr(b, k)})
                if a.oblique_angle != b.oblique_angle:
                    lens["oblique_angle"] = (1 - t) * a.oblique_angle + t * b.oblique_angle
        else:
            lens = {"fov_y": (1 - t) * a.fov_y + t * b.fov_y}
        near = None if a.near is None else (1 - t) * a.near + t * b.near
        between = f"frame {f}, between the keyframes at frame {keys[i][0]} and frame {keys[i + 1][0]}"
        try:
            cam = replace(a, eye=tuple(eye), target=tuple(target), up=tuple(up), near=near, **lens)
            if a.projection in ANGLED:  # the distance before the target changes linearly, not the eye
                depth = (1 - t) * _depth(a) + t * _depth(b)
                cam = replace(cam, eye=tuple(np.asarray(cam.target) - depth * cam.ray_dir))
        except InputError as e:  # the eye passes through the target
            raise InputError(f"{between}: {e}", source or None) from None
        if cam.up_along_view:  # e.g. an eye that passes straight over the target
            raise InputError(f"{between}: the up vector turns parallel to the view direction, so the image's "
                             "roll is undefined: give the keys an 'up' across the view there, or add a key",
                             source or None)
        out.append(cam)
    return out


def _depth(cam: Camera) -> float:
    """How far the target lies before the camera, along its view."""
    return float(np.subtract(cam.target, cam.eye) @ cam.basis[2])


# --- camera path files ----------------------------------------------------------------------------

def _whole_number(value, what: str) -> int:
    """A whole number from a JSON value: an int, or a float with an integral value (3.0). Anything
    else (2.7, "3", null, true, 1e400) is an InputError naming `what`; the caller adds the file."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError(f"{what} must be a whole number, got {json.dumps(value)}")
    if isinstance(value, float) and not (math.isfinite(value) and value.is_integer()):
        raise InputError(f"{what} must be a whole number, got {value!r}")
    return int(value)


def _number(value, what: str) -> float:
    """A finite number from a JSON value. true and false are not numbers (float(True) is 1.0: a
    "fov_y": true would silently be 1 degree), nor are strings ("30"), null or 1e400; the caller
    adds the file."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError(f"'{what}' must be a number, got {_json_short(value)}")
    try:
        x = float(value)
    except OverflowError:  # an integer beyond float range
        raise InputError(f"bad value: '{what}' {_json_short(value)} is out of range") from None
    if not math.isfinite(x):
        raise InputError(f"'{what}' must be a finite number, got {x!r}")
    return x


def _vector(value, what: str) -> tuple[float, float, float]:
    """Three finite numbers (a JSON list) from a JSON value; no booleans among them."""
    if not (isinstance(value, list) and len(value) == 3) or any(
            isinstance(x, bool) or not isinstance(x, (int, float)) for x in value):
        raise InputError(f"'{what}' must be a list of 3 numbers, got {_json_short(value)}")
    try:
        v = tuple(float(x) for x in value)
    except OverflowError:
        raise InputError(f"bad value: '{what}' {_json_short(value)} is out of range") from None
    if not all(math.isfinite(x) for x in v):
        raise InputError(f"'{what}' must be 3 finite numbers, got {_show_vec(v)}")
    return v


def _json_short(value) -> str:
    text = json.dumps(value, allow_nan=True, default=str)
    return text if len(text) <= 60 else text[:57] + "..."


def _image_side(value, what: str) -> int:
    n = _whole_number(value, what)
    if not 0 < n <= MAX_IMAGE_PX:
        raise InputError(f"image size must be positive and at most {MAX_IMAGE_PX} px, got {what} {n}")
    return n


#: The keys of a camera path file (BRIEF 1.2): the file, and each frame or keyframe. Keys that
#: start with "_" (comments) and "extras" are the user's own and are not read.
_PATH_KEYS = ("width", "height", "fps", "frames", "keyframes", "frame_count", "interpolation")
_CAMERA_KEYS = ("eye", "target", "up", "fov_y", "projection", "ortho_height", "near", "width", "height",
                "distance", "azimuth", "elevation", "oblique_angle")
#: Keys of a camera frame that belong to one kind of lens only: a perspective frame's size is its
#: 'fov_y', a parallel one's its 'ortho_height'; given to the other kind they would be ignored.
_PERSPECTIVE_ONLY = ("fov_y",)
_PARALLEL_ONLY = ("ortho_height",)


def _check_keys(d: dict, known: tuple[str, ...], where: str, source: str) -> None:
    """InputError for a key the reader does not know: a typo ("fovy") would silently give the
    default instead (40 degrees)."""
    unknown = [k for k in d if k not in known and not (isinstance(k, str) and (k.startswith("_") or k == "extras"))]
    if unknown:
        k = unknown[0]
        raise InputError(f"{where}unknown key {json.dumps(k)} ({did_you_mean(k, known)}known: {', '.join(known)}; "
                         "keys starting with '_' are comments)", source)


def _camera_from_dict(d: dict, width: int, height: int, where: str, source: str, extra_keys=()) -> Camera:
    if not isinstance(d, dict):
        raise InputError(f"{where} must be an object", source)
    _check_keys(d, _CAMERA_KEYS + tuple(extra_keys), f"{where}: ", source)
    if d.get("projection") in ANGLED:
        return _angled_camera_from_dict(d, width, height, where, source)
    angled_keys = [k for k in ("distance", "azimuth", "elevation", "oblique_angle") if k in d]
    if angled_keys:
        raise InputError(f"{where}: '{angled_keys[0]}' belongs to the projections {', '.join(ANGLED)}, not to a "
                         f"{d.get('projection', 'perspective')} camera", source)
    if d.get("projection", "perspective") == "perspective" and "ortho_height" in d:
        raise InputError(f"{where}: 'ortho_height' belongs to a parallel camera (\"projection\": \"orthographic\"), "
                         "not to a perspective one, whose size is 'fov_y'", source)
    # ('fov_y' on an orthographic frame is read and ignored: `camera parallel` wrote it there until
    # 2026-11, and users keep their camera files.)
    for key in ("eye", "target"):
        if key not in d:
            raise InputError(f"{where} has no '{key}'", source)
    if d.get("projection") == "orthographic" and "ortho_height" not in d:
        # (it would silently be 1 world unit: the size of the drawing would be a guess)
        raise InputError(f"{where}: an orthographic camera needs 'ortho_height' (world units across the image height)",
                         source)
    try:
        eye, target = _vector(d["eye"], "eye"), _vector(d["target"], "target")
        up = _vector(d["up"], "up") if "up" in d else (0.0, 1.0, 0.0)
        fov_y = _number(d["fov_y"], "fov_y") if "fov_y" in d else 40.0
        ortho_height = _number(d["ortho_height"], "ortho_height") if "ortho_height" in d else 1.0
        near = _number(d["near"], "near") if d.get("near") is not None else None
        projection = d.get("projection", "perspective")
        if not isinstance(projection, str):
            raise InputError(f"'projection' must be a name, got {_json_short(projection)}")
        cam = Camera(eye=eye, target=target, up=up, fov_y=fov_y, width=_image_side(d.get("width", width), "width"),
                     height=_image_side(d.get("height", height), "height"), projection=projection,
                     ortho_height=ortho_height, near=near)
    except InputError as e:
        raise InputError(f"{where}: {e}", source) from None
    except (TypeError, ValueError, OverflowError) as e:  # OverflowError: an integer beyond float range
        raise InputError(f"{where}: bad value ({e})", source) from None
    if "up" in d and not np.any(cam.up):
        raise InputError(f"{where}: 'up' is (0, 0, 0): it gives no direction", source)
    if cam.up_along_view:
        # The image's roll is undefined: Camera.basis would draw the frame with a fallback up,
        # which is not the view asked for.
        given = f"'up' {_show_vec(cam.up)}" if "up" in d else f"'up' (not given: {_show_vec(cam.up)})"
        raise InputError(f"{where}: {given} is parallel to the view direction (eye to target), so the image's "
                         "roll is undefined: give an 'up' across the view", source)
    return cam


def _show_vec(v) -> str:
    return "(" + ", ".join(f"{float(x):g}" for x in v) + ")"


def _angled_camera_from_dict(d: dict, width: int, height: int, where: str, source: str) -> Camera:
    """A frame of an angled parallel projection (isometric ... cabinet): its direction comes from
    the projection and its angles, so it gives a 'distance' before 'target', never an 'eye'."""
    p = d["projection"]
    if "fov_y" in d:
        raise InputError(f"{where}: {_a(p)} camera is a parallel projection: it has no 'fov_y' (its size is "
                         "'ortho_height')", source)
    if "eye" in d:
        raise InputError(f"{where}: {_a(p)} camera takes its direction from its projection: give 'distance' (world "
                         "units before the target) instead of 'eye'", source)
    for key in ("target", "ortho_height", "distance"):
        if key not in d:
            raise InputError(f"{where}: {_a(p)} camera needs '{key}'", source)
    try:
        angles = {k: _number(d[k], k) for k in ("azimuth", "elevation", "oblique_angle") if d.get(k) is not None}
        return Camera.parallel(p, _vector(d["target"], "target"), _number(d["distance"], "distance"),
                               up=_vector(d["up"], "up") if "up" in d else (0.0, 1.0, 0.0),
                               ortho_height=_number(d["ortho_height"], "ortho_height"),
                               width=_image_side(d.get("width", width), "width"),
                               height=_image_side(d.get("height", height), "height"), **angles,
                               near=(_number(d["near"], "near") if d.get("near") is not None else None))
    except InputError as e:
        raise InputError(f"{where}: {e}", source) from None
    except (TypeError, ValueError, OverflowError) as e:
        raise InputError(f"{where}: bad value ({e})", source) from None


def _a(word: str) -> str:
    return ("an " if word[0] in "aeiou" else "a ") + word


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
    except InputError as e:
        raise InputError(str(e), source) from None
    fps = data.get("fps", 24)
    if isinstance(fps, bool) or not isinstance(fps, (int, float)):  # (float(true) is 1.0)
        raise InputError(f"fps must be a number > 0, got {_json_short(fps)}", source)
    try:
        fps = float(fps)
    except OverflowError:
        raise InputError(f"bad fps: {_json_short(fps)} is out of range", source) from None
    if not (math.isfinite(fps) and fps > 0):
        raise InputError(f"fps must be a number > 0, got {fps:g}", source)
    # Entries are named as output frames are, from 1 (BRIEF 1.2: entry k is output frame k+1).
    if "frames" in data:
        frames = data["frames"]
        if not isinstance(frames, list) or not frames:
            raise InputError("'frames' must be a non-empty list", source)
        if "interpolation" in data:  # (nothing lies between listed frames: it would be ignored)
            raise InputError("'interpolation' belongs to the keyframe form ('keyframes'): a 'frames' list gives "
                             "every frame", source)
        if "frame_count" in data:
            # The frames form has as many frames as it lists; a count that says otherwise was
            # silently ignored (3 asked, 1 rendered). One that agrees is harmless.
            try:
                count = _whole_number(data["frame_count"], "frame_count")
            except InputError as e:
                raise InputError(str(e), source) from None
            if count != len(frames):
                n = len(frames)
                raise InputError(f"frame_count {count} disagrees with 'frames', which lists {n} frame{'s' * (n != 1)} "
                                 "(a 'frames' list has one entry per frame; frame_count belongs to the keyframe "
                                 "form)", source)
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
            if not 0 <= frame < count:
                # Never reached: the path would only move part of the way toward it (the key
                # numbers or frame_count are wrong, e.g. keys counted at another frame rate).
                raise InputError(f"keyframe {i + 1}: 'frame' {frame} is outside the path's frames 0 to {count - 1} "
                                 f"(frame_count {count}; keyframes sit on output frames, counted from 0)", source)
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
        # utf-8-sig: a byte-order mark (Windows editors write one) is read as the text it starts.
        data = json.loads(p.read_text(encoding="utf-8-sig"))
    except OSError as e:
        raise InputError(f"cannot read camera file ({e.strerror or e})", p) from None
    except UnicodeDecodeError:
        raise InputError("camera file is not text", p) from None
    except json.JSONDecodeError as e:
        raise InputError(f"camera file is not valid JSON ({e.msg}: line {e.lineno}, column {e.colno})", p) from None
    return camera_path_from_json(data, str(p))


#: A scene "rests on" a flat base facing down along an axis when that much of its surface area
#: lies within BASE_HEIGHT of its extent from its bottom along the axis, facing down within
#: BASE_DEG: a part on a printer's bed, a scan cut flat at its foot.
BASE_AREA = 0.02
BASE_HEIGHT = 0.01
BASE_DEG = 10.0


def base_area(vertices: np.ndarray, faces: np.ndarray, axis: int) -> float:
    """The share of the surface area of the mesh (`vertices` (V, 3), `faces` (F, 3)) in its flat
    base facing down along `axis` (0 x, 1 y, 2 z): faces whose every vertex lies within
    BASE_HEIGHT of the largest extent from the bottom, their normals within BASE_DEG of -axis."""
    tri = vertices[faces]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = np.linalg.norm(cross, axis=1)
    total = area.sum()
    if not total > 0:
        return 0.0
    lo = vertices[:, axis].min()
    extent = float(np.ptp(vertices, axis=0).max())
    low = tri[:, :, axis].max(axis=1) <= lo + BASE_HEIGHT * extent
    down = cross[:, axis] <= -math.cos(math.radians(BASE_DEG)) * area
    return float(area[low & down].sum() / total)


def looks_z_up(vertices: np.ndarray, faces: np.ndarray) -> bool:
    """Whether a mesh looks modelled Z-up (most scans and STLs for printing are): it rests on a
    flat base facing -Z (BASE_AREA of its area at least) at least twice the one it has facing -Y.
    A mesh without a flat base says nothing: no guess from its proportions (a Y-up car is long
    in Z)."""
    z = base_area(vertices, faces, 2)
    return z >= BASE_AREA and z >= 2.0 * base_area(vertices, faces, 1)


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


def parallel_path(center: np.ndarray, radius: float, projection: str, *, azimuth: float | None = None,
                  elevation: float | None = None, oblique_angle: float | None = None, frames: int = 1,
                  width: int = 1024, height: int = 1024, fps: float = 24.0, up_axis: str = "y",
                  points: np.ndarray | None = None, margin: float = 0.05) -> CameraPath:
    """`frames` frames of one parallel view (an angled projection, see camera.view, or
    orthographic from `azimuth` / `elevation`, default 0: the front view) that frame a sphere
    of `radius` around `center`, the camera 3 radii before it; with `points` (the scene's
    vertices), their image instead, centred with `margin` (a fraction of the image) around it."""
    if not (np.isfinite(radius) and radius > 0):
        raise InputError("cannot frame an empty or degenerate scene")
    up = (0.0, 1.0, 0.0) if up_axis == "y" else (0.0, 0.0, 1.0)
    c = tuple(float(x) for x in center)
    if projection == "orthographic":
        if oblique_angle is not None:
            raise UsageError("--oblique-angle belongs to the oblique projections (cavalier, cabinet)")
        el = 0.0 if elevation is None else elevation
        if not abs(el) < 90.0:
            raise UsageError(f"elevation must be strictly between -90 and 90 degrees, got {el:g}")
        _, _, fwd = angled_basis(up, 0.0 if azimuth is None else azimuth, el)
        cam = Camera(eye=tuple(np.asarray(c) - 3.0 * radius * fwd), target=c, up=up, projection="orthographic",
                     ortho_height=2.3 * radius * max(1.0, height / width), width=width, height=height)
    else:
        probe = Camera.parallel(projection, c, 1.0, up=up, azimuth=azimuth, elevation=elevation,
                                oblique_angle=oblique_angle)
        kx, ky = probe.shear  # the sphere's image: an ellipse R sqrt(1 + kx^2) wide, R sqrt(1 + ky^2) high
        size = 2.3 * radius * max(math.sqrt(1.0 + ky * ky), math.sqrt(1.0 + kx * kx) * height / width)
        cam = Camera.parallel(projection, c, 3.0 * radius, up=up, ortho_height=size, width=width, height=height,
                              azimuth=probe.azimuth, elevation=probe.elevation, oblique_angle=probe.oblique_angle)
    if points is not None and len(points):
        # Fit the drawing: the points' image box, centred, `margin` of the image left around it.
        p, _ = cam.project(np.asarray(points, float))
        lo, hi = p.min(axis=0), p.max(axis=0)
        span = max((hi[0] - lo[0]) / (width * (1 - 2 * margin)), (hi[1] - lo[1]) / (height * (1 - 2 * margin)))
        mid = 0.5 * (lo + hi)
        right, up_v, _ = cam.basis
        shift = ((mid[0] - width / 2.0) * right - (mid[1] - height / 2.0) * up_v) / cam.focal_px
        size = cam.ortho_height * max(span, 1e-12)
        target = tuple(np.asarray(cam.target) + shift)
        if projection == "orthographic":
            cam = replace(cam, eye=tuple(np.asarray(cam.eye) + shift), target=target, ortho_height=size)
        else:
            cam = Camera.parallel(projection, target, 3.0 * radius, up=up, ortho_height=size, width=width,
                                  height=height, azimuth=cam.azimuth, elevation=cam.elevation,
                                  oblique_angle=cam.oblique_angle)
    return CameraPath(cameras=(cam,) * frames, fps=fps, source=projection)
