"""Scenes that move: a glTF file's node animations, skins and morph targets (`SceneMotion`), the
scene they pose at a time (`SceneMotion.posed`), and where each object is in it (`ScenePose`: a
world point's object and its point in the object's own frame, and back, so that a surface point
moves with its object from frame to frame).

A posed scene is the scene a static file of the posed vertices would give (the same weld, the
same vertex and face order): every stage draws it as it draws any scene. Only what moves is
posed: a part whose nodes no channel drives keeps its rest vertices."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from strokekit.animation import (
    GLTF_TRS,
    Channels,
    GltfData,
    NodeTree,
    animation_label,
    field_of,
    is_index,
    load_gltf,
    read_channels,
    time_span,
)
from strokekit.errors import InputError
from strokekit.scene.tables import (
    bounds_of,
    dihedral_cos_of,
    face_corners_of,
    face_crosses_of,
    face_normals_of,
    face_offsets_of,
    same_rows,
)
from strokekit.scene.weld import Welded, weld

#: How a part moves under an animation: not at all (its rest vertices), rigidly (its node's
#: world matrix), or deforming (skinned or morphed).
STATIC, RIGID, DEFORMING = "static", "rigid", "deforming"


@dataclass(frozen=True)
class AnimationInfo:
    """One animation of the file: its index, name ("" when it has none), and the span of its key
    times in seconds."""

    index: int
    name: str
    start: float
    end: float

    @property
    def label(self) -> str:
        return f"{self.index} ({self.name})" if self.name else str(self.index)


@dataclass(frozen=True, eq=False)
class Skin:
    """A skinned part: joints (J,) node ids, inverse bind matrices (J, 4, 4), per vertex its
    joint slots (n, K) (indices into joints) and weights (n, K)."""

    joints: np.ndarray
    inverse_bind: np.ndarray
    joint: np.ndarray
    weight: np.ndarray


@dataclass(frozen=True, eq=False)
class Part:
    """One glTF primitive instance of the scene (one scene object): its node and primitive, its
    rows of the scene's input vertices and faces, whether its rest transform mirrors, its
    vertices in its mesh's own frame, its morph targets (T, n, 3) with their default weights,
    its skin."""

    node: int
    primitive: int
    vertices: slice
    faces: slice
    mirrored: bool
    mesh_vertices: np.ndarray
    targets: np.ndarray | None = None
    weights: np.ndarray | None = None
    skin: Skin | None = None


@dataclass(frozen=True, eq=False)
class ScenePose:
    """Where the objects of a posed scene are. matrix (O, 4, 4): each object's world matrix
    (object frame -> world) at this time; deforming: the objects whose mesh deforms, each with
    its posed input vertices (n, 3); parts, file_faces: the motion's parts and input faces;
    face_file (F,): the input face of each scene face (None: the rest scene's faces); time: the
    time in seconds.

    A deforming object's own frame is its mesh's (bind pose): a point on it is carried by its
    barycentric coordinates on its face (and its height over the face, in units of the face's
    size)."""

    matrix: np.ndarray
    deforming: dict
    parts: tuple
    file_faces: np.ndarray
    rest_faces: np.ndarray
    face_file: np.ndarray | None
    face_object: np.ndarray
    time: float = 0.0
    names: tuple[str, ...] = ()

    def to_json(self) -> dict:
        """What a frame JSON says of the pose: the time (s), and each object's name, its world
        matrix (4 rows) and whether its mesh deforms (its "local" points are then in its mesh's
        bind pose)."""
        return {"time": self.time, "objects": [
            {"name": n, "matrix": np.round(m, 12).tolist(), "deforms": k in self.deforming}
            for k, (n, m) in enumerate(zip(self.names, self.matrix))]}

    def input_faces(self, face: np.ndarray) -> np.ndarray:
        """The input face of scene faces `face` (-1 stays -1)."""
        face = np.asarray(face, np.int64)
        table = self.rest_faces if self.face_file is None else self.face_file
        return np.where(face >= 0, table.take(np.maximum(face, 0)), -1)

    def object_points(self, X: np.ndarray, face: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(object (N,), point (N, 3)) of world points X on scene faces `face`: the object of the
        face and the point in the object's own frame (-1 and X where the face is unknown)."""
        X = np.asarray(X, float)
        ff = self.input_faces(face)
        obj = np.where(ff >= 0, self.face_object.take(np.maximum(ff, 0)), -1)
        local = X.copy()
        for o in np.unique(obj[obj >= 0]).tolist():
            k = obj == o
            if o in self.deforming:
                local[k] = _carry_on_faces(X[k], self._corners(o, ff[k], posed=True),
                                           self._corners(o, ff[k], posed=False))
            else:
                M = np.linalg.inv(self.matrix[o])
                local[k] = X[k] @ M[:3, :3].T + M[:3, 3]
        return obj, local

    def world_points(self, obj: np.ndarray, local: np.ndarray, input_face: np.ndarray) -> np.ndarray:
        """World points of object points (`object_points`), their input faces given."""
        obj = np.asarray(obj, np.int64)
        out = np.asarray(local, float).copy()
        for o in np.unique(obj[obj >= 0]).tolist():
            k = obj == o
            if o in self.deforming:
                ff = np.asarray(input_face)[k]
                out[k] = _carry_on_faces(out[k], self._corners(o, ff, posed=False), self._corners(o, ff, posed=True))
            else:
                M = self.matrix[o]
                out[k] = out[k] @ M[:3, :3].T + M[:3, 3]
        return out

    def _corners(self, o: int, input_face: np.ndarray, posed: bool) -> np.ndarray:
        """(N, 3, 3) the corners of object o's input faces, posed or in its mesh frame."""
        part = self.parts[o]
        v = self.deforming[o] if posed else part.mesh_vertices
        return v[self.file_faces[input_face] - part.vertices.start]


def _carry_on_faces(X: np.ndarray, src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """Points X (N, 3) near triangles src (N, 3, 3) taken to triangles dst: the same barycentric
    coordinates and the same height over the face, in units of the face's size."""
    a, e1, e2 = src[:, 0], src[:, 1] - src[:, 0], src[:, 2] - src[:, 0]
    n = np.cross(e1, e2)
    area2 = np.linalg.norm(n, axis=1)
    ok = area2 > 0
    n = n / np.where(ok, area2, 1.0)[:, None]
    w = X - a
    d11, d12, d22 = (e1 * e1).sum(1), (e1 * e2).sum(1), (e2 * e2).sum(1)
    w1, w2 = (w * e1).sum(1), (w * e2).sum(1)
    den = d11 * d22 - d12 * d12
    den = np.where(den != 0, den, 1.0)
    u = (d22 * w1 - d12 * w2) / den
    v = (d11 * w2 - d12 * w1) / den
    h = (w * n).sum(1) / np.sqrt(np.where(ok, area2, 1.0))
    b, f1, f2 = dst[:, 0], dst[:, 1] - dst[:, 0], dst[:, 2] - dst[:, 0]
    m = np.cross(f1, f2)
    marea2 = np.linalg.norm(m, axis=1)
    m = m / np.where(marea2 > 0, marea2, 1.0)[:, None]
    return b + u[:, None] * f1 + v[:, None] * f2 + (h * np.sqrt(marea2))[:, None] * m


@dataclass(eq=False)
class SceneMotion:
    """How a glTF scene's objects move: its animations (`animations`), each part's node, skin and
    morph targets, and the scene's input arrays (vertices, faces, each face's object and
    material) and their rest weld, as load_scene read them."""

    path: Path
    tree: NodeTree
    parts: tuple[Part, ...]
    animations: tuple[AnimationInfo, ...]
    channels: dict  # {animation index: Channels}
    file_vertices: np.ndarray
    file_faces: np.ndarray
    file_face_object: np.ndarray
    file_face_material: np.ndarray
    rest: Welded
    #: (Fi,) the input faces the rest weld dropped as duplicates (not for want of area).
    rest_duplicates: np.ndarray = field(default=None)
    _kinds: dict = field(default_factory=dict)
    _last: tuple | None = None

    def __post_init__(self):
        #: The input vertices some face uses (the weld's extent is theirs); None: all of them.
        self.face_vertices = np.unique(self.file_faces)
        if len(self.face_vertices) == len(self.file_vertices):
            self.face_vertices = None
        if self.rest_duplicates is None:
            dropped = np.ones(len(self.file_faces), bool)
            dropped[self.rest.kept] = False
            self.rest_duplicates = dropped & _has_area(self.file_vertices, self.file_faces)

    # --- reading ----------------------------------------------------------------------------------
    @staticmethod
    def read(path, layout, parts: tuple, rest: Welded) -> "SceneMotion":
        """The motion of glTF file `path`, whose scene load_scene read as `parts` (its input
        vertices, faces, face objects and materials first) welded as `rest`; `layout`: each
        part's (node, primitive, vertices, faces, mirrored) in the order of the arrays. Every
        animation, skin and morph target is checked here: a problem is one InputError naming the
        file (and the animation)."""
        path = Path(path)
        g = load_gltf(path)
        data = GltfData(g, path)
        tree = NodeTree(g, data)
        in_scene = _scene_nodes(g, tree)
        parts_, v0, f0 = [], 0, 0
        for node, prim, nv, nf, mirrored in layout:
            n = g.nodes[node]
            mesh = data.item("meshes", n.mesh, f"node {node}")
            p = mesh.primitives[prim]
            what = f"mesh {n.mesh} primitive {prim}"
            pos = data.accessor(p.attributes.POSITION, f"{what} POSITION")
            if len(pos) != nv:
                raise data.error(f"{what} has {len(pos)} positions, the scene read {nv}")
            targets = weights = None
            if p.targets:
                targets = np.stack([_target(data, t, nv, f"{what} morph target {k}") for k, t in enumerate(p.targets)])
                weights = _default_weights(n, mesh, len(targets), node, data)
            skin = _skin(g, data, n.skin, p, nv, what, in_scene) if n.skin is not None else None
            parts_.append(Part(node, prim, slice(v0, v0 + nv), slice(f0, f0 + nf), bool(mirrored), pos, targets,
                               weights, skin))
            v0, f0 = v0 + nv, f0 + nf
        morphs = {part.node: len(part.targets) for part in parts_ if part.targets is not None}
        animations, channels = [], {}
        for ai in range(len(g.animations or [])):
            ch = read_channels(g, data, ai, weights=morphs, label=animation_label(g, ai), check_targets=True)
            channels[ai] = ch
            t0, t1 = time_span(ch) if ch else (0.0, 0.0)
            name = field_of(g.animations[ai], "name")
            animations.append(AnimationInfo(ai, name if isinstance(name, str) else "", t0, t1))
        motion = SceneMotion(path, tree, tuple(parts_), tuple(animations), channels,
                             np.asarray(parts[0], float), np.asarray(parts[1], np.int64),
                             np.asarray(parts[2], np.int32), np.asarray(parts[3], np.int32), rest)
        # Every animation posed at its keys: a pose beyond float64's range is said now, not in a frame.
        for ai in channels:
            if motion.moves(ai):
                for t in motion.key_times(ai):
                    motion.file_vertices_at(ai, float(t))
        return motion

    # --- animations -----------------------------------------------------------------------------------
    def animation(self, name: str | None) -> int | None:
        """The index of the animation called `name` (or numbered so); the first one when name
        is None, and None when the file has none. InputError for a name it does not have."""
        if not self.animations:
            if name is None:
                return None
            raise InputError(f"has no animation (asked for {name!r})", self.path)
        if name is None:
            return 0
        for a in self.animations:
            if a.name == name:
                return a.index
        if name.isdigit() and int(name) < len(self.animations):
            return int(name)
        known = ", ".join(a.label for a in self.animations)
        raise InputError(f"has no animation {name!r} (it has {known})", self.path)

    def key_times(self, ai: int) -> np.ndarray:
        """Every key time of animation ai, sorted."""
        keys = [c.keys for c in (self.channels.get(ai) or {}).values()]
        return np.unique(np.concatenate(keys)) if keys else np.zeros(1)

    def kind(self, ai: int | None, part: int) -> str:
        """How part `part` moves under animation ai (None: no animation): STATIC, RIGID or DEFORMING."""
        key = (ai, part)
        if key not in self._kinds:
            p = self.parts[part]
            ch = self._channels(ai)
            moved = {n for (n, prop) in ch if prop in GLTF_TRS}
            weights = (p.node, "weights") in ch
            if p.skin is not None or (p.targets is not None and (weights or np.any(p.weights != 0))):
                self._kinds[key] = DEFORMING
            elif moved.intersection(self.tree.chain(p.node)):
                self._kinds[key] = RIGID
            else:
                self._kinds[key] = STATIC
        return self._kinds[key]

    def moves(self, ai: int | None) -> bool:
        """Whether animation ai (None: none) poses any part away from the rest scene."""
        return any(self.kind(ai, k) != STATIC for k in range(len(self.parts)))

    def sample_times(self, ai: int | None, fps: float = 24.0) -> np.ndarray:
        """Times that show animation ai's range of poses: its key times and every 1 / fps between
        its first and last key."""
        if ai is None or not self.channels.get(ai):
            return np.zeros(1)
        a = self.animations[ai]
        steps = np.arange(a.start, a.end + 0.5 / fps, 1.0 / fps)
        return np.unique(np.concatenate([self.key_times(ai), np.minimum(steps, a.end)]))

    def extent(self, ai: int | None) -> tuple[np.ndarray, np.ndarray, float]:
        """(bounds (2, 3), centre (3,), radius) of the scene over animation ai: the box of every
        pose at `sample_times`, its centre, and the largest distance of a posed vertex from it."""
        key = ("extent", ai)
        if key not in self._kinds:
            used = self.rest.vertex_of >= 0
            poses = [self.file_vertices_at(ai, float(t))[used] for t in self.sample_times(ai)]
            lo = np.min([v.min(axis=0) for v in poses], axis=0)
            hi = np.max([v.max(axis=0) for v in poses], axis=0)
            c = 0.5 * (lo + hi)
            r = max(float(np.linalg.norm(v - c, axis=1).max()) for v in poses)
            self._kinds[key] = (np.stack([lo, hi]), c, r if r > 0 else 1.0)
        return self._kinds[key]

    def carrier(self, ai: int | None) -> int | None:
        """The node that carries the whole scene under animation ai, when there is one: every part
        moves rigidly, and only by this node's motion (it is an ancestor of every part, and no
        channel drives a node below it or elsewhere). None otherwise."""
        key = ("carrier", ai)
        if key not in self._kinds:
            node = None
            if self.parts and all(self.kind(ai, k) == RIGID for k in range(len(self.parts))):
                driven = {n for (n, prop) in self._channels(ai) if prop in GLTF_TRS}
                chains = [self.tree.chain(p.node) for p in self.parts]
                # each part's driven ancestors, nearest the root last
                tops = {tuple(n for n in c if n in driven) for c in chains}
                if len(tops) == 1:
                    (d,) = tops
                    node = d[0] if len(d) == 1 else None
            self._kinds[key] = node
        return self._kinds[key]

    def carried(self, ai: int | None, t: float, cache: dict | None = None) -> np.ndarray | None:
        """(4, 4) the similarity that takes the rest scene to the scene at time t, when one node
        carries the whole scene (`carrier`) and its motion is a similarity (rotation, uniform
        scale, translation); None otherwise. `cache`: the node matrices at t (object_matrices')."""
        node = self.carrier(ai)
        if node is None:
            return None
        W = self.tree.world(node, self._channels(ai), np.array([float(t)]), cache)[0]
        key = ("rest inverse", node)
        if key not in self._kinds:
            self._kinds[key] = np.linalg.inv(self.tree.world(node, {}, np.zeros(1))[0])
        with np.errstate(over="ignore", invalid="ignore"):
            D = W @ self._kinds[key]
        L = D[:3, :3]
        G = L.T @ L
        s2 = float(np.trace(G)) / 3.0
        if not (np.all(np.isfinite(D)) and s2 > 0 and np.abs(G - s2 * np.eye(3)).max() <= 1e-9 * s2
                and np.linalg.det(L) > 0):
            return None
        return D

    def pose(self, rest, ai: int | None, t: float, cache: dict | None = None) -> ScenePose:
        """Where the objects are at time t (the ScenePose of `posed`, without posing the scene)
        for a scene that moves only rigidly (faces as the rest scene's). `cache`: as carried's."""
        return ScenePose(self.object_matrices(ai, t, cache), {}, self.parts, self.file_faces, self.rest.kept, None,
                         self.file_face_object, float(t), tuple(rest.objects))

    def _moving(self, ai: int | None) -> tuple[np.ndarray, np.ndarray]:
        """(input vertices, input faces) of the parts animation ai poses away from rest (bool masks)."""
        key = ("moving", ai)
        if key not in self._kinds:
            rows = np.zeros(len(self.file_vertices), bool)
            faces = np.zeros(len(self.file_faces), bool)
            for k, p in enumerate(self.parts):
                if self.kind(ai, k) != STATIC:
                    rows[p.vertices] = True
                    faces[p.faces] = True
            self._kinds[key] = (rows, faces)
        return self._kinds[key]

    def _moving_scene_faces(self, rest, ai: int | None) -> np.ndarray:
        """(F,) the rest scene's faces that animation ai moves."""
        key = ("moving faces", ai)
        if key not in self._kinds:
            moving = [k for k in range(len(self.parts)) if self.kind(ai, k) != STATIC]
            self._kinds[key] = np.isin(rest.face_object, moving)
        return self._kinds[key]

    def _moving_edges(self, rest, ai: int | None) -> tuple[np.ndarray, np.ndarray]:
        """((E,) the rest scene's edges with an end animation ai moves, (E,) those beside a face
        it moves), bool masks."""
        key = ("moving edges", ai)
        if key not in self._kinds:
            rows = self._moving(ai)[0]
            of = self.rest.vertex_of
            moved = np.zeros(len(rest.vertices), bool)
            moved[of[rows & (of >= 0)]] = True
            faces = self._moving_scene_faces(rest, ai)
            ef = rest.edge_faces
            beside = faces[ef[:, 0]] | (faces[np.maximum(ef[:, 1], 0)] & (ef[:, 1] >= 0))
            self._kinds[key] = (moved[rest.edges].any(axis=1), beside)
        return self._kinds[key]

    def _channels(self, ai: int | None) -> Channels:
        return self.channels.get(ai, {}) if ai is not None else {}

    # --- posing ---------------------------------------------------------------------------------------
    def object_matrices(self, ai: int | None, t: float, cache: dict | None = None) -> np.ndarray:
        """(O, 4, 4) each object's world matrix at time t (a skinned object's: its node's)."""
        times, cache = np.array([float(t)]), ({} if cache is None else cache)
        return np.stack([self.tree.world(p.node, self._channels(ai), times, cache)[0] for p in self.parts])

    def file_vertices_at(self, ai: int | None, t: float, cache: dict | None = None) -> np.ndarray:
        """(Vi, 3) the scene's input vertices posed at time t by animation ai (a static part's
        rows are its rest rows). InputError when the pose leaves float64's range. `cache`: the
        node matrices at t (NodeTree.world's), shared with object_matrices."""
        ch = self._channels(ai)
        times = np.array([float(t)])
        cache = {} if cache is None else cache
        out = self.file_vertices.copy()
        for k, p in enumerate(self.parts):
            if self.kind(ai, k) == STATIC:
                continue
            v = p.mesh_vertices
            if p.targets is not None:
                w = ch[(p.node, "weights")].at(times)[0] if (p.node, "weights") in ch else p.weights
                v = v + np.tensordot(w, p.targets, axes=1)
            with np.errstate(over="ignore", invalid="ignore"):
                if p.skin is not None:
                    joints = np.stack([self.tree.world(int(j), ch, times, cache)[0] for j in p.skin.joints])
                    J = joints @ p.skin.inverse_bind  # (J, 4, 4)
                    vh = np.concatenate([v, np.ones((len(v), 1))], axis=1)
                    posed = np.zeros((len(v), 4))
                    for slot in range(p.skin.joint.shape[1]):
                        posed += p.skin.weight[:, slot, None] * np.einsum("nij,nj->ni", J[p.skin.joint[:, slot]], vh)
                    v = posed[:, :3]
                else:
                    M = self.tree.world(p.node, ch, times, cache)[0]
                    v = v @ M[:3, :3].T + M[:3, 3]  # (as load_scene places a part at rest)
            out[p.vertices] = v
        if not np.all(np.isfinite(out)):
            label = animation_label(self.tree.g, ai) if ai is not None else "the rest pose"
            raise InputError(f"{label} at t = {t:g} s poses vertices beyond float64's range", self.path)
        return out

    def posed(self, rest, ai: int | None, t: float):
        """The scene `rest` (the Scene this motion belongs to) posed at time t by animation ai:
        the Scene a static file of the posed vertices gives (weld.weld of them), with its
        ScenePose. The rest scene itself when nothing moves; the last posed scene again when
        the pose is the same."""
        if not self.moves(ai):
            return rest
        cache: dict = {}
        V = self.file_vertices_at(ai, t, cache)
        last = self._last
        if last is not None and last[0] == ai and np.array_equal(last[1], V):
            return last[2]
        matrices = self.object_matrices(ai, t, cache)
        scene = self._posed_scene(rest, V, matrices, ai, t)
        self._last = (ai, V, scene)
        return scene

    def _posed_scene(self, rest, V: np.ndarray, matrices: np.ndarray, ai: int | None, t: float):
        faces = self.file_faces
        flips = [p for k, p in enumerate(self.parts)
                 if self.kind(ai, k) == RIGID and p.mirrored != bool(np.linalg.det(matrices[k, :3, :3]) < 0)]
        if flips:  # a scale turned negative (or back): that part's winding turns with it
            faces = faces.copy()
            for p in flips:
                faces[p.faces] = faces[p.faces][:, ::-1]
        moved = self._moving_scene_faces(rest, ai)
        fast = None if flips else _posed_weld(self, V, faces, ai, self._moving(ai), moved)
        deforming = {k: V[p.vertices] for k, p in enumerate(self.parts) if self.kind(ai, k) == DEFORMING}
        if fast is not None:
            vertices, new, crosses = fast
            pose = ScenePose(matrices, deforming, self.parts, self.file_faces, self.rest.kept, None,
                             self.file_face_object, float(t), tuple(rest.objects))
            scene = replace(rest, vertices=vertices, faces=new[rest.faces], pose=pose)
            # The rest scene's topology with the vertices renumbered: the same edges and faces
            # of each edge, the edges sorted again (what Scene._topology makes of these faces),
            # and its face and edge tables, computed again where a face moved.
            topology, order = _renumbered_topology(rest, new, self._moving_edges(rest, ai))
            scene.__dict__.update(_carried_tables(rest, scene, topology, order, moved, crosses,
                                                  self._moving_edges(rest, ai)[1]))
            return scene
        w = weld(V, faces, str(self.path))
        pose = ScenePose(matrices, deforming, self.parts, self.file_faces, self.rest.kept, w.kept,
                         self.file_face_object, float(t), tuple(rest.objects))
        return replace(rest, vertices=w.vertices, faces=w.faces, face_object=self.file_face_object[w.kept],
                       face_material=self.file_face_material[w.kept], dropped_degenerate=w.dropped_degenerate,
                       dropped_duplicate=w.dropped_duplicate, pose=pose)


def _renumbered_topology(rest, new: np.ndarray, moving: tuple | None = None) -> tuple:
    """rest._topology (edges, edge faces, face counts) after renumbering vertex v as new[v]: each
    edge's faces are found in the same order (face order is kept), only the edges' rows and
    their order change. `moving`: (the rest edges with a moving end (E,) bool, ...) (None: sort
    them all). `new` keeps the order of the still vertices, so the edges between two of them keep
    theirs: only the others are sorted, and merged in, where they are few."""
    edges, edge_faces, counts = rest._topology
    e = new[edges]
    lo, hi = np.minimum(e[:, 0], e[:, 1]), np.maximum(e[:, 0], e[:, 1])
    e = np.stack([lo, hi], axis=1)
    key = lo * (len(new) + 1) + hi  # (unique: the edges are)
    mv = None if moving is None else moving[0]
    if mv is None or np.count_nonzero(mv) * 8 > len(key):
        order = np.argsort(key, kind="stable")
    else:
        m, still = np.flatnonzero(mv), np.flatnonzero(~mv)
        m = m[np.argsort(key[m], kind="stable")]
        ins = np.searchsorted(key[still], key[m])  # (ascending: still keys keep their order)
        order = np.empty(len(key), np.int64)
        at_m = ins + np.arange(len(m))
        order[at_m] = m
        filled = np.zeros(len(key), bool)
        filled[at_m] = True
        order[~filled] = still
    return (e.take(order, axis=0), edge_faces.take(order, axis=0), counts[order]), order


def _carried_tables(rest, scene, topology: tuple, order: np.ndarray, moved: np.ndarray, crosses: tuple | None = None,
                    beside: np.ndarray | None = None) -> dict:
    """The posed `scene`'s cached tables from the rest scene's (its faces as the rest scene's,
    the edges renumbered in `order`): face normals, plane offsets and dihedral cosines kept for
    the faces that did not move and computed again, with Scene's formulas, for those that did
    (`moved` (F,); `crosses`: their face_crosses_of and face_corners_of, made already) and the
    edges beside them
    (`beside` (E,): rest edges with a moved face; None: found here): the same values as computed
    afresh. The rest scene's manifold face pairs and material boundaries are carried
    (renumbered) where it has them."""
    m = np.flatnonzero(moved)
    fm = scene.faces[m] if crosses is None else None
    corners = None if crosses is None else crosses[2]
    nm = face_normals_of(scene.vertices, fm, None if crosses is None else crosses[:2])
    om = face_offsets_of(scene.vertices, fm, nm, corners)
    if len(m) == len(moved):  # (every face moved)
        n, off = nm, om
    else:
        n, off = rest.face_normals.copy(), rest.face_offsets.copy()
        n[m], off[m] = nm, om
    ef = topology[1]
    dc = rest.dihedral_cos[order]
    if beside is None:
        touch = np.flatnonzero(moved[ef[:, 0]] | (moved[np.maximum(ef[:, 1], 0)] & (ef[:, 1] >= 0)))
    else:
        touch = np.flatnonzero(beside[order])
    dc[touch] = dihedral_cos_of(ef[touch], n)
    out = {"_topology": topology, "face_normals": n, "face_offsets": off, "dihedral_cos": dc}
    if "manifold_face_pairs" in rest.__dict__:
        a, b = rest.manifold_face_pairs
        out["manifold_face_pairs"] = (a[order], b[order])
    if "is_material_boundary" in rest.__dict__:
        out["is_material_boundary"] = rest.is_material_boundary[order]
    return out


def _area2(V: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(F,) twice each face's area; 0 where two corners are the same point."""
    a, b, c = corners = face_corners_of(V, faces)
    area2 = face_crosses_of(V, faces, corners)[1]
    same = same_rows(a, b) | same_rows(b, c) | same_rows(a, c)
    return np.where(same, 0.0, area2)


def _has_area(V: np.ndarray, faces: np.ndarray, extent: float | None = None) -> np.ndarray:
    """(F,) faces with three distinct corners and an area above the weld's threshold."""
    if extent is None:
        lo, hi = bounds_of(V) if len(V) else (np.zeros(3), np.ones(3))
        extent = float(np.max(hi - lo))
    return _area2(V, faces) > (1e-14 * (extent or 1.0)) ** 2


def _posed_weld(motion: SceneMotion, V: np.ndarray, faces: np.ndarray, ai: int | None,
                moving: tuple[np.ndarray, np.ndarray], moved_scene_faces: np.ndarray):
    """(vertices, new index of each rest vertex, the moved scene faces' face_crosses_of and
    face_corners_of: cross products, norms, corners) when the posed input vertices V keep the
    rest weld: the input vertices welded together at rest stay together and apart from the
    others, and every face keeps whether it is dropped (the kept ones keep their area, the
    dropped ones are still without area or still duplicates); None otherwise (weld V afresh).
    The vertices are then sorted by position as weld(V) sorts them, so the scene is the one
    weld(V) makes. Only the rows and faces of the moving parts under animation ai (`moving`;
    `moved_scene_faces` (F,): the rest scene's faces among them) are looked at again; a kept
    face's area is the norm of the cross product its normal is made of."""
    rest = motion.rest
    rows, moved_faces = moving
    of = rest.vertex_of
    n = len(rest.vertices)
    # (one entry, set whole: frames drawn by threads read it while another may be making it)
    if "rest weld" not in motion._kinds:
        used = of >= 0
        rep = np.empty(n, np.int64)
        rep[of[used]] = np.flatnonzero(used)
        motion._kinds["rest weld"] = (rep, _area2(motion.file_vertices, motion.file_faces))
    rep, rest_area2 = motion._kinds["rest weld"]
    P = V.take(rep, axis=0)
    check = np.flatnonzero(rows & (of >= 0))
    if not np.array_equal(V.take(check, axis=0), P.take(of[check], axis=0)):
        return None
    key = ("moving weld", ai)
    if key not in motion._kinds:
        moved = np.zeros(n, bool)
        moved[of[rows & (of >= 0)]] = True
        kept = np.zeros(len(motion.file_faces), bool)
        kept[rest.kept] = True
        motion._kinds[key] = (np.flatnonzero(~moved), np.flatnonzero(moved), kept,
                              np.flatnonzero(moved_faces & ~kept), rest.kept[np.flatnonzero(moved_scene_faces)])
    still, moving_rows, kept, dropped_moving, kept_moving = motion._kinds[key]
    order = _sorted_order(P, still, moving_rows, motion._kinds.setdefault(("sort", ai), {}))
    if order is None:
        return None  # two welded vertices meet
    S = P.take(order, axis=0)
    # (the weld's extent: of the vertices of every face, dropped ones included)
    lo, hi = bounds_of(V if motion.face_vertices is None else V.take(motion.face_vertices, axis=0))
    extent = float(np.max(hi - lo)) or 1.0
    # The moved kept faces' corners are distinct welded vertices (apart: _sorted_order), so
    # their area is the cross product's norm (_area2's), on V's rows as on the scene's.
    corners = face_corners_of(V, faces[kept_moving])
    crosses = (*face_crosses_of(V, None, corners), corners)
    area2 = rest_area2.copy()
    area2[kept_moving] = crosses[1]
    area2[dropped_moving] = _area2(V, faces[dropped_moving])
    alive = area2 > (1e-14 * extent) ** 2
    if not (alive[kept].all() and np.array_equal(alive & ~kept, motion.rest_duplicates)):
        return None
    new = np.empty(n, np.int64)
    new[order] = np.arange(n)
    return S, new, crosses


def _sorted_order(P: np.ndarray, still: np.ndarray, moving: np.ndarray, memo: dict | None = None) -> np.ndarray | None:
    """The order that sorts the rows of P (V, 3) by position (x, then y, then z, as the weld does),
    given that the rows `still` (those that did not move: in sorted order already, the rest
    scene's) and `moving` cover them: the moving rows sorted and merged in (a sort of all the rows
    where most of them move). None where two rows are equal (welded vertices that meet).
    `memo`: _lex_order's, kept from frame to frame."""
    if len(moving) * 8 > len(P):
        order = _lex_order(P, memo)
        S = P.take(order, axis=0)
        return None if len(S) > 1 and same_rows(S[1:], S[:-1]).any() else order
    mv = moving[_lex_order(P.take(moving, axis=0), memo)]
    M = P.take(mv, axis=0)
    if len(M) > 1 and same_rows(M[1:], M[:-1]).any():
        return None
    St = P.take(still, axis=0)
    lo = np.searchsorted(St[:, 0], M[:, 0], side="left")
    hi = np.searchsorted(St[:, 0], M[:, 0], side="right")
    ins = lo.copy()
    for j in np.flatnonzero(hi > lo).tolist():  # the still rows of the same x: by y, then z
        block = St[lo[j]:hi[j]]
        y, z = M[j, 1], M[j, 2]
        less = (block[:, 1] < y) | ((block[:, 1] == y) & (block[:, 2] < z))
        if ((block[:, 1] == y) & (block[:, 2] == z)).any():
            return None
        ins[j] = lo[j] + int(less.sum())
    order = np.empty(len(P), np.int64)
    order[ins + np.arange(len(mv))] = mv
    order[np.arange(len(still)) + np.searchsorted(ins, np.arange(len(still)), side="right")] = still
    return order


def _lex_order(P: np.ndarray, memo: dict | None = None) -> np.ndarray:
    """np.lexsort((P[:, 2], P[:, 1], P[:, 0])): the rows of P (N, 3) by x, then y, then z. Where
    no two rows share x (a turned object's rows, mostly), the sort by x alone, a quarter of the
    time. `memo` (a dict kept between calls on like rows) remembers that rows shared x (a wheel
    turning about x keeps it), and sorts by all three at once the next time."""
    x = np.ascontiguousarray(P[:, 0])
    if memo is None or not memo.get("shared x"):
        order = np.argsort(x, kind="stable")
        xs = x[order]
        if not (len(xs) > 1 and (xs[1:] == xs[:-1]).any()):
            return order
        if memo is not None:
            memo["shared x"] = True
    return np.lexsort((P[:, 2], P[:, 1], x))


def _scene_nodes(g, tree: NodeTree) -> set[int]:
    """The nodes of the file's default scene (its roots and their descendants)."""
    scenes = g.scenes or []
    si = g.scene if is_index(g.scene) and g.scene < len(scenes) else 0
    roots = list(scenes[si].nodes or []) if scenes else [i for i in range(len(tree.nodes)) if i not in tree.parent]
    out, stack = set(), [r for r in roots if is_index(r) and r < len(tree.nodes)]
    while stack:
        n = stack.pop()
        if n in out:
            continue
        out.add(n)
        stack.extend(c for c in (tree.nodes[n].children or []) if is_index(c) and c < len(tree.nodes))
    return out


def _target(data: GltfData, target, n: int, what: str) -> np.ndarray:
    i = field_of(target, "POSITION")
    if i is None:
        return np.zeros((n, 3))
    d = data.accessor(i, f"{what} POSITION")
    if d.shape != (n, 3):
        raise data.error(f"{what}: POSITION holds {len(d)} VEC{d.shape[1]} values for {n} vertices")
    return d


def _default_weights(node, mesh, count: int, ni: int, data: GltfData) -> np.ndarray:
    w = field_of(node, "weights") or field_of(mesh, "weights") or [0.0] * count
    try:
        a = np.asarray(w, float)
    except (TypeError, ValueError):
        a = np.zeros(0)
    if a.shape != (count,) or not np.all(np.isfinite(a)):
        raise data.error(f"node {ni}: its morph weights {w!r} are not {count} numbers (one per morph target)")
    return a


def _skin(g, data: GltfData, si, prim, n: int, what: str, in_scene: set[int]) -> Skin:
    """The skin `si` of a part whose primitive `prim` has n vertices: its joints must be nodes of
    the scene, its inverse bind matrices one MAT4 per joint, JOINTS_n / WEIGHTS_n one per vertex."""
    skin = data.item("skins", si, what)
    label = f"skin {si}"
    joints = field_of(skin, "joints") or []
    if not joints:
        raise data.error(f"{label} has no joints")
    for j in joints:
        if not is_index(j) or j >= len(g.nodes or []):
            raise data.error(f"{label}: joint {j!r} is not a node of the file")
        if j not in in_scene:
            raise data.error(f"{label}: joint node {j} is not in the scene (no root of the scene leads to it)")
    ibm_i = field_of(skin, "inverseBindMatrices")
    if ibm_i is None:
        ibm = np.broadcast_to(np.eye(4), (len(joints), 4, 4))
    else:
        m = data.accessor(ibm_i, f"{label} inverseBindMatrices")
        if m.shape != (len(joints), 16):
            raise data.error(f"{label}: inverseBindMatrices holds {len(m)} values of {m.shape[1]} components for "
                             f"{len(joints)} joints (one MAT4 each)")
        ibm = m.reshape(-1, 4, 4).transpose(0, 2, 1)  # (column-major in the file)
    attrs = prim.attributes
    sets = []
    k = 0
    while getattr(attrs, f"JOINTS_{k}", None) is not None or (k == 0 and False):
        ji, wi = getattr(attrs, f"JOINTS_{k}"), getattr(attrs, f"WEIGHTS_{k}", None)
        if wi is None:
            raise data.error(f"{what} has JOINTS_{k} without WEIGHTS_{k}")
        jj = data.accessor(ji, f"{what} JOINTS_{k}", integers=True)
        ww = data.accessor(wi, f"{what} WEIGHTS_{k}")
        if jj.shape != (n, 4) or ww.shape != (n, 4):
            raise data.error(f"{what}: JOINTS_{k} and WEIGHTS_{k} need {n} VEC4 values each (one per vertex), got "
                             f"{len(jj)} and {len(ww)}")
        sets.append((jj, ww))
        k += 1
    if not sets:
        raise data.error(f"{what} is skinned (its node has skin {si}) but has no JOINTS_0 and WEIGHTS_0")
    joint = np.concatenate([s[0] for s in sets], axis=1).astype(np.int64)
    weight = np.concatenate([s[1] for s in sets], axis=1)
    if joint.max() >= len(joints):
        raise data.error(f"{what}: a vertex names joint {int(joint.max())} of skin {si}, which has {len(joints)}")
    return Skin(np.asarray(joints, np.int64), np.ascontiguousarray(ibm), joint, weight)
