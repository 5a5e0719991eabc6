"""Textured ribbons of the strokes as binary glTF (GLB), for Blender and any glTF viewer.

One GLB per frame (`glb_for_frame`): a node "camera" holding the frame's camera (opening the file
shows the same view) and a node "strokes_0001" (frame number) with one mesh, one primitive per
line kind (one material each, tinted like the SVG layers). A sequence GLB (`glb_for_sequence`):
one node "frame_0001", ... per frame under a node "strokes", each shown only on its own frame by
STEP scale keys (0 -> 1 -> 0: the baseline every importer understands), and the camera node
moved by STEP translation/rotation keys; all channels in one animation named "sequence". Key
time = frame number / fps, so Blender's frame N shows our frame N. glTF cameras cannot animate
their field of view without extensions: the sequence's camera keeps the first frame's lens.
Image space ("image"): a fixed orthographic camera looking at the pixel rectangle.

Layout of a primitive:
- POSITION (float32): world units relative to the node's translation (keeps float32 precision
  far from the origin), or pixels (x, H - y, 0) in image space;
- TEXCOORD_0: brush texture coordinates (strokekit.ribbons: head | body | tail along u,
  v = 0 / 0.5 / 1 across);
- TEXCOORD_1: (level, level_weight) of each stroke's self-similar octave, constant along the
  stroke (the material does not use it: it is there for custom shaders);
- extras: {"kind": name, "strokes": {"id", "first_triangle", "triangle_count", "level",
  "level_weight"}}: stroke s of the primitive owns triangles [first, first + count) of its indices.

Material: KHR_materials_unlit (not required: viewers without it fall back on the PBR block,
metallic 0, roughness 1), double sided, alpha BLEND (or MASK with a cutoff), base colour
texture = the brush PNG embedded in a buffer view (every buffer view starts 4-byte aligned).
No timestamps or versions inside: the same strokes give the same bytes.
"""

from __future__ import annotations

import json
import math
import struct
from dataclasses import replace

import numpy as np

from strokekit.camera.view import Camera
from strokekit.colour import srgb_decode
from strokekit.errors import UsageError
from strokekit.model import KINDS, N_KINDS, Strokes, layer_name
from strokekit.ribbons.brushes import get_brush
from strokekit.ribbons.mesh import RibbonMesh, build_ribbons
from strokekit.style.linesets import KIND_COLORS
from strokekit.style.widths import StyledStrokes
from strokekit.writers.options import GltfOptions, hex_srgb


def _hex_rgba(c: str) -> list[float]:
    """#rrggbb (sRGB, as in the SVG) -> linear RGBA, as glTF's baseColorFactor is: a factor written
    unconverted drew the ribbons lighter than the SVG's lines (#b3261e came out as (218, 108, 96))."""
    return [float(x) for x in srgb_decode(hex_srgb(c))] + [1.0]


# --- document building ----------------------------------------------------------------------------

_FLOAT, _USHORT, _UINT = 5126, 5123, 5125
_ARRAY, _ELEMENTS = 34962, 34963


def _bounds(a: np.ndarray) -> tuple[list[float], list[float]]:
    """Per-column min and max of (n, k) as lists; column by column (numpy reduces a strided axis 0
    of a narrow array an order of magnitude slower)."""
    return ([float(a[:, i].min()) for i in range(a.shape[1])], [float(a[:, i].max()) for i in range(a.shape[1])])


class _Doc:
    """A glTF document (plain JSON-ready dicts: pygltflib's serializer costs more than the whole
    ribbon build) and its single binary buffer, grown piece by piece."""

    def __init__(self, opts: GltfOptions):
        self.opts = opts
        self.j: dict = {"asset": {"generator": "strokekit", "version": "2.0"}, "scene": 0}
        self.parts: list[bytes] = []
        self.length = 0
        self.brush = get_brush(opts.brush)
        self.texture: int | None = None
        self.materials: dict[int, int] = {}

    def add(self, key: str, obj: dict) -> int:
        lst = self.j.setdefault(key, [])
        lst.append(obj)
        return len(lst) - 1

    def view(self, data: bytes, target: int | None = None) -> int:
        pad = (-self.length) % 4  # every buffer view starts 4-byte aligned
        if pad:
            self.parts.append(b"\0" * pad)
            self.length += pad
        bv = {"buffer": 0, "byteOffset": self.length, "byteLength": len(data)}
        if target is not None:
            bv["target"] = target
        self.parts.append(data)
        self.length += len(data)
        return self.add("bufferViews", bv)

    def accessor(self, a: np.ndarray, type_: str, target: int | None = _ARRAY, minmax: bool = False) -> int:
        if a.dtype == np.uint16:
            ct = _USHORT
        elif a.dtype == np.uint32:
            ct = _UINT
        else:
            a, ct = a.astype("<f4"), _FLOAT
        a = np.ascontiguousarray(a)
        count = a.shape[0] if type_ != "SCALAR" else a.size
        acc = {"bufferView": self.view(a.tobytes(), target), "componentType": ct, "count": int(count), "type": type_}
        if minmax:  # bounds of the float32 values actually stored
            flat = a.reshape(count, -1)
            acc["min"], acc["max"] = _bounds(flat)
        return self.add("accessors", acc)

    def material(self, kind: int, line_set: str | None = None, colour: str | None = None) -> int:
        """The material of a kind code's ribbons (named as its SVG layer), or of one line set's
        ribbons of that kind (named <layer>--<set>, in the set's colour)."""
        key = (kind, line_set)
        if key in self.materials:
            return self.materials[key]
        if self.texture is None:
            img = self.add("images", {"bufferView": self.view(self.brush.png), "mimeType": "image/png",
                                      "name": self.brush.name})
            smp = self.add("samplers", {"magFilter": 9729, "minFilter": 9987, "wrapS": 33071, "wrapT": 33071})
            self.texture = self.add("textures", {"source": img, "sampler": smp})
        name = layer_name(kind) if 0 <= kind else f"kind{kind}"  # (hidden-<kind> for hidden lines)
        if line_set is not None:
            name = f"{name}--{line_set}"
        if self.opts.color is not None:
            rgba = _hex_rgba(self.opts.color)
        elif colour is not None and self.brush.tinted:
            rgba = _hex_rgba(colour)
        elif self.brush.tinted:
            rgba = _hex_rgba(KIND_COLORS.get(name.removeprefix("hidden-"), "#000000"))
        else:
            rgba = [1.0, 1.0, 1.0, 1.0]
        m = {"name": name, "doubleSided": True, "alphaMode": self.opts.alpha_mode,
             "pbrMetallicRoughness": {"baseColorFactor": rgba, "baseColorTexture": {"index": self.texture},
                                      "metallicFactor": 0.0, "roughnessFactor": 1.0}}
        if self.opts.alpha_mode == "MASK":
            m["alphaCutoff"] = self.opts.alpha_cutoff
        if self.opts.unlit:
            m["extensions"] = {"KHR_materials_unlit": {}}
            used = self.j.setdefault("extensionsUsed", [])
            if "KHR_materials_unlit" not in used:
                used.append("KHR_materials_unlit")
        self.materials[key] = self.add("materials", m)
        return self.materials[key]

    def ribbon_node(self, mesh: RibbonMesh, name: str, styled: StyledStrokes | None = None) -> int:
        """A node holding the ribbons (one primitive per line kind, or per line kind and line set
        of `styled`, the strokes' style: their order is the mesh's); no mesh when there are none."""
        node: dict = {"name": name}
        if len(mesh.indices):
            origin = np.zeros(3)
            if mesh.space == "world":
                lo, hi = _bounds(mesh.positions)
                origin = np.round(0.5 * (np.array(lo) + np.array(hi)), 6)
                node["translation"] = [float(x) for x in origin]
            pos = mesh.positions - origin
            vo, to = mesh.vertex_offsets, mesh.triangle_offsets
            tcount_all = np.diff(to)
            # strokes come grouped by kind (ribbons_for): each kind is one slice of vertices and triangles
            group = mesh.kind.astype(np.int64) + (0 if styled is None else 1024 * styled.lineset)
            _, first = np.unique(group, return_index=True)
            last = np.r_[first[1:], len(mesh.kind)]
            prims = []
            for a, b in zip(first, last):
                k = mesh.kind[a]
                v0, v1, t0, t1 = vo[a], vo[b], to[a], to[b]
                if t1 == t0:
                    continue
                nv = int(v1 - v0)
                idx = (mesh.indices[t0:t1] - v0).ravel().astype(np.uint16 if nv < 65535 else np.uint32)
                strokes_k = a + np.nonzero(tcount_all[a:b] > 0)[0]
                tcount = tcount_all[strokes_k]
                attrs = {"POSITION": self.accessor(pos[v0:v1], "VEC3", minmax=True),
                         "TEXCOORD_0": self.accessor(mesh.uv[v0:v1], "VEC2")}
                if self.opts.level_texcoord:
                    attrs["TEXCOORD_1"] = self.accessor(mesh.level_uv[v0:v1], "VEC2")
                extras = {"kind": KINDS[k % N_KINDS] if 0 <= k else int(k),
                          **({"occlusion": int(k) // N_KINDS} if k >= N_KINDS else {}),
                          "strokes": {"id": mesh.ids[strokes_k].tolist(),
                                      "first_triangle": (np.cumsum(tcount) - tcount).tolist(),
                                      "triangle_count": tcount.tolist(),
                                      "level": mesh.level[strokes_k].tolist(),
                                      "level_weight": mesh.level_weight[strokes_k].tolist()}}
                indices = self.accessor(idx, "SCALAR", _ELEMENTS)  # (before the material's texture)
                if styled is None:
                    material = self.material(int(k))
                else:
                    ls = int(styled.lineset[a])
                    extras["lineset"] = styled.sets[ls].name
                    material = self.material(int(k), styled.sets[ls].name, styled.color(ls, KINDS[int(k) % N_KINDS]))
                prims.append({"attributes": attrs, "indices": indices, "material": material, "mode": 4,
                              "extras": extras})
            node["mesh"] = self.add("meshes", {"name": name, "primitives": prims})
        return self.add("nodes", node)

    def camera_node(self, camera: Camera, depths: tuple[float, float] | None = None) -> int:
        """The frame's camera: a glTF camera looks down its local -Z with +Y up. `depths`: the
        (nearest, farthest) view depth of the ribbons it shows (world units), which the clip
        planes must hold: from the eye-target distance alone, a camera 0.2 units from a nose
        with its target 400 units away clipped the ribbons nearer than 0.4."""
        aspect = camera.width / camera.height
        if self.opts.space == "image":
            d = float(max(camera.width, camera.height))
            cam = {"type": "orthographic", "name": "image", "orthographic": {
                "xmag": camera.width / 2.0, "ymag": camera.height / 2.0, "znear": 0.01 * d, "zfar": 2.0 * d}}
            node = {"name": "camera", "translation": [camera.width / 2.0, camera.height / 2.0, d]}
        else:
            dist = float(np.linalg.norm(np.subtract(camera.target, camera.eye)))
            if camera.is_ortho:
                h = camera.ortho_height / 2.0
                zfar = 100.0 * dist if depths is None else max(100.0 * dist, 2.0 * depths[1])
                znear = float(camera.near) if camera.near else 0.0  # a section's near plane, as in perspective
                if depths is not None and znear > 0:
                    znear = min(znear, 0.999 * max(depths[0], 0.0))
                cam = {"type": "orthographic", "name": "camera", "orthographic": {
                    "xmag": h * aspect, "ymag": h, "znear": znear, "zfar": zfar}}
            else:
                znear = float(camera.near) if camera.near else 1e-3 * dist
                if depths is not None and depths[0] > 0:
                    # A near plane the camera gives is the drawing's section: a viewer must cut the
                    # scene there too, so it goes only as far below as a ribbon needs (ribbons of
                    # clipped edges sit on it, pulled a little toward the eye).
                    znear = min(znear, (0.999 if camera.near else 0.5) * depths[0])
                cam = {"type": "perspective", "name": "camera", "perspective": {
                    "aspectRatio": aspect, "yfov": math.radians(camera.fov_y), "znear": znear}}
            node = {"name": "camera", "translation": [float(x) for x in _camera_position(camera)],
                    "rotation": _camera_quat(camera)}
            if camera.projection not in ("perspective", "orthographic"):
                # glTF knows perspective and orthographic cameras only: an axonometric view is an
                # orthographic camera (the one above, exact); an oblique one has no glTF form: the
                # camera above is its image plane seen straight on, centred on the target.
                cam["extras"] = {"projection": camera.projection, "azimuth": camera.azimuth,
                                 "elevation": camera.elevation}
                if camera.is_oblique:
                    cam["extras"].update({"oblique_angle": camera.oblique_angle, "receding_shear": list(camera.shear),
                                          "note": "glTF has no oblique projection: the drawing is sheared by "
                                                  "receding_shear x depth; this camera is its unsheared front view"})
        node["camera"] = self.add("cameras", cam)
        return self.add("nodes", node)

    def glb(self, roots: list[int]) -> bytes:
        self.j["scenes"] = [{"name": "strokes", "nodes": roots}]
        blob = b"".join(self.parts)
        blob += b"\0" * ((-len(blob)) % 4)
        if blob:
            self.j["buffers"] = [{"byteLength": len(blob)}]
        js = json.dumps(self.j, separators=(",", ":")).encode("utf-8")
        js += b" " * ((-len(js)) % 4)
        chunks = [struct.pack("<I4s", len(js), b"JSON"), js]
        if blob:
            chunks += [struct.pack("<I4s", len(blob), b"BIN\0"), blob]
        body = b"".join(chunks)
        return struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body


def _camera_position(camera: Camera) -> np.ndarray:
    """Where the glTF camera node stands: the eye, but for an oblique projection (whose eye is on
    its slanted ray through the target) the point as far before the target straight along fwd."""
    if not camera.is_oblique:
        return np.asarray(camera.eye, float)
    _, _, fwd = camera.basis
    depth = float(np.subtract(camera.target, camera.eye) @ fwd)
    return np.asarray(camera.target, float) - depth * fwd


def _camera_quat(camera: Camera) -> list[float]:
    """glTF rotation (x, y, z, w) taking local +X, +Y, -Z to right, up, fwd."""
    right, up, fwd = camera.basis
    m = np.stack([right, up, -fwd], axis=1)
    tr = np.trace(m)
    if tr > 0:
        s = math.sqrt(tr + 1.0) * 2
        q = [(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, 0.25 * s]
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2]) * 2
        q = [0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s, (m[2, 1] - m[1, 2]) / s]
    elif m[1, 1] > m[2, 2]:
        s = math.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2]) * 2
        q = [(m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s, (m[0, 2] - m[2, 0]) / s]
    else:
        s = math.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1]) * 2
        q = [(m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s, (m[1, 0] - m[0, 1]) / s]
    q = np.array(q)
    q /= np.linalg.norm(q)
    if q[3] < 0:  # one sign for the same rotation: deterministic and smooth keys
        q = -q
    return [float(x) for x in q]


def by_kind(strokes: Strokes, styled: StyledStrokes | None = None) -> tuple[Strokes, StyledStrokes | None]:
    """The same strokes reordered so each line kind (and with `styled`, the strokes in their
    style, each of its line sets within a kind) is one run (stable: chain order kept inside);
    one primitive per run is then a slice of the ribbon arrays. Returns the strokes and their
    style in that order."""
    key = strokes.kind.astype(np.int64) + (0 if styled is None else 1024 * styled.lineset)
    order = np.argsort(key, kind="stable")
    if np.all(order == np.arange(len(order))):
        return strokes, styled
    counts = np.diff(strokes.offsets)[order]
    starts = strokes.offsets[:-1][order]
    new_off = np.r_[0, np.cumsum(counts)].astype(np.int64)
    pidx = np.repeat(starts - new_off[:-1], counts) + np.arange(new_off[-1])
    out = replace(strokes, points=strokes.points[pidx], surface=strokes.surface[pidx], face=strokes.face[pidx],
                  u=strokes.u[pidx], offsets=new_off, kind=strokes.kind[order], ids=strokes.ids[order],
                  level=strokes.level[order], level_weight=strokes.level_weight[order])
    if styled is not None:
        styled = replace(styled, strokes=out, width=styled.width[pidx], lineset=styled.lineset[order])
    return out, styled


def drawn(strokes: Strokes | StyledStrokes) -> tuple[Strokes, StyledStrokes | None]:
    """(strokes, their style) of a frame's strokes, or of its strokes in their style: a style
    with line sets gives the ribbons their widths and colours; the default style leaves them the
    ribbons' own (GltfOptions: --ribbon-width, --taper)."""
    if isinstance(strokes, StyledStrokes):
        return strokes.strokes, (None if strokes.style.is_default else strokes)
    return strokes, None


def ribbons_for(strokes: Strokes | StyledStrokes, camera: Camera | None, options: GltfOptions,
                surface_depth=None) -> RibbonMesh:
    """The ribbons a GLB holds: strokes grouped by kind (and line set), geometry per options and
    brush, widths the style's when it has line sets (surface_depth: see ribbons.build_ribbons)."""
    return styled_ribbons(strokes, camera, options, surface_depth)[0]


def styled_ribbons(strokes: Strokes | StyledStrokes, camera: Camera | None, options: GltfOptions, surface_depth=None
                   ) -> tuple[RibbonMesh, StyledStrokes | None]:
    """ribbons_for's ribbons and the strokes' style in their order (None without line sets)."""
    brush = get_brush(options.brush)
    st, styled = by_kind(*drawn(strokes))
    widths = styled.width if styled is not None else None
    return build_ribbons(st, camera, options.ribbon_options(brush), surface_depth, widths=widths), styled


def glb_for_frame(strokes: Strokes | StyledStrokes, camera: Camera | None = None, options: GltfOptions | None = None,
                  surface_depth=None) -> bytes:
    """GLB bytes of one frame: its camera and its strokes (or its strokes in their style: see
    `drawn`) as textured ribbons. `surface_depth` (raster.surface_depth_at(occluder)) lays world
    ribbons on the scene's surface where it comes nearer than the stroke (see
    ribbons.build_ribbons)."""
    opts = options if options is not None else GltfOptions()
    st = drawn(strokes)[0]
    cam = camera if camera is not None else st.camera
    if cam is None:
        raise UsageError("glTF output needs the frame's camera")
    doc = _Doc(opts)
    mesh, styled = styled_ribbons(strokes, cam, opts, surface_depth)
    strokes_node = doc.ribbon_node(mesh, f"strokes_{int(st.frame):04d}", styled)
    cam_node = doc.camera_node(cam, _depth_range([(cam, mesh)]))
    return doc.glb([cam_node, strokes_node])


def glb_for_sequence(frames: list[Strokes | StyledStrokes], options: GltfOptions | None = None,
                     surface_depth=None) -> bytes:
    """One GLB for a sequence: one node per frame (each Strokes carries its camera and frame number;
    or a frame's strokes in their style, see `drawn`), shown only on its frame (STEP scale keys),
    the camera moved by STEP keys, at options.fps."""
    opts = options if options is not None else GltfOptions()
    styles = frames
    frames = [drawn(f)[0] for f in frames]
    if not frames:
        raise UsageError("a glTF sequence needs at least one frame")
    if any(f.camera is None for f in frames):
        raise UsageError("glTF output needs every frame's camera")
    doc = _Doc(opts)
    nums = np.array([int(f.frame) for f in frames])
    # key time = frame number / fps, so an importer's frame N (Blender: time x fps) is our frame N;
    # frames out of order or negative fall back on their list position
    ok = np.all(np.diff(nums) > 0) and nums[0] >= 0
    times = (nums if ok else np.arange(len(frames))) / float(opts.fps)
    n = len(frames)
    children, meshes = [], []
    for f, given in zip(frames, styles):
        mesh, styled = styled_ribbons(given, f.camera, opts, surface_depth)
        meshes.append((f.camera, mesh))
        children.append(doc.ribbon_node(mesh, f"frame_{int(f.frame):04d}", styled))
    anim: dict = {"name": "sequence", "channels": [], "samplers": []}
    if n > 1:
        for i, node in enumerate(children):
            t_keys, s_keys = [], []
            if i > 0:  # hidden from time 0 (importers hold the first key before it)
                t_keys.append(0.0), s_keys.append(0.0)
            t_keys.append(times[i]), s_keys.append(1.0)
            if i < n - 1:
                t_keys.append(times[i + 1]), s_keys.append(0.0)
            doc.j["nodes"][node]["scale"] = [1.0, 1.0, 1.0] if i == 0 else [0.0, 0.0, 0.0]
            _channel(doc, anim, node, "scale", np.array(t_keys), np.repeat(np.array(s_keys)[:, None], 3, 1))
    root_i = doc.add("nodes", {"name": "strokes", "children": children})
    cam_node = doc.camera_node(frames[0].camera, _depth_range(meshes))
    if n > 1 and opts.space == "world":
        eyes = np.array([_camera_position(f.camera) for f in frames], float)
        quats = np.array([_camera_quat(f.camera) for f in frames])
        for k in range(1, n):  # shortest path between consecutive keys
            if np.dot(quats[k], quats[k - 1]) < 0:
                quats[k] = -quats[k]
        _channel(doc, anim, cam_node, "translation", times, eyes)
        _channel(doc, anim, cam_node, "rotation", times, quats)
    if anim["channels"]:
        doc.add("animations", anim)
    return doc.glb([cam_node, root_i])


def _depth_range(meshes: list[tuple[Camera, RibbonMesh]]) -> tuple[float, float] | None:
    """(nearest, farthest) view depth of world ribbons, each seen from its frame's camera (None:
    no ribbon, or image-space ribbons)."""
    z = [cam.depth(m.positions) for cam, m in meshes if m.space == "world" and len(m.positions)]
    if not z:
        return None
    z = np.concatenate(z)
    return float(z.min()), float(z.max())


def _key_times(t: np.ndarray) -> np.ndarray:
    """Key times as float32 no later than the exact times: float32(N / fps) rounds up for many N
    (1, 2, 4, 8, 11, 13 at 24 fps), and a player sampling a STEP track at exactly N / fps then
    showed frame N - 1."""
    t = np.asarray(t, float)
    t32 = t.astype(np.float32)
    late = t32.astype(float) > t
    t32[late] = np.nextafter(t32[late], np.float32(-np.inf))
    return t32


def _channel(doc: _Doc, anim: dict, node: int, path: str, t: np.ndarray, values: np.ndarray) -> None:
    inp = doc.accessor(_key_times(t), "SCALAR", target=None, minmax=True)
    out = doc.accessor(np.asarray(values, float), "VEC4" if path == "rotation" else "VEC3", target=None)
    anim["samplers"].append({"input": inp, "output": out, "interpolation": "STEP"})
    anim["channels"].append({"sampler": len(anim["samplers"]) - 1, "target": {"node": node, "path": path}})
