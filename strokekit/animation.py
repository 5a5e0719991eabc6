"""glTF node animation, one implementation for cameras and objects: a file's buffers and accessors
(`GltfData`), an animation's channels checked and read (`read_channels`), sampled at any times
(`sample_channel`: LINEAR with slerp for rotations, STEP, CUBICSPLINE) and composed down the
node tree into world matrices (`NodeTree.world`)."""

from __future__ import annotations

import base64
import binascii
import json
import math
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import unquote

import numpy as np

from strokekit.errors import InputError

GLTF_FLOAT = 5126
# componentType -> (numpy dtype, divisor when normalized; None: not a normalized type)
GLTF_COMPONENTS = {5126: ("<f4", None), 5120: ("<i1", 127.0), 5121: ("<u1", 255.0), 5122: ("<i2", 32767.0),
                   5123: ("<u2", 65535.0), 5125: ("<u4", None)}
GLTF_INDEX_TYPES = {5121: "<u1", 5123: "<u2", 5125: "<u4"}
GLTF_NCOMP = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
#: The node properties an animation channel may target, and their components ("weights": one
#: per morph target of the node's mesh).
GLTF_TRS = {"translation": 3, "rotation": 4, "scale": 3}
GLTF_INTERPOLATIONS = ("LINEAR", "STEP", "CUBICSPLINE")


def field_of(obj, name, default=None):
    """Attribute of a pygltflib object, or key of a plain dict (nested parts may stay dicts)."""
    if obj is None:
        return default
    if isinstance(obj, dict):
        return obj.get(name, default)
    return getattr(obj, name, default)


def is_index(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool) and v >= 0


class GltfData:
    """Buffers and accessors of one glTF file, read as float64 arrays. Every problem is an
    InputError naming the file."""

    def __init__(self, gltf, path: Path):
        self.g, self.path = gltf, Path(path)
        self._buffers: dict[int, bytes] = {}

    def error(self, msg: str) -> InputError:
        return InputError(msg, self.path)

    def item(self, kind: str, i, what: str):
        items = getattr(self.g, kind) or []
        if not is_index(i) or i >= len(items):
            raise self.error(f"{what} refers to {kind[:-1]} {i!r}, which does not exist")
        return items[i]

    def buffer(self, i: int, what: str) -> bytes:
        if i in self._buffers:
            return self._buffers[i]
        b = self.item("buffers", i, what)
        uri = field_of(b, "uri")
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
        length = field_of(b, "byteLength")
        if not is_index(length) or len(data) < length:
            raise self.error(f"buffer {i} holds {len(data)} bytes, fewer than its byteLength {length!r}")
        self._buffers[i] = bytes(data[:length])
        return self._buffers[i]

    def _read(self, view_i, offset, count: int, ncomp: int, dtype: str, what: str, strided: bool = True):
        """(count, ncomp) array of `dtype` from buffer view `view_i` at byte `offset`."""
        bv = self.item("bufferViews", view_i, what)
        buf = self.buffer(field_of(bv, "buffer"), f"buffer view {view_i}")
        v_off, v_len = field_of(bv, "byteOffset") or 0, field_of(bv, "byteLength")
        if not is_index(v_off) or not is_index(v_len) or v_off + v_len > len(buf):
            raise self.error(f"buffer view {view_i} lies outside its buffer")
        item = np.dtype(dtype).itemsize
        esize = ncomp * item
        stride = (field_of(bv, "byteStride") or esize) if strided else esize
        if not is_index(offset) or not is_index(stride) or stride < esize:
            raise self.error(f"{what}: bad byteOffset {offset!r} or byteStride {stride!r}")
        if count == 0:
            return np.zeros((0, ncomp), dtype)
        if offset + stride * (count - 1) + esize > v_len:
            raise self.error(f"{what} reads past the end of buffer view {view_i}")
        return np.ndarray((count, ncomp), dtype=dtype, buffer=buf, offset=v_off + offset,
                          strides=(stride, item)).copy()

    def accessor(self, i, what: str, integers: bool = False) -> np.ndarray:
        """Accessor i as a (count, components) float64 array: float, or normalized integers
        scaled to [0, 1] / [-1, 1]; sparse substitution applied; all values finite.
        `integers`: unsigned integers as they are (joint indices), not normalized ones."""
        a = self.item("accessors", i, what)
        name = f"accessor {i}"
        ncomp, ctype, count = GLTF_NCOMP.get(field_of(a, "type")), field_of(a, "componentType"), field_of(a, "count")
        if ncomp is None:
            raise self.error(f"{name} has unknown type {field_of(a, 'type')!r}")
        if ctype not in GLTF_COMPONENTS:
            raise self.error(f"{name} has unknown componentType {ctype!r}")
        dtype, scale = GLTF_COMPONENTS[ctype]
        if integers:
            if ctype not in GLTF_INDEX_TYPES or field_of(a, "normalized"):
                raise self.error(f"{what}: {name} must hold unsigned integers (componentType 5121, 5123 or 5125), "
                                 f"got {ctype}")
            scale = None
        elif ctype != GLTF_FLOAT and not (field_of(a, "normalized") and scale is not None):
            raise self.error(f"{name}: componentType {ctype} is neither float nor a normalized integer")
        if not is_index(count):
            raise self.error(f"{name} has a bad count {count!r}")
        view = field_of(a, "bufferView")
        if view is None:
            out = np.zeros((count, ncomp))
        else:
            out = self._read(view, field_of(a, "byteOffset") or 0, count, ncomp, dtype, name).astype(np.float64)
        sparse = field_of(a, "sparse")
        if sparse is not None:
            n = field_of(sparse, "count")
            idx, vals = field_of(sparse, "indices"), field_of(sparse, "values")
            itype = GLTF_INDEX_TYPES.get(field_of(idx, "componentType"))
            if not is_index(n) or idx is None or vals is None or itype is None:
                raise self.error(f"{name} has a malformed sparse block")
            where = self._read(field_of(idx, "bufferView"), field_of(idx, "byteOffset") or 0, n, 1, itype,
                               f"{name} sparse indices", strided=False)[:, 0].astype(np.int64)
            if n and where.max() >= count:
                raise self.error(f"{name}: sparse index beyond the accessor's count {count}")
            out[where] = self._read(field_of(vals, "bufferView"), field_of(vals, "byteOffset") or 0, n, ncomp, dtype,
                                    f"{name} sparse values", strided=False).astype(np.float64)
        if scale is not None and ctype != GLTF_FLOAT:
            out = out / scale
            if dtype.startswith("<i"):
                out = np.maximum(out, -1.0)
        if not np.all(np.isfinite(out)):
            raise self.error(f"{what}: {name} holds non-finite values")
        return out


def load_gltf(path):
    """The pygltflib document of a glTF/GLB file; InputError when it cannot be read."""
    import pygltflib

    path = Path(path)
    try:
        g = pygltflib.GLTF2().load(str(path))
    except Exception as e:  # pygltflib raises many kinds on bad files
        raise InputError(f"cannot read glTF ({e})", path) from None
    if g is None:
        raise InputError("cannot read glTF (not a glTF or GLB file)", path)
    return g


# --- rotations and node transforms ---------------------------------------------------------------

def quats_to_matrices(q: np.ndarray) -> np.ndarray:
    """(N, 3, 3) rotation matrices of (N, 4) unit quaternions in glTF order (x, y, z, w)."""
    x, y, z, w = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
    ], 1)


def slerp(q0: np.ndarray, q1: np.ndarray, s: np.ndarray) -> np.ndarray:
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


def sample_channel(keys: np.ndarray, values: np.ndarray, interp: str, rotation: bool, t: np.ndarray) -> np.ndarray:
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
            return slerp(vals[j], vals[j + 1], s)
        return (1.0 - s)[:, None] * vals[j] + s[:, None] * vals[j + 1]
    s2, s3 = s * s, s * s * s
    h00, h10, h01, h11 = 2 * s3 - 3 * s2 + 1, s3 - 2 * s2 + s, -2 * s3 + 3 * s2, s3 - s2
    out = (h00[:, None] * vals[j] + (h10 * td)[:, None] * tan_out[j] + h01[:, None] * vals[j + 1]
           + (h11 * td)[:, None] * tan_in[j + 1])
    if rotation:
        out = out / np.linalg.norm(out, axis=1, keepdims=True)
    return out


def node_matrix(n, what: str, data: GltfData) -> np.ndarray | None:
    """The node's 4 x 4 matrix (column-major in the file), None when it has none."""
    m = field_of(n, "matrix")
    if not m:
        return None
    try:
        a = np.array(m, float)
    except (TypeError, ValueError, OverflowError):
        a = np.zeros(0)
    if a.shape != (16,):
        raise data.error(f"{what} has a malformed matrix: glTF needs 16 numbers, got {json.dumps(m)[:80]}")
    return a.reshape(4, 4).T


def trs_matrices(t: np.ndarray, r: np.ndarray, s: np.ndarray) -> np.ndarray:
    """(F, 4, 4) matrices T @ R @ S from (F, 3) translations, (F, 4) unit quaternions (x, y, z, w)
    and (F, 3) scales."""
    m = np.zeros((len(t), 4, 4))
    m[:, :3, :3] = quats_to_matrices(r) * s[:, None, :]
    m[:, :3, 3] = t
    m[:, 3, 3] = 1.0
    return m


def rest_trs(n, path: str, what: str, data: GltfData) -> np.ndarray:
    """A node's rest translation, rotation (unit quaternion) or scale."""
    default = {"translation": [0.0, 0.0, 0.0], "rotation": [0.0, 0.0, 0.0, 1.0], "scale": [1.0, 1.0, 1.0]}[path]
    v = field_of(n, path) or default
    try:
        a = np.asarray(v, float).reshape(GLTF_TRS[path])
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


# --- animations ---------------------------------------------------------------------------------

#: {(node, path): Channel}: what one animation drives.
Channels = dict


@dataclass(frozen=True, eq=False)
class Channel:
    """One checked animation channel: key times (n,) strictly increasing, values (n or 3n, k)
    (CUBICSPLINE: in-tangent, value, out-tangent per key), its interpolation."""

    keys: np.ndarray
    values: np.ndarray
    interpolation: str

    def at(self, t: np.ndarray, rotation: bool = False) -> np.ndarray:
        """The channel's values at times t (len(t), k)."""
        return sample_channel(self.keys, self.values, self.interpolation, rotation, t)


def animation_label(g, ai: int) -> str:
    """How messages name animation `ai`: "animation 2 ('walk')", or "animation 2" without a name."""
    name = field_of((g.animations or [])[ai], "name")
    return f"animation {ai} ({name!r})" if isinstance(name, str) and name else f"animation {ai}"


def read_channels(g, data: GltfData, ai: int, nodes=None, weights: dict[int, int] | None = None,
                  label: str | None = None, check_targets: bool = False) -> Channels:
    """{(node, path): Channel} of animation `ai`'s translation, rotation and scale channels on
    `nodes` (None: every node), and with `weights` ({node: number of morph targets}) its morph
    weight channels on those nodes. Checked: indices, key counts, strictly increasing finite
    key times, value shapes, interpolation names; with `check_targets`, also every channel's
    target node (a node that does not exist, a weights channel on a node without morph
    targets). `label`: how messages name the animation (default "animation <ai>")."""
    anim = (g.animations or [])[ai]
    label = label or f"animation {ai}"
    node_count = len(g.nodes or [])
    out: Channels = {}
    samplers = field_of(anim, "samplers") or []
    for ci, ch in enumerate(field_of(anim, "channels") or []):
        tgt = field_of(ch, "target")
        node, prop = field_of(tgt, "node"), field_of(tgt, "path")
        if check_targets and prop in (*GLTF_TRS, "weights"):
            if not is_index(node) or node >= node_count:
                raise data.error(f"{label}: channel {ci} targets node {node!r}, which does not exist (the file has "
                                 f"{node_count})")
        wanted = prop in GLTF_TRS or (weights is not None and prop == "weights" and node in weights)
        if not wanted or (nodes is not None and node not in nodes):
            if check_targets and prop == "weights" and weights is not None and node not in weights:
                raise data.error(f"{label}: channel {ci} animates the morph weights of node {node}, whose mesh has no "
                                 "morph targets")
            continue
        si = field_of(ch, "sampler")
        what = f"{label} sampler {si}"
        if not is_index(si) or si >= len(samplers):
            raise data.error(f"{label}: a channel refers to sampler {si!r}, which does not exist")
        if (node, prop) in out:
            raise data.error(f"{label} has two channels for node {node} {prop}")
        smp = samplers[si]
        interp = field_of(smp, "interpolation") or "LINEAR"
        if interp not in GLTF_INTERPOLATIONS:
            raise data.error(f"{what}: interpolation {interp!r} is not supported (LINEAR, STEP or CUBICSPLINE)")
        keys = data.accessor(field_of(smp, "input"), f"{what} input")
        if keys.shape[1] != 1:
            raise data.error(f"{what}: key times must be a SCALAR accessor")
        keys = keys[:, 0]
        if len(keys) == 0:
            raise data.error(f"{what} has no keyframes")
        if np.any(np.diff(keys) <= 0):
            raise data.error(f"{what}: key times must increase strictly")
        values = data.accessor(field_of(smp, "output"), f"{what} output")
        per_key = 3 if interp == "CUBICSPLINE" else 1
        if prop == "weights":
            want = weights[node]
            if values.shape[1] != 1 or len(values) != per_key * len(keys) * want:
                raise data.error(f"{what}: weights of node {node} need {per_key * len(keys) * want} SCALAR values "
                                 f"({want} morph targets, {len(keys)} {interp} keys), got {len(values)} of "
                                 f"{values.shape[1]} components")
            values = values.reshape(-1, want)
        else:
            want = GLTF_TRS[prop]
            if values.shape[1] != want or len(values) != per_key * len(keys):
                raise data.error(f"{what}: {prop} needs {per_key * len(keys)} VEC{want} values for {len(keys)} "
                                 f"{interp} keys, got {len(values)} of {values.shape[1]} components")
        if prop == "rotation":
            v = values[1::3] if interp == "CUBICSPLINE" else values
            if np.any(np.linalg.norm(v, axis=1) == 0):
                raise data.error(f"{what}: a rotation key is the zero quaternion")
        out[(node, prop)] = Channel(keys, values, interp)
    return out


def time_span(channels: Channels) -> tuple[float, float]:
    """(first, last) key time over the channels."""
    return (min(float(c.keys[0]) for c in channels.values()), max(float(c.keys[-1]) for c in channels.values()))


def _repeated(a: np.ndarray, frames: int) -> np.ndarray:
    """(frames, *a.shape) read-only rows of a kept array a: a view (np.broadcast_to's cost is in
    Python, paid by every node at every frame)."""
    return a[None] if frames == 1 else np.broadcast_to(a, (frames, *a.shape))


class NodeTree:
    """The node hierarchy of a glTF file: parents checked (a child that does not exist, a cycle),
    and each node's world matrix at given times under an animation's channels."""

    def __init__(self, g, data: GltfData):
        self.g, self.data = g, data
        self.nodes = g.nodes or []
        self._fixed: dict[int, np.ndarray] = {}  # node -> its local matrix, where no channel drives it
        self._rest: dict[tuple, np.ndarray] = {}  # (node, path) -> its rest translation, rotation or scale
        self._animated: dict[tuple, tuple] = {}  # (id of channels, node) -> (channels, the paths they drive)
        self.parent: dict[int, int] = {}
        for i, n in enumerate(self.nodes):
            for c in field_of(n, "children") or []:
                if not is_index(c) or c >= len(self.nodes):
                    raise data.error(f"node {i} has child {json.dumps(c)}, but there is no such node "
                                     f"(the file has {len(self.nodes)})")
                self.parent[c] = i

    def chain(self, node: int) -> list[int]:
        """node, its parent, ..., its root."""
        out = [node]
        while out[-1] in self.parent:
            p = self.parent[out[-1]]
            if p in out:
                raise InputError(f"node hierarchy has a cycle through node {p}", self.data.path)
            out.append(p)
        return out

    def local(self, ni: int, channels: Channels, times: np.ndarray) -> np.ndarray:
        """(T, 4, 4) node ni's local matrix at `times` (T,) under `channels`."""
        n, what = self.nodes[ni], f"node {ni}"
        frames = len(times)
        key = (id(channels), ni)
        if key not in self._animated or self._animated[key][0] is not channels:
            self._animated[key] = (channels, {p for (node, p) in channels if node == ni and p in GLTF_TRS})
        animated = self._animated[key][1]
        if not animated and ni in self._fixed:
            return _repeated(self._fixed[ni], frames)
        fixed = node_matrix(n, what, self.data)
        if fixed is not None:
            if animated:
                raise self.data.error(f"animation targets {what}, which has a matrix (glTF allows only TRS there)")
            if not np.all(np.isfinite(fixed)):
                raise self.data.error(f"{what} has a non-finite matrix")
            fixed.setflags(write=False)
            self._fixed[ni] = fixed
            return _repeated(fixed, frames)
        trs = {}
        for p in ("translation", "rotation", "scale"):
            if p in animated:
                trs[p] = channels[(ni, p)].at(times, p == "rotation")
            else:
                if (ni, p) not in self._rest:
                    a = rest_trs(n, p, what, self.data)
                    a.setflags(write=False)
                    self._rest[(ni, p)] = a
                trs[p] = _repeated(self._rest[(ni, p)], frames)
        m = trs_matrices(trs["translation"], trs["rotation"], trs["scale"])
        if not animated:
            m.setflags(write=False)
            self._fixed[ni] = m[0]
        return m

    def world(self, node: int, channels: Channels, times: np.ndarray, cache: dict | None = None) -> np.ndarray:
        """(T, 4, 4) node's world matrix at `times`: L_root @ ... @ L_node. `cache` ({node:
        matrices}) keeps the ancestors' matrices for other nodes at the same times."""
        cache = {} if cache is None else cache
        todo = []
        for ni in self.chain(node):
            if ni in cache:
                break
            todo.append(ni)
        world = cache[self.parent[todo[-1]]] if todo and todo[-1] in self.parent else None
        if not todo:
            return cache[node]
        for ni in reversed(todo):
            local = self.local(ni, channels, times)
            with np.errstate(over="ignore", invalid="ignore"):  # (callers say it in one line)
                world = local if world is None else world @ local
            cache[ni] = world
        return cache[node]


def frame_times(t0: float, t1: float, fps: float, max_frames: int, what: str, path) -> np.ndarray:
    """Times t0 + k / fps for k = 0, 1, ... while at most t1 (up to float32 rounding of key times)."""
    count = int(math.floor((t1 - t0) * fps + 1e-4 + 1e-6 * max(abs(t0), abs(t1)) * fps)) + 1
    if count > max_frames:
        raise InputError(f"{what} spans {t1 - t0:g} s: {count} frames at {fps:g} fps (more than {max_frames})", path)
    return t0 + np.arange(count) / fps
