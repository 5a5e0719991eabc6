"""Animated glTF scenes made with pygltflib for the tests and benchmarks: a mesh on a turntable (a
node rotation), the same mesh still, and a skinned tube bent by its second joint. Import as
`from animated import ...` (tests/) or with tests/ on sys.path (benchmarks/)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pygltflib


class Doc:
    """A glTF document under construction, its arrays packed into one GLB binary chunk."""

    def __init__(self):
        self.blob = bytearray()
        self.g = pygltflib.GLTF2(asset=pygltflib.Asset(version="2.0"), scene=0, scenes=[pygltflib.Scene(nodes=[])],
                                 nodes=[], meshes=[], accessors=[], bufferViews=[], buffers=[], animations=[],
                                 skins=[], materials=[])

    def accessor(self, arr, kind: str, component: int = 5126, target=None) -> int:
        dtype = {5126: np.float32, 5125: np.uint32, 5123: np.uint16, 5121: np.uint8}[component]
        a = np.asarray(arr, dtype)
        rows = a.reshape(len(a), -1)
        while len(self.blob) % 4:
            self.blob.append(0)
        raw = rows.tobytes()
        self.g.bufferViews.append(pygltflib.BufferView(buffer=0, byteOffset=len(self.blob), byteLength=len(raw),
                                                       target=target))
        self.blob += raw
        kw = {}
        if component == 5126 and kind in ("VEC3", "SCALAR") and np.isfinite(rows).all():
            kw = {"min": rows.min(0).tolist(), "max": rows.max(0).tolist()}
        self.g.accessors.append(pygltflib.Accessor(bufferView=len(self.g.bufferViews) - 1, componentType=component,
                                                   count=len(rows), type=kind, **kw))
        return len(self.g.accessors) - 1

    def mesh(self, vertices, faces, **attributes) -> int:
        """A one-primitive mesh (positions float32, indices uint32); `attributes`: more accessors."""
        if not self.g.materials:
            self.g.materials.append(pygltflib.Material(name="clay", pbrMetallicRoughness=pygltflib.PbrMetallicRoughness(
                baseColorFactor=[0.8, 0.8, 0.8, 1.0])))
        pos = self.accessor(vertices, "VEC3", target=34962)
        idx = self.accessor(np.asarray(faces).reshape(-1), "SCALAR", component=5125, target=34963)
        self.g.meshes.append(pygltflib.Mesh(primitives=[pygltflib.Primitive(
            attributes=pygltflib.Attributes(POSITION=pos, **attributes), indices=idx, material=0)]))
        return len(self.g.meshes) - 1

    def node(self, parent: int | None = None, **kw) -> int:
        self.g.nodes.append(pygltflib.Node(**kw))
        i = len(self.g.nodes) - 1
        if parent is None:
            self.g.scenes[0].nodes.append(i)
        else:
            p = self.g.nodes[parent]
            p.children = (p.children or []) + [i]
        return i

    def animate(self, channels, name: str | None = None) -> None:
        """One animation; channels (node, path, key times, values)."""
        anim = pygltflib.Animation(channels=[], samplers=[], name=name)
        for node, path, times, values in channels:
            kind = {"rotation": "VEC4", "weights": "SCALAR"}.get(path, "VEC3")
            inp = self.accessor(np.asarray(times, float), "SCALAR")
            out = self.accessor(np.asarray(values, float), kind)
            anim.samplers.append(pygltflib.AnimationSampler(input=inp, output=out, interpolation="LINEAR"))
            anim.channels.append(pygltflib.AnimationChannel(
                sampler=len(anim.samplers) - 1, target=pygltflib.AnimationChannelTarget(node=node, path=path)))
        self.g.animations.append(anim)

    def save(self, path: Path) -> Path:
        blob = bytes(self.blob) + b"\0" * (-len(self.blob) % 4)
        self.g.buffers = [pygltflib.Buffer(byteLength=len(blob))]
        self.g.set_binary_blob(blob)
        self.g.save_binary(str(path))
        return Path(path)


def yaw_quat(deg: float) -> list[float]:
    """The unit quaternion (x, y, z, w) of a rotation by `deg` degrees about +Y."""
    h = math.radians(deg) / 2
    return [0.0, math.sin(h), 0.0, math.cos(h)]


def turntable_glb(path: Path, vertices, faces, frames: int = 120, fps: float = 24.0, deg_per_frame: float = 3.0,
                  animated: bool = True) -> Path:
    """The mesh on a turntable: one node turning about +Y by `deg_per_frame` a frame (a key per
    frame, frames + 1 keys), or (`animated` False) the same file without its animation."""
    d = Doc()
    m = d.mesh(vertices, faces)
    n = d.node(mesh=m, name="turntable")
    if animated:
        k = np.arange(frames + 1)
        d.animate([(n, "rotation", k / fps, [yaw_quat(deg_per_frame * i) for i in k])], name="turn")
    return d.save(path)


def yaw_matrix(deg: float) -> np.ndarray:
    """(3, 3) rotation by `deg` degrees about +Y."""
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def tube(rings: int = 24, sides: int = 16, length: float = 4.0, radius: float = 0.5):
    """(vertices, faces) of a closed tube along +Y from 0 to `length` (caps fanned from a centre)."""
    ys = np.linspace(0.0, length, rings)
    a = 2 * np.pi * np.arange(sides) / sides
    ring = np.stack([radius * np.cos(a), np.zeros(sides), -radius * np.sin(a)], axis=1)
    V = np.concatenate([ring + [0.0, y, 0.0] for y in ys] + [[[0.0, 0.0, 0.0]], [[0.0, length, 0.0]]])
    F = []
    for r in range(rings - 1):
        for s in range(sides):
            a0, a1 = r * sides + s, r * sides + (s + 1) % sides
            b0, b1 = a0 + sides, a1 + sides
            F += [[a0, a1, b1], [a0, b1, b0]]
    bottom, top = rings * sides, rings * sides + 1
    for s in range(sides):
        F.append([bottom, (s + 1) % sides, s])
        t0, t1 = (rings - 1) * sides + s, (rings - 1) * sides + (s + 1) % sides
        F.append([top, t0, t1])
    return V, np.asarray(F, np.int64)


def tube_weights(V: np.ndarray, length: float = 4.0) -> np.ndarray:
    """(V, 2) skin weights of joints 0 (base) and 1 (middle): 1, 0 below a third of the length,
    0, 1 above two thirds, blended linearly between."""
    w1 = np.clip((V[:, 1] / length - 1 / 3) * 3, 0.0, 1.0)
    return np.stack([1 - w1, w1], axis=1)


def bend_quat(deg: float) -> list[float]:
    """The unit quaternion of a rotation by `deg` degrees about +Z."""
    h = math.radians(deg) / 2
    return [0.0, 0.0, math.sin(h), math.cos(h)]


def skinned_tube_glb(path: Path, frames: int = 24, fps: float = 24.0, max_bend: float = 60.0, length: float = 4.0
                     ) -> Path:
    """A skinned tube: joint 0 at the base (the scene's root), joint 1 at half the length, its
    child, bent about +Z from 0 to `max_bend` degrees over `frames` frames (a key per frame). The
    inverse bind matrices undo the joints' rest translations."""
    V, F = tube(length=length)
    W = tube_weights(V, length)
    d = Doc()
    joints = np.zeros((len(V), 4), np.uint16)
    joints[:, 1] = 1
    weights = np.zeros((len(V), 4))
    weights[:, :2] = W
    ja = d.accessor(joints, "VEC4", component=5123)
    wa = d.accessor(weights, "VEC4")
    m = d.mesh(V, F, JOINTS_0=ja, WEIGHTS_0=wa)
    root = d.node(name="root")
    mid = d.node(parent=root, name="middle", translation=[0.0, length / 2, 0.0])
    ibm = np.stack([np.eye(4), np.eye(4)])
    ibm[1, 1, 3] = -length / 2
    ib = d.accessor(ibm.transpose(0, 2, 1).reshape(2, 16), "MAT4")
    d.g.skins.append(pygltflib.Skin(joints=[root, mid], inverseBindMatrices=ib, skeleton=root))
    d.node(mesh=m, skin=0, name="tube")
    k = np.arange(frames + 1)
    d.animate([(mid, "rotation", k / fps, [bend_quat(max_bend * i / frames) for i in k])], name="bend")
    return d.save(path)


def skinned_tube_vertices(t: float, fps: float = 24.0, frames: int = 24, max_bend: float = 60.0,
                          length: float = 4.0) -> np.ndarray:
    """The tube's vertices at time t, skinned here (linear blend of the two joints' matrices, the
    joint 1 angle interpolated linearly between its keys): the reference for the reader's pose."""
    V, _ = tube(length=length)
    V = V.astype(np.float32).astype(float)  # (as the file holds them)
    W = tube_weights(V, length).astype(np.float32).astype(float)
    deg = max_bend * min(max(t * fps / frames, 0.0), 1.0)
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    pivot = np.array([0.0, length / 2, 0.0])
    bent = (V - pivot) @ R.T + pivot
    return W[:, :1] * V + W[:, 1:2] * bent


def sphere_and_box_glb(path: Path, moving: str) -> Path:
    """A still box over an icosphere of 5120 faces (their x ranges overlap); `moving` turns the sphere (a rigid object
    that keeps its BVH) or the box (a small one, built again each frame, beside the sphere's kept
    still BVH)."""
    import trimesh

    sph = trimesh.creation.icosphere(subdivisions=4, radius=1.0)
    box = trimesh.creation.box(extents=(0.8, 0.8, 0.8))
    d = Doc()
    a = d.node(mesh=d.mesh(np.asarray(sph.vertices), np.asarray(sph.faces)), name="sphere")
    b = d.node(mesh=d.mesh(np.asarray(box.vertices), np.asarray(box.faces)), name="box", translation=[0.2, 1.55, 0.3])
    turned = a if moving == "sphere" else b
    k = np.arange(13)
    d.animate([(turned, "rotation", k / 24, [[0.0, math.sin(math.radians(5 * i)), 0.0, math.cos(math.radians(5 * i))]
                                             for i in k])])
    return d.save(path)
