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

    def without_faces(self, drop: np.ndarray) -> "Occluder":
        """An occluder of the same scene (same frame) in which the faces where `drop` (F,) is True
        hide nothing: the faces a frame sees exactly edge-on (lines.facing.FrameView.edge_on).
        Its first hits give scene face numbers too; its BVH is built now."""
        keep = np.flatnonzero(~np.asarray(drop, bool))
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
        r = self._rs.cast_rays(self._o3c.Tensor.from_numpy(np.ascontiguousarray(rays)))
        ids = r["primitive_ids"].numpy().view(np.int32)  # (uint32 "no hit", 0xFFFFFFFF, reads as -1)
        return {"t_hit": r["t_hit"].numpy(), "primitive_ids": ids, "primitive_uvs": r["primitive_uvs"].numpy()}

    def test_occlusions(self, rays: np.ndarray) -> np.ndarray:
        """(N,) True where the (N, 6) float32 local ray meets a triangle for t in [0, 1] (open3d)."""
        return self._rs.test_occlusions(self._o3c.Tensor(rays), tnear=0.0, tfar=1.0).numpy().astype(bool)

    def list_intersections(self, rays: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every hit of the (N, 6) float32 local rays, in one Embree call (open3d): (t_hit (K,)
        float32, ray_ids (K,), primitive_ids (K,) Embree's ids), grouped by ray."""
        lx = self._rs.list_intersections(self._o3c.Tensor(rays))
        return lx["t_hit"].numpy(), lx["ray_ids"].numpy(), lx["primitive_ids"].numpy()

    def count_intersections(self, rays: np.ndarray) -> np.ndarray:
        """(N,) how many triangles each (N, 6) float32 local ray meets from its origin on (open3d)."""
        return self._rs.count_intersections(self._o3c.Tensor(rays)).numpy()

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
            t = self._rs.cast_rays(self._o3c.Tensor(self._local_rays(origins, targets)))["t_hit"].numpy().astype(float)
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


def _has_embreex() -> bool:
    try:
        import embreex  # noqa: F401

        return True
    except ImportError:
        return False
