"""Camera paths from a glTF/GLB file's camera node: the node's world transform through its
ancestors, its animation sampled at 24 fps (rotations slerped), its lens."""

from __future__ import annotations

import base64
import binascii
import json
import math
from pathlib import Path
from urllib.parse import unquote

import numpy as np

from strokekit.camera.view import MAX_IMAGE_PX, MAX_PATH_FRAMES, Camera, CameraPath
from strokekit.errors import InputError


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
            head, sep, payload = uri.partition(",")
            if not sep or not head.endswith(";base64"):
                raise self.error(f"buffer {i}: data URI is not base64")
            try:
                data = base64.b64decode(payload, validate=False)
            except (binascii.Error, ValueError) as e:
                raise self.error(f"buffer {i}: bad base64 data URI ({e})") from None
        else:
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
    with np.errstate(over="ignore", under="ignore"):
        scale = np.linalg.norm(rot, axis=0)
    if not np.all(np.isfinite(scale) & (scale > 0)):  # a scale of 1e300 (or 1e-300) squared: the
        peak = np.max(np.abs(rot), axis=0)  # columns brought near 1 first, then normalized
        rot = rot / np.where(peak > 0, peak, 1)
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
        with np.errstate(over="ignore", invalid="ignore"):  # (said below, in one line)
            world = world @ local
    if not np.all(np.isfinite(world)):
        raise InputError(f"the world transform of camera node {cam_i} is out of range (its nodes' scales and "
                         "translations multiply beyond float64)", path)

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
