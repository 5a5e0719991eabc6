"""The scene's ray backend (`Occluder`): Embree through open3d's RaycastingScene, or embreex
through trimesh when open3d cannot load. Rays run in a frame centred on the scene and scaled to
unit radius (the local frame), so float32 keeps its precision far from the origin and a scene
moved or scaled as a whole gets the same answers. What the line stage asks of the rays (whether a
point is seen, how many surfaces hide it) is strokekit.lines.sightlines."""

from __future__ import annotations

import threading
from functools import cached_property

import numpy as np

from strokekit.errors import hold_interrupts
from strokekit.numba_cache import KernelGroup, LazyKernels
from strokekit.scene.load import Scene

_IMPORT_LOCK = threading.Lock()


def import_open3d():
    """open3d, imported without its plotly drawing module.

    `import open3d` imports open3d.visualization, which imports plotly and dash (with IPython),
    most of the import's time, paid by the command and again by every spawned worker, for
    drawing functions strokekit never calls. A stand-in module takes their place when open3d has
    not been imported yet; calling them says so. Under a lock: a thread that finds open3d in
    sys.modules while another is still initializing it would get a half-made module (a dask
    worker's threads)."""
    with _IMPORT_LOCK:
        return _import_open3d()


def _import_open3d():
    import sys

    name = "open3d.visualization.draw_plotly"
    if "open3d" not in sys.modules and name not in sys.modules:
        import types

        def unavailable(*args, **kwargs):
            raise RuntimeError("open3d's plotly drawing is not loaded in a strokekit process")

        stand_in = types.ModuleType(name)
        stand_in.get_plotly_fig = stand_in.draw_plotly = stand_in.draw_plotly_server = unavailable
        sys.modules[name] = stand_in
    if "open3d" in sys.modules:
        return sys.modules["open3d"]
    with hold_interrupts():  # open3d's init turns Ctrl-C into ImportError (see hold_interrupts)
        import open3d

    return open3d


class Occluder:
    """Ray queries against a scene's triangles. Backend: open3d's RaycastingScene (Embree);
    trimesh's embreex intersector when open3d cannot be imported.

    World-frame queries (`first_hits`, `segment_hits`, `occluded_segments`, `crossings`) work on
    both backends. Local-frame queries take (N, 6) float32 rays (origin, direction) already in
    the local frame, (X - origin) * inv_scale, and answer as open3d's RaycastingScene does
    (`cast_rays`, `test_occlusions`, `list_intersections`, `count_intersections`); the embreex
    fallback answers `cast_rays` only (the line stage takes world-frame paths there)."""

    def __init__(self, scene: Scene, backend: str | None = None, faces: np.ndarray | None = None):
        """`faces`, if given: the scene faces (indices) that occlude; every face otherwise (see
        `without_faces`)."""
        self.scene = scene
        #: The BVHs of a posed scene's objects, each in its own frame (`composed`); None: one BVH.
        self.parts: tuple[RayPart, ...] | None = None
        #: The scene face of each Embree primitive (None: the same numbers, every face).
        self.face_index = None if faces is None else np.asarray(faces, np.int64)
        self.origin = scene.center.copy()
        self.radius = scene.radius
        #: world -> local frame: (X - origin) * inv_scale. Ray parameters (t in units of the
        #: direction) are the same in both frames.
        self.inv_scale = 1.0 / scene.radius if scene.radius > 0 else 1.0
        local = ((scene.vertices - self.origin) * self.inv_scale).astype(np.float32)
        self.backend = backend
        if backend in (None, "open3d"):
            try:
                o3d = import_open3d()
                self._o3c = o3d.core
                self._rs = o3d.t.geometry.RaycastingScene()
                tris = scene.faces if faces is None else scene.faces[self.face_index]
                self._rs.add_triangles(o3d.core.Tensor(local), o3d.core.Tensor(tris.astype(np.uint32)))
                self.backend = "open3d"
                return
            except ImportError:
                if backend == "open3d":
                    raise
        import trimesh

        mesh = trimesh.Trimesh(local.astype(np.float64), scene.faces if faces is None else scene.faces[self.face_index],
                               process=False)
        self._intersector = trimesh.ray.ray_pyembree.RayMeshIntersector(mesh) if _has_embreex() else mesh.ray
        self.backend = "embreex" if _has_embreex() else "trimesh"

    @classmethod
    def composed(cls, scene: Scene, parts: tuple[RayPart, ...], origin: np.ndarray, radius: float) -> "Occluder":
        """The occluder of `scene` (its faces) made of BVHs built elsewhere, each in its own frame
        (RayPart): a posed scene's objects keep the BVH they were built with, and rays are taken
        into each one's frame. Local rays are centred on `origin` and scaled by 1 / `radius`
        (the frame of the scene over its whole animation). open3d only."""
        occ = cls.__new__(cls)
        occ.scene, occ.parts, occ.face_index, occ.backend = scene, tuple(parts), None, "open3d"
        occ.origin, occ.radius = np.asarray(origin, float).copy(), float(radius)
        occ.inv_scale = 1.0 / occ.radius
        occ._o3c = import_open3d().core
        return occ

    def without_faces(self, drop: np.ndarray) -> "Occluder":
        """An occluder of the same scene (same frame) in which the faces where `drop` (F,) is True
        hide nothing: the faces a frame sees exactly edge-on (lines.facing.FrameView.edge_on).
        Its first hits give scene face numbers too; its BVH is built now."""
        keep = np.flatnonzero(~np.asarray(drop, bool))
        if self.parts is not None:
            return Occluder.composed(self.scene, tuple(p.without_faces(~np.asarray(drop, bool)) for p in self.parts),
                                     self.origin, self.radius)
        return Occluder(self.scene, self.backend, faces=keep)

    @cached_property
    def kept_faces(self) -> np.ndarray | None:
        """(F,) the faces that hide something, None for all."""
        if self.face_index is None:
            return None
        kept = np.zeros(len(self.scene.faces), bool)
        kept[self.face_index] = True
        return kept

    def scene_faces(self, prim: np.ndarray) -> np.ndarray:
        """Scene face numbers (int64) of Embree primitive ids."""
        prim = np.asarray(prim).astype(np.int64)
        return prim if self.face_index is None else self.face_index.take(prim)

    # --- local-frame queries (open3d's RaycastingScene) -----------------------------------------------

    def cast_rays(self, rays: np.ndarray) -> dict:
        """First hits of (N, 6) float32 local rays: 't_hit' (N,) float32 (in units of the
        direction, inf for none), 'primitive_ids' (N,) int32 Embree's triangle ids, -1 for none
        (the scene faces unless the occluder leaves faces out: `scene_faces` maps them),
        'primitive_uvs' (N, 2) float32 (barycentric weights of the triangle's 2nd and 3rd
        corners)."""
        if self.backend != "open3d":
            o = rays[:, :3].astype(np.float64) / self.inv_scale + self.origin
            return self.first_hits(o, rays[:, 3:].astype(np.float64) / self.inv_scale)
        if self.parts is not None:
            return self._parts_cast(rays)
        r = self._rs.cast_rays(self._o3c.Tensor.from_numpy(np.ascontiguousarray(rays)))
        ids = r["primitive_ids"].numpy().view(np.int32)  # (uint32 "no hit", 0xFFFFFFFF, reads as -1)
        return {"t_hit": r["t_hit"].numpy(), "primitive_ids": ids, "primitive_uvs": r["primitive_uvs"].numpy()}

    def test_occlusions(self, rays: np.ndarray) -> np.ndarray:
        """(N,) True where the (N, 6) float32 local ray meets a triangle for t in [0, 1] (open3d)."""
        if self.parts is not None:
            out = np.zeros(len(rays), bool)
            for part, idx, r in self._part_rays(rays, 1.0):
                out[idx] |= part.rs.test_occlusions(self._o3c.Tensor(r), tnear=0.0, tfar=1.0).numpy().astype(bool)
            return out
        return self._rs.test_occlusions(self._o3c.Tensor(rays), tnear=0.0, tfar=1.0).numpy().astype(bool)

    def list_intersections(self, rays: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every hit of the (N, 6) float32 local rays, in one Embree call (open3d): (t_hit (K,)
        float32, ray_ids (K,), primitive_ids (K,) Embree's ids), grouped by ray."""
        if self.parts is not None:
            ts, rs, ps = [np.zeros(0, np.float32)], [np.zeros(0, np.uint32)], [np.zeros(0, np.uint32)]
            for part, idx, r in self._part_rays(rays, np.inf):
                lx = part.rs.list_intersections(self._o3c.Tensor(r))
                ts.append(lx["t_hit"].numpy())
                rs.append(idx.take(lx["ray_ids"].numpy().astype(np.int64)).astype(np.uint32))
                ps.append(part.faces.take(lx["primitive_ids"].numpy().astype(np.int64)).astype(np.uint32))
            t, ray, prim = np.concatenate(ts), np.concatenate(rs), np.concatenate(ps)
            o = np.argsort(ray, kind="stable")  # (grouped by ray, as Embree lists them)
            return t[o], ray[o], prim[o]
        lx = self._rs.list_intersections(self._o3c.Tensor(rays))
        return lx["t_hit"].numpy(), lx["ray_ids"].numpy(), lx["primitive_ids"].numpy()

    def count_intersections(self, rays: np.ndarray) -> np.ndarray:
        """(N,) how many triangles each (N, 6) float32 local ray meets from its origin on (open3d)."""
        if self.parts is not None:
            out = np.zeros(len(rays), np.int64)
            for part, idx, r in self._part_rays(rays, np.inf):
                out[idx] += part.rs.count_intersections(self._o3c.Tensor(r)).numpy().astype(np.int64)
            return out
        return self._rs.count_intersections(self._o3c.Tensor(rays)).numpy()

    def _part_rays(self, rays: np.ndarray, tfar: float):
        """(part, ray indices, their rays in the part's frame, float32) for each part whose box the
        local rays (N, 6) may meet for t in [0, tfar]."""
        every = None
        rays = np.ascontiguousarray(rays, np.float32)
        for part in self.parts:
            if part.A is None and not part.cull:
                every = np.arange(len(rays)) if every is None else every
                yield part, every, rays
                continue
            idx, r = ray_kernels().rays_into(rays, part.lo, part.hi, min(float(tfar), 1e300), part.Af, part.bf,
                                             part.cull)
            if len(idx):
                yield part, idx, r

    def _parts_cast(self, rays: np.ndarray) -> dict:
        """cast_rays over the parts: the nearest hit of each ray, its scene face as its primitive."""
        n = len(rays)
        t = ids = uvs = None
        for part, idx, r in self._part_rays(rays, np.inf):
            hit = part.rs.cast_rays(self._o3c.Tensor.from_numpy(r))
            th, prim = hit["t_hit"].numpy(), hit["primitive_ids"].numpy().view(np.int32)
            if t is None and len(idx) == n:  # (the first part that takes every ray: its answers as they are)
                t, uvs = th, hit["primitive_uvs"].numpy()
                ids = np.where(prim >= 0, part.faces.take(np.maximum(prim, 0)), -1).astype(np.int32)
                continue
            if t is None:
                t, ids, uvs = np.full(n, np.inf, np.float32), np.full(n, -1, np.int32), np.zeros((n, 2), np.float32)
            near = th < t.take(idx)
            if near.any():
                k = idx[near]
                t[k] = th[near]
                ids[k] = part.faces.take(prim[near].astype(np.int64))
                uvs[k] = hit["primitive_uvs"].numpy()[near]
        if t is None:
            t, ids, uvs = np.full(n, np.inf, np.float32), np.full(n, -1, np.int32), np.zeros((n, 2), np.float32)
        return {"t_hit": t, "primitive_ids": ids, "primitive_uvs": uvs}

    # --- world-frame queries --------------------------------------------------------------------------

    def _local_rays(self, origins: np.ndarray, targets: np.ndarray):
        """The segments origins -> targets (world, (N, 3)) in the local frame: (N, 6) float32 rays
        (origin, direction = the whole segment) for open3d, (origins, directions) arrays else."""
        o = (origins - self.origin) * self.inv_scale
        d = (targets - origins) * self.inv_scale
        if self.backend != "open3d":
            return o, d
        rays = np.empty((len(o), 6), np.float32)
        rays[:, :3] = o
        rays[:, 3:] = d
        return rays

    def occluded_segments(self, origins: np.ndarray, targets: np.ndarray) -> np.ndarray:
        """(N,) True where the segment origins -> targets (world, (N, 3)) hits a triangle.
        Callers offset the origins; the target end is open."""
        if len(origins) == 0:
            return np.zeros(0, bool)
        if self.backend == "open3d":
            return self.test_occlusions(self._local_rays(origins, targets))
        return np.isfinite(self.segment_hits(origins, targets))

    def segment_hits(self, origins: np.ndarray, targets: np.ndarray) -> np.ndarray:
        """(N,) where the segment origins -> targets (world, (N, 3)) first meets a triangle, as a
        fraction of its length; inf where it meets none before its end (open there)."""
        if len(origins) == 0:
            return np.zeros(0)
        if self.backend == "open3d":
            t = self.cast_rays(self._local_rays(origins, targets))["t_hit"].astype(float)
            return np.where(t <= 1.0, t, np.inf)
        o, d = self._local_rays(origins, targets)
        length = np.linalg.norm(d, axis=1)
        unit = d / np.where(length > 0, length, 1)[:, None]
        idx_tri, idx_ray, loc = self._intersector.intersects_id(o, unit, multiple_hits=False, return_locations=True)
        t = np.full(len(o), np.inf)
        if len(idx_ray):
            dist = np.einsum("ij,ij->i", loc - o[idx_ray], unit[idx_ray])
            inside = (dist > 0) & (dist < length[idx_ray])
            t[idx_ray[inside]] = dist[inside] / length[idx_ray][inside]
        return t

    def first_hits(self, origins: np.ndarray, directions: np.ndarray) -> dict:
        """Nearest hit per ray (world origins, (N, 3) unnormalized directions): 't_hit' (N,) (in
        units of the direction, inf for none), 'primitive_ids' (N,) scene faces (-1 none),
        'primitive_uvs' (N, 2) (barycentric weights of the triangle's 2nd and 3rd corners, as
        Embree's)."""
        if self.backend != "open3d":
            return self._first_hits_trimesh(origins, directions)
        rays = np.concatenate([(origins - self.origin) * self.inv_scale, directions * self.inv_scale],
                              axis=1).astype(np.float32)
        r = self.cast_rays(rays)
        ids = r["primitive_ids"].astype(np.int64)
        none = ids < 0
        if self.face_index is not None:
            ids = self.face_index.take(np.where(none, 0, ids))
        ids[none] = -1
        return {"t_hit": r["t_hit"], "primitive_ids": ids, "primitive_uvs": r["primitive_uvs"]}

    def _first_hits_trimesh(self, origins: np.ndarray, directions: np.ndarray) -> dict:
        """first_hits through trimesh's intersector (embreex, or its own triangle test)."""
        n = len(origins)
        o = ((origins - self.origin) * self.inv_scale).astype(np.float64)
        d = (directions * self.inv_scale).astype(np.float64)
        length = np.linalg.norm(d, axis=1)
        unit = d / np.where(length > 0, length, 1)[:, None]
        t = np.full(n, np.inf, np.float32)
        ids = np.full(n, -1, np.int64)
        uvs = np.zeros((n, 2), np.float32)
        if n:
            tri, ray, loc = self._intersector.intersects_id(o, unit, multiple_hits=False, return_locations=True)
            if len(ray):
                f = self.scene.faces[self.scene_faces(tri)]
                V = (self.scene.vertices - self.origin) * self.inv_scale
                a, b, c = V[f[:, 0]], V[f[:, 1]], V[f[:, 2]]
                # loc = a + u (b - a) + v (c - a): least squares on the two edge vectors.
                e1, e2, w = b - a, c - a, loc - a
                d11, d12, d22 = (e1 * e1).sum(1), (e1 * e2).sum(1), (e2 * e2).sum(1)
                w1, w2 = (w * e1).sum(1), (w * e2).sum(1)
                den = d11 * d22 - d12 * d12
                den = np.where(den != 0, den, 1.0)
                uvs[ray, 0] = (d22 * w1 - d12 * w2) / den
                uvs[ray, 1] = (d11 * w2 - d12 * w1) / den
                t[ray] = ((loc - o[ray]) * unit[ray]).sum(1) / np.where(length[ray] > 0, length[ray], 1)
                ids[ray] = self.scene_faces(tri)
        return {"t_hit": t, "primitive_ids": ids, "primitive_uvs": uvs}

    def crossings(self, origins: np.ndarray, directions: np.ndarray) -> np.ndarray:
        """(N,) how many times each ray (world origins, (N, 3) directions) crosses the scene's
        triangles, from its origin on (Embree's count_intersections; trimesh's intersector with
        every hit in the fallback)."""
        o = (origins - self.origin) * self.inv_scale
        if self.backend == "open3d":
            rays = np.concatenate([o, directions], axis=1).astype(np.float32)
            return self.count_intersections(rays).astype(np.int64)
        _, ray = self._intersector.intersects_id(o.astype(np.float64), np.asarray(directions, np.float64),
                                                 multiple_hits=True)
        return np.bincount(np.asarray(ray, np.int64), minlength=len(o))


#: The compiled loop of a moving scene's rays (`strokekit.scene.compiled_rays`), imported on first
#: use: still scenes never import numba for it.
RAYS = LazyKernels("strokekit.scene.compiled_rays")
MOVING_SCENE = KernelGroup("moving-scene ray", (RAYS,), compile_seconds=3)
ray_kernels = RAYS.kernels


class RayPart:
    """One BVH of a composed occluder (Occluder.composed): an Embree scene of some scene faces
    (`faces` (P,), the scene face of each primitive), built in its own frame; rays of the
    occluder's local frame are taken there by x -> A x + b (A None: the same frame); lo, hi (3,)
    the part's box in the occluder's local frame (rays that miss it are not cast)."""

    def __init__(self, rs, faces: np.ndarray, A: np.ndarray | None, b: np.ndarray | None, lo: np.ndarray,
                 hi: np.ndarray, build=None, cull: bool = True):
        self.rs, self.faces, self.A, self.b = rs, np.asarray(faces, np.int64), A, b
        # (padded by float32's rounding of unit coordinates, so that a ray grazing the box is cast)
        pad = 1e-5 * max(1.0, float(np.abs(np.concatenate([lo, hi])).max()))
        self.lo, self.hi = np.asarray(lo, float) - pad, np.asarray(hi, float) + pad
        #: The frame change as the compiled loop takes it (the identity for A None).
        self.Af = np.eye(3) if A is None else np.ascontiguousarray(A, float)
        self.bf = np.zeros(3) if b is None else np.ascontiguousarray(b, float)
        #: build(keep (P,) bool) -> RaycastingScene of the primitives kept (for without_faces).
        self.build = build
        #: Whether rays are tested against the box before they are cast (not for a part that
        #: fills most of the scene: nearly every ray would be cast anyway).
        self.cull = cull

    def without_faces(self, keep_faces: np.ndarray) -> "RayPart":
        """This part less the scene faces where keep_faces (F,) is False."""
        keep = keep_faces[self.faces]
        if keep.all():
            return self
        return RayPart(self.build(keep), self.faces[keep], self.A, self.b, self.lo, self.hi,
                       lambda k, keep=keep, b=self.build: b(_subset(keep, k)), self.cull)


def _subset(keep: np.ndarray, k: np.ndarray) -> np.ndarray:
    """The mask over the whole part of the primitives kept by `keep` and then by `k`."""
    out = np.zeros(len(keep), bool)
    out[np.flatnonzero(keep)[k]] = True
    return out


def _has_embreex() -> bool:
    try:
        import embreex  # noqa: F401

        return True
    except ImportError:
        return False


#: Faces below which a BVH is built again each frame rather than kept: building one of that many
#: faces costs about what a frame's ray queries lose to one more BVH cast into (docs/animation.md).
KEEP_FACES = 5000


class PosedRays:
    """The ray backend of a moving scene's frames (`occluder(posed)`: the frame's Occluder).

    A scene of fewer than KEEP_FACES faces, or of deforming objects alone, gets the posed scene's
    own BVH each frame (a still scene's). Otherwise rays run in one local frame for the whole
    animation (centred on the scene's box over the animation, unit radius: SceneMotion.extent);
    the still objects keep one BVH in that frame for every frame; each rigidly moving node whose
    objects have KEEP_FACES faces or more keeps one in its mesh's own frame, where rays are taken
    (those that may meet its box); the other moving objects (deforming, or small) share a BVH
    built each frame."""

    def __init__(self, rest: Scene, animation: int | None, backend: str | None = None):
        self.rest, self.animation, self.backend = rest, animation, backend
        motion = rest.motion
        groups: dict = {}  # "static" or ("rigid", node) or "deforming" -> object ids
        for k in range(len(motion.parts)):
            kind = motion.kind(animation, k)
            groups.setdefault(kind if kind != "rigid" else ("rigid", motion.parts[k].node), []).append(k)
        size = {key: int(np.isin(rest.face_object, objs).sum()) for key, objs in groups.items()}
        self.groups: dict = {}  # "static", ("rigid", node) or "rebuilt" -> object ids
        for key, objs in groups.items():  # the small moving ones and the deforming ones: rebuilt
            if key != "static" and (key == "deforming" or size[key] < KEEP_FACES):
                key = "rebuilt"
            self.groups.setdefault(key, []).extend(objs)
        self.faces = {key: np.flatnonzero(np.isin(rest.face_object, objs)) for key, objs in self.groups.items()}
        #: The whole scene's BVH each frame: the scene is small, or nothing in it keeps a BVH.
        self.whole = len(rest.faces) < KEEP_FACES or set(self.groups) == {"rebuilt"}
        _, self.origin, self.radius = motion.extent(animation)
        self.inv_scale = 1.0 / self.radius
        self._kept: dict = {}

    def occluder(self, posed: Scene) -> Occluder:
        """The Occluder of frame scene `posed` (rest.at(...))."""
        if (self.whole or posed.pose is None or posed.pose.face_file is not None
                or self.backend not in (None, "open3d")):
            return Occluder(posed, self.backend)
        try:
            o3d = import_open3d()
        except ImportError:
            return Occluder(posed, self.backend)
        c, k = self.origin, self.inv_scale
        parts = []
        for key, objs in self.groups.items():
            faces = self.faces[key]
            if len(faces) == 0:
                continue
            if key == "rebuilt":
                V = ((posed.vertices - c) * k).astype(np.float32)
                tris = posed.faces[faces]
                used = V[np.unique(tris)].astype(float)
                lo, hi = used.min(axis=0), used.max(axis=0)
                parts.append(RayPart(_raycasting_scene(o3d, V, tris), faces, None, None, lo, hi,
                                     lambda keep, V=V, tris=tris: _raycasting_scene(o3d, V, tris[keep]),
                                     cull=_small(lo, hi)))
                continue
            if key not in self._kept:
                self._kept[key] = self._build(o3d, key, objs, faces)
            rs, lo, hi, own_c, own_k, build = self._kept[key]
            if key == "static":
                parts.append(RayPart(rs, faces, None, None, lo, hi, build, cull=_small(lo, hi)))
                continue
            # local -> world (x / k + c) -> the node's mesh frame (M) -> its own local frame
            M = np.linalg.inv(posed.pose.matrix[objs[0]])
            A = own_k * M[:3, :3] / k
            b = own_k * (M[:3, :3] @ c + M[:3, 3] - own_c)
            corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
            back = np.linalg.solve(A, (corners - b).T).T
            lo, hi = back.min(axis=0), back.max(axis=0)
            parts.append(RayPart(rs, faces, A, b, lo, hi, build, cull=_small(lo, hi)))
        return Occluder.composed(posed, tuple(parts), self.origin, self.radius)

    def _build(self, o3d, key, objs: list[int], faces: np.ndarray):
        """(BVH, its box lo, hi in its frame, its frame's centre and scale, a builder of subsets)
        of a kept group: the still objects in the animation's frame, a moving node's objects in
        their mesh frame (centred on their box, unit radius)."""
        rest, motion = self.rest, self.rest.motion
        if key == "static":
            c, inv = self.origin, self.inv_scale
            V = ((rest.vertices - c) * inv).astype(np.float32)
            tris = rest.faces[faces]
        else:
            # Each kept face's corners in the node's mesh frame: its input face's vertices (rows of
            # the parts' mesh vertices, stacked) through the rest weld.
            parts = [motion.parts[o] for o in objs]
            mesh = np.concatenate([p.mesh_vertices for p in parts])
            start = np.concatenate([[0], np.cumsum([len(p.mesh_vertices) for p in parts])[:-1]])
            offset = np.zeros(len(motion.parts), np.int64)
            for j, o in enumerate(objs):
                offset[o] = start[j] - motion.parts[o].vertices.start
            tris = motion.file_faces[motion.rest.kept[faces]] + offset[rest.face_object[faces]][:, None]
            c = 0.5 * (mesh.min(axis=0) + mesh.max(axis=0))
            inv = 1.0 / (float(np.linalg.norm(mesh - c, axis=1).max()) or 1.0)
            V = ((mesh - c) * inv).astype(np.float32)
        used = V[np.unique(tris)].astype(float)
        return (_raycasting_scene(o3d, V, tris), used.min(axis=0), used.max(axis=0), c, inv,
                lambda keep, V=V, tris=tris: _raycasting_scene(o3d, V, tris[keep]))


def _small(lo: np.ndarray, hi: np.ndarray) -> bool:
    """Whether a part's box (in the animation's unit frame) is small enough for rays to be tested
    against it before they are cast: under a quarter of the frame's cube of side 2 (one that
    fills the scene would have nearly every ray cast anyway)."""
    return float(np.prod(np.maximum(np.asarray(hi) - np.asarray(lo), 0.0))) < 0.25 * 8.0


def _raycasting_scene(o3d, V: np.ndarray, tris: np.ndarray):
    rs = o3d.t.geometry.RaycastingScene()
    rs.add_triangles(o3d.core.Tensor(np.ascontiguousarray(V, np.float32)),
                     o3d.core.Tensor(np.ascontiguousarray(tris, np.uint32)))
    return rs
