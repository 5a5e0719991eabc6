"""Ray queries against a scene (`Occluder`): Embree through open3d's RaycastingScene, or
embreex through trimesh when open3d cannot load. Rays run in a frame centred on the scene and
scaled to unit radius, so float32 keeps its precision far from the origin and a scene moved or
scaled as a whole gets the same answers."""

from __future__ import annotations

import math
import threading

import numpy as np

from strokekit.camera.view import Camera
from strokekit.errors import hold_interrupts
from strokekit.model import row_norm
from strokekit.numba_cache import LazyKernels
from strokekit.scene.load import Scene

_IMPORT_LOCK = threading.Lock()


def import_open3d():
    """open3d, imported without its plotly drawing module.

    `import open3d` imports open3d.visualization, which imports plotly and dash (with IPython):
    0.7 s of a 1.2 s import, paid by the command and again by every spawned worker, for drawing
    functions strokekit never calls. A stand-in module takes their place when open3d has not been
    imported yet; calling them says so. Under a lock: a thread that finds open3d in sys.modules
    while another is still initializing it would get a half-made module (a dask worker's threads)."""
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
    """Occlusion queries against a scene. Backend: open3d RaycastingScene (Embree); trimesh's
    embreex intersector when open3d cannot be imported."""

    def __init__(self, scene: Scene, backend: str | None = None, faces: np.ndarray | None = None):
        """`faces`, if given: the scene faces (indices) that occlude; every face otherwise (see
        `without_faces`)."""
        self.scene = scene
        #: The scene face of each Embree primitive (None: the same numbers, every face).
        self.face_index = None if faces is None else np.asarray(faces, np.int64)
        self.origin = scene.center.copy()
        self._faces64 = np.ascontiguousarray(scene.faces, np.int64)
        self.radius = scene.radius
        #: world -> Embree frame: (X - origin) * inv_scale. Ray parameters (t in units of the
        #: direction) are the same in both frames.
        self.inv_scale = 1.0 / scene.radius if scene.radius > 0 else 1.0
        self._origin_col = self.origin[:, None]
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

    def without_faces(self, drop: np.ndarray) -> "Occluder":
        """An occluder of the same scene (same frame) in which the faces where `drop` (F,) is True
        hide nothing: the faces a frame sees exactly edge-on (lines.surface.edge_on_faces). Its
        first hits give scene face numbers too; its BVH is built now."""
        keep = np.flatnonzero(~np.asarray(drop, bool))
        return Occluder(self.scene, self.backend, faces=keep)

    def _scene_faces(self, prim: np.ndarray) -> np.ndarray:
        """Scene face numbers (int64) of Embree primitive ids."""
        prim = np.asarray(prim).astype(np.int64)
        return prim if self.face_index is None else self.face_index.take(prim)

    def _local_rays(self, origins: np.ndarray, targets: np.ndarray):
        """The segments origins -> targets (world, (N, 3)) in the Embree frame: an open3d ray
        tensor (origin, direction = the whole segment), or (origins, directions) arrays."""
        o = (origins - self.origin) * self.inv_scale
        d = (targets - origins) * self.inv_scale
        if self.backend != "open3d":
            return o, d
        rays = np.empty((len(o), 6), np.float32)
        rays[:, :3] = o
        rays[:, 3:] = d
        return self._o3c.Tensor(rays)

    def occluded_segments(self, origins: np.ndarray, targets: np.ndarray) -> np.ndarray:
        """(N,) True where the segment origins -> targets (world, (N, 3)) hits a triangle.
        Callers offset the origins; the target end is open."""
        if len(origins) == 0:
            return np.zeros(0, bool)
        if self.backend == "open3d":
            hit = self._rs.test_occlusions(self._local_rays(origins, targets), tnear=0.0, tfar=1.0)
            return hit.numpy().astype(bool)
        return np.isfinite(self.segment_hits(origins, targets))

    def segment_hits(self, origins: np.ndarray, targets: np.ndarray) -> np.ndarray:
        """(N,) where the segment origins -> targets (world, (N, 3)) first meets a triangle, as a
        fraction of its length; inf where it meets none before its end (open there)."""
        if len(origins) == 0:
            return np.zeros(0)
        if self.backend == "open3d":
            t = self._rs.cast_rays(self._local_rays(origins, targets))["t_hit"].numpy().astype(float)
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
        units of the direction, inf for none), 'primitive_ids' (N,) (-1 none), 'primitive_uvs'
        (N, 2) (barycentric weights of the triangle's 2nd and 3rd corners, as Embree's)."""
        if self.backend != "open3d":
            return self._first_hits_trimesh(origins, directions)
        rays = np.concatenate([(origins - self.origin) * self.inv_scale, directions * self.inv_scale],
                              axis=1).astype(np.float32)
        r = self._rs.cast_rays(self._o3c.Tensor(rays))
        ids = r["primitive_ids"].numpy().astype(np.int64)
        none = ids == np.iinfo(np.uint32).max
        if self.face_index is not None:
            ids = self.face_index.take(np.where(none, 0, ids))
        ids[none] = -1
        return {"t_hit": r["t_hit"].numpy(), "primitive_ids": ids, "primitive_uvs": r["primitive_uvs"].numpy()}

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
                f = self.scene.faces[self._scene_faces(tri)]
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
                ids[ray] = self._scene_faces(tri)
        return {"t_hit": t, "primitive_ids": ids, "primitive_uvs": uvs}

    def visible(self, points: np.ndarray, camera: Camera, offset: float = 1e-5,
                lift: np.ndarray | None = None, scale: np.ndarray | None = None) -> np.ndarray:
        """(N,) True where world points (N, 3) are seen from the camera. `lift` (N, 3), if given,
        moves each ray origin off the surface (world units) before the test.

        The ray starts `offset` x a length toward the eye: the scene radius, or, when `scale` (N,)
        (the local size of the geometry at each point, world units, e.g. its edge length) is
        given, max(|point - scene centre|, scale). float32 errors grow with the coordinates'
        magnitude in the centred frame, so that is the size the offset must beat; a global radius
        would let a huge floor make the offset jump over small nearby occluders.

        With a lift, a point is visible when either the lifted or the plain ray reaches the eye:
        the plain ray can graze the point's own 1-ring (false hits within float32 rounding), the
        lifted one can start inside an object the surface rests on (a box on the floor); each
        failure only ever hides, and a real occluder stops both rays."""
        if scale is None:
            eps = np.full(len(points), offset * self.radius)
        else:
            c = points - self.origin
            eps = offset * np.maximum(np.sqrt(np.einsum("ij,ij->i", c, c)), scale)
        if lift is None:
            return self._visible_from(points, camera, eps, offset)
        lifted = points + lift
        hit_at = self._visible_from(lifted, camera, eps, offset, first_hit=True)
        vis = np.isinf(hit_at)
        # Only a lifted ray blocked right at its start can be the contact case; most hidden
        # samples are hidden by something far away and need no second full ray. The first hit's
        # distance (one closest-hit ray instead of an occlusion ray and a short second one)
        # tells which.
        reach = 100.0 * np.linalg.norm(lift, axis=1) + eps
        again = np.flatnonzero(~vis & (hit_at <= reach))
        if len(again):
            vis[again] = self._visible_from(points[again], camera, eps[again], offset)
        return vis

    def _visible_from(self, points: np.ndarray, camera: Camera, eps: np.ndarray, offset: float,
                      first_hit: bool = False):
        """Rays from points toward the eye, started eps along. Visibility (N,) bool; with
        `first_hit`, instead the distance to the first hit along the ray (world units, inf where
        the ray reaches the eye)."""
        if camera.is_ortho:
            # Parallel rays toward the camera, as far as the near plane: what lies before it is
            # clipped out of the drawing (clip_segments) and hides nothing either (a section view,
            # a camera placed inside the scene).
            _, _, fwd = camera.basis
            reach = np.maximum((points - np.asarray(camera.eye, float)) @ fwd - camera.near_distance(self.radius), 0.0)
            if not reach.all():  # a point on the near plane itself: no segment, nothing can hide it
                on = reach > 0
                out = np.full(len(points), np.inf) if first_hit else np.ones(len(points), bool)
                if on.any():
                    out[on] = self._visible_from(points[on], camera, eps[on], offset, first_hit)
                return out
        # The segment is open at the eye too (perspective): an eye standing on a surface must not
        # see that surface as an occluder of everything; it stops short by the float32 rounding
        # scale there.
        origins, targets = self._segments(points, camera, eps, offset)
        if first_hit:
            t = self.segment_hits(origins, targets)
            return t * np.linalg.norm(targets - origins, axis=1)
        return ~self.occluded_segments(origins, targets)

    # --- occlusion levels: how many surfaces hide a point ------------------------------------------

    def count_crossings(self, origins: np.ndarray, targets: np.ndarray, limit: int, skip: np.ndarray | None = None,
                        near: tuple[np.ndarray, np.ndarray] | None = None,
                        verify: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(count (N,) int64, first (N,)): how many surfaces the segments origins -> targets (world,
        (N, 3)) cross, at most `limit`, and the distance (world units) to the first crossing (inf:
        none). Callers offset the origins; the target end is open. Hits on the faces `skip`
        (N, 2) of each ray (-1: none) are not crossings; nor, with `near` = (vertices (N, 2),
        distances (N,)), those on faces around those vertices closer than that to the origin; with
        `verify` = (points (N, 3), targets (N, 3), distances (N,)), hits closer than that to the
        origin count only where the segment from the point to the target crosses the triangle in
        float64 (`_crosses`).

        Every hit along each segment comes from one Embree call (open3d's list_intersections).
        A ray through an edge or a vertex that several triangles share may be reported by each of
        them (float32 hit distances a little apart): consecutive hits on triangles that share a
        vertex, facing the ray the same way, within 1e-5 of the scene radius of each other count
        once, whichever triangles Embree reported (crossing a consistently wound surface twice in
        a row flips the side it is crossed from, so two same-side hits in a row are one crossing;
        a ray grazing a fold, in and out, keeps both). open3d's count_intersections is about twice
        as fast but returns a number only: it cannot leave out a ray's own faces (0.9% of a bunny
        frame's level samples come out wrong) and counts a shared edge twice when Embree reports
        both triangles at float32 distances a little apart; rays continued past each hit
        (`_count_crossings_stepping`, the path without open3d) are slower and meet a grazed
        triangle again (benchmarks/bench_hidden.py, table 3)."""
        n = len(origins)
        count = np.zeros(n, np.int64)
        first = np.full(n, np.inf)
        if n == 0:
            return count, first
        if self.backend != "open3d":
            return self._count_crossings_stepping(origins, targets, limit, skip, near, verify)
        k = self.inv_scale
        d_local = (np.asarray(targets, float) - origins) * k
        rays = np.empty((n, 6), np.float32)
        rays[:, :3] = (origins - self.origin) * k
        rays[:, 3:] = d_local
        lx = self._rs.list_intersections(self._o3c.Tensor(rays))
        t = lx["t_hit"].numpy()
        ray = lx["ray_ids"].numpy().astype(np.int64)
        inside = t <= 1.0
        if not inside.all():
            t, ray = t[inside], ray[inside]
            prim = lx["primitive_ids"].numpy()[inside]
        else:
            prim = lx["primitive_ids"].numpy()
        if len(t) == 0:
            return count, first
        o = _order_along_rays(t, ray)  # by ray, then along it
        t, ray, face = t[o].astype(float), ray[o], self._scene_faces(prim[o])
        length = np.sqrt(np.einsum("ij,ij->i", d_local, d_local))
        dist = t * length.take(ray) / k
        drop = self._skipped(ray, face, dist, skip, near)
        if verify is not None:
            close = np.flatnonzero(dist <= verify[2].take(ray))
            if len(close):
                if drop is None:
                    drop = np.zeros(len(t), bool)
                r_c = ray[close]
                drop[close] |= ~self._crosses(verify[0].take(r_c, axis=0), verify[1].take(r_c, axis=0), face[close])
        if drop is not None:
            t, ray, face = t[~drop], ray[~drop], face[~drop]
            if len(t) == 0:
                return count, first
        count, head = self._crossing_count(t, ray, face, length, d_local, n, limit)
        firsts = np.flatnonzero(head)
        first[ray[firsts]] = t[firsts] * length.take(ray[firsts]) / k
        return count, first

    def _crossing_count(self, t, ray, face, length, d_local, n, limit):
        """(count (n,), head (K,)): the crossings of each of n rays, at most `limit`, from its hits
        (K >= 1; t along the ray's local direction d_local (n, 3), of norm length (n,), by ray then
        t; scene faces): consecutive hits on triangles that share a vertex, facing the ray alike,
        within 1e-5 (Embree frame) count once (see count_crossings); head marks each ray's first."""
        head = np.empty(len(t), bool)
        head[0] = True
        np.not_equal(ray[1:], ray[:-1], out=head[1:])
        close = ~head[1:] & ((t[1:] - t[:-1]) * length.take(ray[1:]) <= 1e-5)
        dup = np.zeros(len(t), bool)
        if close.any():
            i = np.flatnonzero(close) + 1  # hit i repeats hit i - 1?
            F = self.scene.faces
            fa, fb = F.take(face[i - 1], axis=0), F.take(face[i], axis=0)
            shared = (fa[:, :, None] == fb[:, None, :]).any(axis=(1, 2))
            d = d_local.take(ray[i], axis=0)
            nrm = self.scene.face_normals
            side_a = np.einsum("ij,ij->i", nrm.take(face[i - 1], axis=0), d) > 0
            side_b = np.einsum("ij,ij->i", nrm.take(face[i], axis=0), d) > 0
            dup[i] = shared & (side_a == side_b)
        return np.minimum(np.bincount(ray[~dup], minlength=n), int(limit)), head

    def _levels_compiled(self, points: np.ndarray, camera: Camera, offset: float, lift: np.ndarray,
                         scale: np.ndarray, limit: int, own: np.ndarray) -> np.ndarray | None:
        """levels of points that all lie on mesh edges, for a perspective camera: the same rays,
        hits and counts, the rays built and the hits sorted and filtered by the compiled loops of
        `strokekit.scene.compiled`. None when Embree's list does not come grouped by ray."""
        K = level_kernels()
        n = len(points)
        eye = np.asarray(camera.eye, float)
        eye_tail = offset * np.linalg.norm(eye - self.origin)
        k = self.inv_scale
        rays, targets, d_local, length, reach = K.level_rays(
            np.ascontiguousarray(points, float), np.ascontiguousarray(lift, float), np.ascontiguousarray(scale, float),
            eye, self.origin, k, offset, eye_tail)
        lx = self._rs.list_intersections(self._o3c.Tensor(rays))
        index = self.face_index if self.face_index is not None else np.zeros(0, np.int64)
        ok, t, ray, face, close = K.listed_hits(lx["t_hit"].numpy(), lx["ray_ids"].numpy(), lx["primitive_ids"].numpy(),
                                                index, length, k, np.ascontiguousarray(own, np.int64), reach)
        if not ok:
            return None
        c = np.flatnonzero(close)
        if len(c):  # hits near the start count only where they cross in float64
            r_c = ray[c]
            keep = np.ones(len(t), bool)
            keep[c] = K.crosses(points.take(r_c, axis=0), targets.take(r_c, axis=0), face[c], self._faces64, self.scene.vertices)
            t, ray, face = t[keep], ray[keep], face[keep]
        if len(t) == 0:
            return np.zeros(n, np.int64)
        return self._crossing_count(t, ray, face, length, d_local, n, limit)[0]

    def _crosses(self, a: np.ndarray, b: np.ndarray, face: np.ndarray) -> np.ndarray:
        """(M,) whether the open segments a -> b (world, (M, 3)) cross the scene faces `face` (M,)
        in float64 (Moller-Trumbore on the closed triangle; a face seen edge-on crosses nothing)."""
        F, V = self.scene.faces, self.scene.vertices
        tri = F.take(face, axis=0)
        A = V.take(tri[:, 0], axis=0)
        e1 = V.take(tri[:, 1], axis=0) - A
        e2 = V.take(tri[:, 2], axis=0) - A
        d = b - a
        pv = _cross(d, e2)
        det = np.einsum("ij,ij->i", e1, pv)
        scale = row_norm(_cross(e1, e2)) * row_norm(d)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / det
            tv = a - A
            u = np.einsum("ij,ij->i", tv, pv) * inv
            qv = _cross(tv, e1)
            v = np.einsum("ij,ij->i", d, qv) * inv
            t = np.einsum("ij,ij->i", e2, qv) * inv
        return (np.abs(det) > 1e-12 * scale) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0) & (t < 1)

    def _skipped(self, ray, face, dist, skip, near) -> np.ndarray | None:
        """Which hits (ray, scene face, world distance from the origin) are not crossings (see
        count_crossings); None for none."""
        drop = None
        if skip is not None:
            drop = (face == skip[:, 0].take(ray)) | (face == skip[:, 1].take(ray))
        if near is not None:
            verts, reach = near
            close = dist <= reach[ray]
            if close.any():
                i = np.flatnonzero(close)
                f = self.scene.faces.take(face[i], axis=0)
                v = verts[ray[i]]
                touch = ((f == v[:, :1]) | (f == v[:, 1:])).any(axis=1) & ((v >= 0).any(axis=1))
                hit = np.zeros(len(face), bool)
                hit[i[touch]] = True
                drop = hit if drop is None else drop | hit
        return drop

    def _count_crossings_stepping(self, origins: np.ndarray, targets: np.ndarray, limit: int, skip=None,
                                  near=None, verify=None):
        """count_crossings without open3d: the segment is cast again from just past each hit (1e-6
        of the local size; a grazing ray can meet its last triangle again: a fallback, slower and
        rougher than the open3d path)."""
        n = len(origins)
        count = np.zeros(n, np.int64)
        first = np.full(n, np.inf)
        active = np.arange(n)
        o = np.asarray(origins, float)
        tgt = np.asarray(targets, float)
        for r in range(int(limit)):
            seg = tgt - o
            length = np.sqrt(np.einsum("ij,ij->i", seg, seg))
            hits = self.first_hits(o, tgt - o)
            t = np.where(hits["t_hit"] <= 1.0, hits["t_hit"], np.inf).astype(float)
            hit = np.isfinite(t)
            ray_h, face_h, dist_h = active[hit], hits["primitive_ids"][hit], t[hit] * length[hit]
            drop = self._skipped(ray_h, face_h, dist_h, skip, near)
            if verify is not None:
                base = np.linalg.norm(o[hit] - origins[ray_h], axis=1)  # how far this round started
                close = np.flatnonzero(base + dist_h <= verify[2][ray_h])
                if len(close):
                    drop = np.zeros(len(ray_h), bool) if drop is None else drop
                    r_c = ray_h[close]
                    drop[close] |= ~self._crosses(verify[0][r_c], verify[1][r_c], face_h[close])
            counted = hit.copy()
            if drop is not None:
                counted[np.flatnonzero(hit)[drop]] = False
            if r == 0:
                first[active[counted]] = t[counted] * length[counted]
            count[active[counted]] += 1
            if r + 1 == limit or not hit.any():
                break
            at = o[hit] + t[hit, None] * seg[hit]
            size = np.maximum(np.sqrt(np.einsum("ij,ij->i", at - self.origin, at - self.origin)), self.radius)
            step = t[hit] + 1e-6 * size / np.where(length[hit] > 0, length[hit], 1.0)
            go = step < 1.0
            active = active[hit][go]
            o = o[hit][go] + step[go, None] * seg[hit][go]
            tgt = tgt[hit][go]
            if len(active) == 0:
                break
        return count, first

    def _segments(self, points: np.ndarray, camera: Camera, eps: np.ndarray, offset: float):
        """The open segments from points toward the eye (perspective) or along the projection
        rays to the near plane (parallel), started eps along: (origins, targets), as
        _visible_from casts them; a point on the near plane itself gets an empty segment."""
        if camera.is_ortho:
            _, _, fwd = camera.basis
            toward = np.broadcast_to(-camera.ray_dir, points.shape)
            reach = np.maximum((points - np.asarray(camera.eye, float)) @ fwd - camera.near_distance(self.radius), 0.0)
            origins = points + np.minimum(eps, 0.5 * reach)[:, None] * toward
            targets = points + reach[:, None] * toward
            return origins, targets
        eye = np.asarray(camera.eye, float)
        d = eye - points
        dist = np.sqrt(np.einsum("ij,ij->i", d, d))
        toward = d / np.where(dist > 0, dist, 1.0)[:, None]
        origins = points + np.minimum(eps, 0.5 * dist)[:, None] * toward
        tail = np.minimum(np.maximum(eps, offset * np.linalg.norm(eye - self.origin)), 0.25 * dist)
        return origins, eye - tail[:, None] * toward

    def levels(self, points: np.ndarray, camera: Camera, offset: float, lift: np.ndarray | None,
               scale: np.ndarray, limit: int, own: np.ndarray | None = None,
               ends: np.ndarray | None = None) -> np.ndarray:
        """(N,) occlusion level of world points (N, 3): how many surfaces the open segment from
        each point to the eye (parallel cameras: along the projection rays to the near plane)
        crosses, up to `limit`, the point's own faces `own` (N, 2), -1 for none, excluded.

        A point on a mesh edge (`ends` (N, 2): its end vertices, -1 for none) is counted along the
        ray from the point itself (started `offset` x the local size `scale` along): the geometry
        of the definition. That ray grazes the point's own neighbourhood within float32 rounding,
        so its hits closer than 100 lifts to its start are tested again in float64 against the
        exact segment and count only if they are crossings there (a box standing on a floor is not
        hidden by it). A lifted ray would skip a real surface within its lift, and one leaving a
        contour whose back face is nearly edge-on dips under the nearly flat surface beyond (a
        crossing the point does not have). Other points (lines inside faces, whose rays rise off
        the facets by design: lines.contours.view_lift) take the smaller count of the lifted ray
        and of the plain ray: each ray's failures there add crossings."""
        n = len(points)
        on_edge = np.zeros(n, bool) if ends is None or lift is None else ends[:, 0] >= 0
        e = np.flatnonzero(on_edge)
        if n and len(e) == n and not camera.is_ortho and self.backend == "open3d" and own is not None:
            count = self._levels_compiled(points, camera, offset, lift, scale, limit, own)
            if count is not None:
                return count
        c = points - self.origin
        eps = offset * np.maximum(np.sqrt(np.einsum("ij,ij->i", c, c)), scale)
        count = np.zeros(n, np.int64)
        if n and len(e) == n:  # (every point on an edge: no gathers)
            o, t = self._segments(points, camera, eps, offset)
            count, _ = self.count_crossings(o, t, limit, skip=own, verify=(points, t, 100.0 * row_norm(lift) + eps))
            return count
        if len(e):
            P = points[e]
            o, t = self._segments(P, camera, eps[e], offset)
            reach = 100.0 * row_norm(lift[e]) + eps[e]
            count[e], _ = self.count_crossings(o, t, limit, skip=None if own is None else own[e],
                                               verify=(P, t, reach))
        rest = np.flatnonzero(~on_edge)
        if len(rest) == 0:
            return count
        P = points[rest]
        start = P if lift is None else P + lift[rest]
        c_rest, _ = self.count_crossings(*self._segments(start, camera, eps[rest], offset), limit,
                                         skip=None if own is None else own[rest])
        if lift is not None:
            again = np.flatnonzero(c_rest > 0)
            if len(again):
                plain, _ = self.count_crossings(*self._segments(P[again], camera, eps[rest][again], offset), limit,
                                                skip=None if own is None else own[rest][again])
                c_rest[again] = np.minimum(c_rest[again], plain)
        count[rest] = c_rest
        return count

    # --- the same queries on (3, N) coordinate rows (perspective, lifted) -------------------------
    # visible_runs' hot path. Every value is computed by the same float64 operations, in the same
    # order, as visible / _visible_from / occluded_segments (so the float32 rays, hence the
    # answers, are bit for bit the same); only the memory layout differs, which makes numpy's
    # elementwise loops contiguous. np.einsum("ij,ij->i", x, x) sums (x0 x0 + x2 x2) + x1 x1 and
    # np.linalg.norm(x, axis=1) sqrt((x0 x0 + x1 x1) + x2 x2): the helpers below keep those orders.

    def _rays_rows(self, o: np.ndarray, t: np.ndarray):
        """open3d rays (Embree frame, float32) of the segments between (3, N) origins and targets."""
        rays = np.empty((o.shape[1], 6), np.float32)
        rays[:, :3] = ((o - self._origin_col) * self.inv_scale).T
        rays[:, 3:] = ((t - o) * self.inv_scale).T
        return self._o3c.Tensor(rays)

    def _occluded_rows(self, o: np.ndarray, t: np.ndarray) -> np.ndarray:
        """occluded_segments for (3, N) origins and targets (open3d backend)."""
        if o.shape[1] == 0:
            return np.zeros(0, bool)
        hit = self._rs.test_occlusions(self._rays_rows(o, t), tnear=0.0, tfar=1.0)
        return hit.numpy().astype(bool)

    def _hit_distance_rows(self, o: np.ndarray, t: np.ndarray, faces: bool = False):
        """segment_hits for (3, N) origins and targets, times the segment lengths (world units).
        With `faces`, also the (N,) triangle each ray first meets (meaningless where it meets none)."""
        if o.shape[1] == 0:
            return (np.zeros(0), np.zeros(0, np.int64)) if faces else np.zeros(0)
        r = self._rs.cast_rays(self._rays_rows(o, t))
        f = r["t_hit"].numpy().astype(float)
        f = np.where(f <= 1.0, f, np.inf)
        dist = f * np.sqrt(_norm_sq(t - o))
        return (dist, r["primitive_ids"].numpy()) if faces else dist

    def _visible_from_rows(self, P: np.ndarray, eye: np.ndarray, eps: np.ndarray, eye_eps: float,
                           d: np.ndarray | None = None, dist: np.ndarray | None = None,
                           first_hit: bool = False, faces: bool = False):
        """_visible_from (perspective) for (3, N) points; eye (3, 1); eye_eps = offset x |eye - origin|.
        d = eye - P and dist = its length (einsum order) may be passed when already known. With
        `first_hit` and `faces`, (hit distances, first triangles) (see _hit_distance_rows)."""
        if d is None:
            d = eye - P
            dist = np.sqrt(_einsum_sq(d))
        toward = d / np.where(dist > 0, dist, 1.0)
        origins = P + np.minimum(eps, 0.5 * dist) * toward
        tail = np.minimum(np.maximum(eps, eye_eps), 0.25 * dist)
        targets = eye - tail * toward
        if first_hit:
            return self._hit_distance_rows(origins, targets, faces)
        return ~self._occluded_rows(origins, targets)

    def visible_rows(self, P: np.ndarray, camera: Camera, offset: float, lift: np.ndarray,
                     scale: np.ndarray, retest_front_hits: bool = True) -> np.ndarray:
        """visible(points, camera, offset, lift, scale) for a perspective camera and the open3d
        backend, with points and lift as (3, N) rows.

        `retest_front_hits` False (LineOptions.retest_front_hits, the draft preset): the plain ray
        is not cast where the lifted ray's near first hit is the front side of a triangle, only
        where it is a back side. The plain ray is there for a lifted origin that starts inside an
        object the surface rests on, whose first hit is then that object's back side; a near
        front-side hit is the surface's own relief around the point, where the plain ray mostly
        meets it too: skipping it changes under 1% of the re-tested answers, nearly all on lines
        edge-on in concave corners (the README's draft figures)."""
        c = P - self._origin_col
        eps = offset * np.maximum(np.sqrt(_einsum_sq(c)), scale)
        eye = np.asarray(camera.eye, float)
        eye_eps = offset * np.linalg.norm(eye - self.origin)
        eye = eye[:, None]
        lifted = P + lift
        d = eye - lifted
        dist = np.sqrt(_einsum_sq(d))
        if retest_front_hits:
            hit_at = self._visible_from_rows(lifted, eye, eps, eye_eps, d, dist, first_hit=True)
        else:
            hit_at, tri = self._visible_from_rows(lifted, eye, eps, eye_eps, d, dist, first_hit=True, faces=True)
        vis = np.isinf(hit_at)
        reach = 100.0 * np.sqrt(_norm_sq(lift)) + eps
        again = np.flatnonzero(~vis & (hit_at <= reach))
        if not retest_front_hits and len(again):
            # Back side: the triangle's normal points along the ray (toward the eye). A normal
            # perpendicular to the ray (dot 0) keeps its re-test too.
            n = np.take(self.scene.face_normals, self._scene_faces(tri.take(again)), axis=0)
            again = again[np.einsum("ij,ji->i", n, d[:, again]) >= 0.0]
        if len(again):
            vis[again] = self._visible_from_rows(P[:, again], eye, eps[again], eye_eps)
        return vis

    def visible_local(self, P: np.ndarray, camera: Camera, offset: float, lift: np.ndarray,
                      scale: np.ndarray, retest_front_hits: bool = True) -> np.ndarray:
        """visible_rows (the draft preset's path) with points P, lifts and local sizes already in
        the Embree frame (centred on the scene, unit radius) as float64 (3, N) rows: the rays
        are built in fewer passes and rounded to float32 (what Embree takes) once. The ray from
        X + e1 u to eye - e2 u (X the lifted point, u the unit direction to the eye at distance
        r, d = eye - X) starts at X + (e1 / r) d with direction d (r - e1 - e2) / r."""
        eye_w = np.asarray(camera.eye, float)
        eye = ((eye_w - self.origin) * self.inv_scale)[:, None]
        eye_eps = offset * math.dist(eye_w, self.origin) * self.inv_scale
        eps = offset * np.maximum(np.sqrt(_sq3(P)), scale)
        lifted = P + lift
        d = eye - lifted
        dist = np.sqrt(_sq3(d))  # > 0: the near plane keeps points off the eye
        e1 = np.minimum(eps, 0.5 * dist)
        seg_len = dist - e1 - np.minimum(np.maximum(eps, eye_eps), 0.25 * dist)
        inv = 1.0 / dist
        rays = np.empty((P.shape[1], 6), np.float32)
        rays[:, :3] = (lifted + d * (e1 * inv)).T
        rays[:, 3:] = (d * (seg_len * inv)).T
        r = self._rs.cast_rays(self._o3c.Tensor(rays))
        f = r["t_hit"].numpy()
        hidden = np.flatnonzero(f <= 1.0)
        vis = np.ones(len(f), bool)
        vis[hidden] = False
        # The contact re-test: only where the hit is near the start (world reach, Embree frame).
        reach = 100.0 * np.sqrt(_sq3(lift.take(hidden, axis=1))) + eps[hidden]
        again = hidden[f[hidden] * seg_len[hidden] <= reach]
        if not retest_front_hits and len(again):
            tri = self._scene_faces(r["primitive_ids"].numpy().take(again))
            again = again[_dot3(self.scene.face_normal_rows.take(tri, axis=1), d.take(again, axis=1)) >= 0.0]
        if len(again):
            # The plain rays (no lift), from the same points.
            Pa = P.take(again, axis=1)
            d = eye - Pa
            dist = np.sqrt(_sq3(d))
            ea = eps[again]
            e1 = np.minimum(ea, 0.5 * dist)
            seg_len = dist - e1 - np.minimum(np.maximum(ea, eye_eps), 0.25 * dist)
            inv = 1.0 / np.where(dist > 0, dist, 1.0)
            rays = np.empty((len(again), 6), np.float32)
            rays[:, :3] = (Pa + d * (e1 * inv)).T
            rays[:, 3:] = (d * (seg_len * inv)).T
            hit = self._rs.test_occlusions(self._o3c.Tensor(rays), tnear=0.0, tfar=1.0)
            vis[again] = ~hit.numpy().astype(bool)
        return vis

    def crossings(self, origins: np.ndarray, directions: np.ndarray) -> np.ndarray:
        """(N,) how many times each ray (world origins, (N, 3) directions) crosses the scene's
        triangles, from its origin on (Embree's count_intersections; trimesh's intersector with
        every hit in the fallback)."""
        o = (origins - self.origin) * self.inv_scale
        if self.backend == "open3d":
            rays = np.concatenate([o, directions], axis=1).astype(np.float32)
            return self._rs.count_intersections(self._o3c.Tensor(rays)).numpy().astype(np.int64)
        _, ray = self._intersector.intersects_id(o.astype(np.float64), np.asarray(directions, np.float64),
                                                 multiple_hits=True)
        return np.bincount(np.asarray(ray, np.int64), minlength=len(o))

    def eye_enclosed(self, camera: Camera, n: int = 64) -> bool:
        """True when the perspective eye sits inside a closed part of the scene, by ray parity: a
        ray from a point inside a closed surface crosses it an odd number of times, from outside an
        even number, whichever way its faces wind (an inside-out cube encloses its inside as much
        as any). Inside when at least 95% of `n` rays spread over the sphere cross an odd number
        of times: a ray that slips through a hole or a crack, or grazes an edge, may miscount."""
        if camera.is_ortho:
            return False
        k = np.arange(n) + 0.5
        phi = np.arccos(1 - 2 * k / n)
        theta = math.pi * (1 + 5 ** 0.5) * k
        dirs = np.stack([np.cos(theta) * np.sin(phi), np.sin(theta) * np.sin(phi), np.cos(phi)], axis=1)
        eye = np.broadcast_to(np.asarray(camera.eye, float), dirs.shape)
        odd = self.crossings(eye, dirs) % 2 == 1
        return bool(odd.mean() >= 0.95)


def _sq3(x: np.ndarray) -> np.ndarray:
    """Squared length of each column of a (3, N) array."""
    return x[0] * x[0] + x[1] * x[1] + x[2] * x[2]


def _dot3(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Dot product of the columns of two (3, N) arrays."""
    return x[0] * y[0] + x[1] * y[1] + x[2] * y[2]


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """np.cross of (N, 3) rows, the same bits (each component a product minus a product), without
    its generic machinery (its overhead dominates on a frame's rows)."""
    return np.stack([a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1], a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
                     a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]], axis=1)


def _einsum_sq(x: np.ndarray) -> np.ndarray:
    """np.einsum("ij,ij->i", X, X) of the (N, 3) X whose rows x (3, N) holds, same bits."""
    return (x[0] * x[0] + x[2] * x[2]) + x[1] * x[1]


def _norm_sq(x: np.ndarray) -> np.ndarray:
    """The square of np.linalg.norm(X, axis=1) before its sqrt, X (N, 3) given as rows x (3, N)."""
    return (x[0] * x[0] + x[1] * x[1]) + x[2] * x[2]


def _order_along_rays(t: np.ndarray, ray: np.ndarray) -> np.ndarray:
    """np.lexsort((t, ray)): the hits by ray, then along it (ties in list order). Embree's list
    comes grouped by ray in ray order, and within a ray mostly in order already (99% of a bunny
    frame's hits): only the rays whose hits are not are sorted (a full lexsort of a frame's
    hits was 2 ms of its level pass)."""
    n = len(t)
    if n < 2:
        return np.arange(n)
    same = ray[1:] == ray[:-1]
    if (ray[1:] < ray[:-1]).any():  # not grouped in ray order: the general sort
        return np.lexsort((t, ray))
    bad = same & (t[1:] < t[:-1])
    o = np.arange(n)
    if bad.any():
        mark = np.zeros(int(ray[-1]) + 1, bool)
        mark[ray[1:][bad]] = True
        sel = np.flatnonzero(mark[ray])  # every hit of those rays (contiguous groups)
        o[sel] = sel[np.lexsort((t[sel], ray[sel]))]
    return o


#: The compiled loops of occlusion-level rays (`strokekit.scene.compiled`), imported on first use:
#: drawings of visible lines only never import numba (warmed up with the hidden-line kernels).
LEVEL_KERNELS = LazyKernels("strokekit.scene.compiled")


def level_kernels():
    """The module `strokekit.scene.compiled`, imported (its kernels loaded or compiled) on first use."""
    return LEVEL_KERNELS.kernels()


def _has_embreex() -> bool:
    try:
        import embreex  # noqa: F401

        return True
    except ImportError:
        return False
