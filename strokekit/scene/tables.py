"""The tables derived from a scene's arrays (`SceneTables`, which `Scene` inherits): vertex normals,
normals split at creases, curvature tensors, the face -> edge table, face sizes, neighbours.

Each is built on first use and kept with the scene as a cached property (`cached_per_value` for a
table that depends on one value, a crease angle or a count of smoothing passes), so a run builds
only what its lines and outputs ask for. What depends on the camera belongs to the frame, not to
the scene (`view_function` here, strokekit.lines.facing for the lines)."""

from __future__ import annotations

import functools
import inspect
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from strokekit.camera.view import Camera


def cached_per_value(method):
    """A table of one argument, built on first use per value of it and kept with the scene beside
    its cached properties (60 and 60.0 are one value)."""
    (param,) = list(inspect.signature(method).parameters.values())[1:]
    default = param.default

    @functools.wraps(method)
    def table(self, value=default):
        kept = self._tables_per_value
        key = (method.__name__, value)
        if key not in kept:
            kept[key] = method(self, value)
        return kept[key]

    return table


@dataclass(frozen=True, eq=False)
class SplitNormals:
    """Vertex normals split at creases. The corners of a vertex are grouped into nodes: corners
    of two faces sharing an edge are in one node when the edge is manifold and its dihedral
    angle is at most the crease threshold (transitively, around the vertex).

    corner (F, 3) node of each face corner; vertex (N,) the mesh vertex of each node; normals
    (N, 3) unit angle-weighted normal of each node; split (E,) mesh edges whose two sides use
    different nodes at one of its ends (plus every non-manifold edge): there the interpolated
    normal jumps, and so does g. positions (V, 3) and center (3,): the scene's vertices and
    centre."""

    corner: np.ndarray
    vertex: np.ndarray
    normals: np.ndarray
    split: np.ndarray
    positions: np.ndarray
    center: np.ndarray

    @cached_property
    def centred(self) -> np.ndarray:
        """(N, 3) the nodes' positions relative to the scene centre (the same in every frame)."""
        return self.positions[self.vertex] - self.center

    def view_function(self, camera: Camera) -> np.ndarray:
        """(N,) g = n . (P - eye) of every node (see `view_function`)."""
        if camera.is_ortho:
            return self.normals @ camera.ray_dir
        return np.einsum("ij,ij->i", self.normals, self.centred) - self.normals @ (np.asarray(camera.eye, float)
                                                                                  - self.center)

    @cached_property
    def corner_gram(self) -> np.ndarray:
        """(F, 3) n_a.n_b, n_b.n_c, n_c.n_a of each face's corner normals (`corner_gram`)."""
        return corner_gram(self.corner, self.normals)

    @cached_property
    def min_corner_norm(self) -> np.ndarray:
        """(F,) `min_interpolated_norm` of each face's corner normals."""
        return min_interpolated_norm(self.corner_gram)


def corner_gram(corner: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """(F, 3) n_a.n_b, n_b.n_c, n_c.n_a of the normals (N, 3) at each face's corners (F, 3)."""
    N = normals[corner]  # (F, 3, 3)
    return np.stack([np.einsum("ij,ij->i", N[:, k], N[:, (k + 1) % 3]) for k in range(3)], axis=1)


def min_interpolated_norm(gram: np.ndarray) -> np.ndarray:
    """(F,) a lower bound of |w_a n_a + w_b n_b + w_c n_c| over a face (weights >= 0 summing to 1)
    from its corner normals' `corner_gram`: |sum w_i n_i|^2 = sum w_i w_j n_i.n_j >= min n_i.n_j,
    floored at 1e-3 (corner normals that nearly cancel)."""
    return np.sqrt(np.clip(np.minimum(np.minimum(gram[:, 0], gram[:, 1]), gram[:, 2]), 1e-6, 1.0))


class SceneTables:
    """The derived tables of a `Scene` (which inherits them): built from its arrays on first use,
    kept as long as the scene."""

    @cached_property
    def _tables_per_value(self) -> dict:
        return {}

    # --- normals ---------------------------------------------------------------------------------
    def _corner_weights(self) -> np.ndarray:
        """(F, 3, 3) each face corner's contribution to its vertex normal: the face normal x the
        corner angle (Thurmer & Wuthrich), so the result does not depend on how a region is
        triangulated."""
        P = self.vertices[self.faces]  # (F, 3, 3)
        e1 = P[:, [1, 2, 0]] - P  # corner k: towards the next vertex
        e2 = P[:, [2, 0, 1]] - P  # corner k: towards the previous vertex
        cosang = np.einsum("fki,fki->fk", e1, e2) / (np.linalg.norm(e1, axis=2) * np.linalg.norm(e2, axis=2))
        ang = np.arccos(np.clip(cosang, -1.0, 1.0))  # (F, 3)
        return ang[..., None] * self.face_normals[:, None, :]

    def _accumulate_normals(self, node: np.ndarray, n_nodes: int) -> np.ndarray:
        """(n_nodes, 3) unit normals: the corner weights summed per node (`node` (3F,) the node of
        each corner in face-major order). A node whose face normals cancel (a needle fold) falls
        back to its first face's normal."""
        w = self._corner_weights()
        n = np.stack([np.bincount(node, w[..., i].ravel(), minlength=n_nodes) for i in range(3)], axis=1)
        ln = np.linalg.norm(n, axis=1)
        bad = ln < 1e-12
        if bad.any():
            first = np.full(n_nodes, -1, np.int64)
            first[node[::-1]] = np.arange(len(node))[::-1] // 3
            n[bad] = self.face_normals[first[bad]]
            ln[bad] = 1.0
        return n / ln[:, None]

    @cached_property
    def vertex_normals(self) -> np.ndarray:
        """(V, 3) unit vertex normals: face normals weighted by the face's corner angle at the
        vertex (Thurmer & Wuthrich), so the result does not depend on how a region is
        triangulated."""
        return self._accumulate_normals(self.faces.ravel(), len(self.vertices))

    @cached_per_value
    def split_normals(self, crease_angle_deg: float = 60.0) -> SplitNormals:
        """Corner normals split at creases sharper than `crease_angle_deg` (degrees), the "auto
        smooth" rule of Blender and the split normals Freestyle users get. On a mesh without such
        edges the nodes are the vertices and the normals are exactly `vertex_normals`."""
        f = self.faces
        F, V, E = len(f), len(self.vertices), len(self.edges)
        count = self.edge_face_count
        gentle = self.is_manifold & ~self.crease_mask(crease_angle_deg)
        if not ((count >= 2) & ~gentle).any():
            return SplitNormals(f, np.arange(V), self.vertex_normals, np.zeros(E, bool), self.vertices, self.center)
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components

        # Link the two corners of each end of every gentle edge; nodes are the connected groups.
        sel = np.flatnonzero(gentle)
        ev, ef = self.edges[sel], self.edge_faces[sel]
        rows, cols = [], []
        for end in (0, 1):
            v = ev[:, end][:, None]
            rows.append(3 * ef[:, 0] + np.argmax(f[ef[:, 0]] == v, axis=1))
            cols.append(3 * ef[:, 1] + np.argmax(f[ef[:, 1]] == v, axis=1))
        r, cc = np.concatenate(rows), np.concatenate(cols)
        g = coo_matrix((np.ones(len(r)), (r, cc)), shape=(3 * F, 3 * F))
        n_nodes, node = connected_components(g, directed=False)
        node = node.astype(np.int64)
        vertex = np.empty(n_nodes, np.int64)
        vertex[node] = f.ravel()
        corner = node.reshape(F, 3)
        # Split edges: the two faces use different nodes at one end (non-manifold: always).
        split = count > 2
        m = np.flatnonzero(count == 2)
        em, efm = self.edges[m], self.edge_faces[m]
        for end in (0, 1):
            v = em[:, end][:, None]
            n0 = corner[efm[:, 0], np.argmax(f[efm[:, 0]] == v, axis=1)]
            n1 = corner[efm[:, 1], np.argmax(f[efm[:, 1]] == v, axis=1)]
            split[m] |= n0 != n1
        return SplitNormals(corner, vertex, self._accumulate_normals(node, n_nodes), split, self.vertices, self.center)

    # --- curvature -------------------------------------------------------------------------------
    @cached_per_value
    def curvature_tensors(self, smooth_passes: int = 0) -> np.ndarray:
        """(V, 3, 3) symmetric second fundamental form of each vertex as a world-space tensor S
        with S n = 0: the normal curvature in unit tangent direction t is t.S.t (1 / world unit,
        > 0 where the surface bends away from its normal, e.g. 1/r on a sphere of radius r).
        `smooth_passes` averages each vertex's tensor with its one-ring that many times.

        After Rusinkiewicz 2004 ("Estimating curvatures and their derivatives on triangle
        meshes"), vectorized: per face, the second fundamental form is the least-squares fit of
        the change of the vertex normals along the three edges; each vertex takes the
        area-weighted mean of its faces' tensors, projected onto its tangent plane (the paper
        rotates the face frame instead of projecting; the difference is second order in the
        angle between face and vertex normals)."""
        if smooth_passes > 0:
            return self._ring_average(self.curvature_tensors(smooth_passes - 1))
        v, f = self.vertices, self.faces
        nv = self.vertex_normals
        P = v[f]  # (F, 3, 3)
        N = nv[f]
        fn = self.face_normals
        # Edges opposite each corner and the matching change of normal.
        E = P[:, [2, 0, 1]] - P[:, [1, 2, 0]]  # (F, 3, 3)
        dN = N[:, [2, 0, 1]] - N[:, [1, 2, 0]]
        u = E[:, 0] / np.linalg.norm(E[:, 0], axis=1)[:, None]
        w = np.cross(fn, u)
        eu, ew = np.einsum("fki,fi->fk", E, u), np.einsum("fki,fi->fk", E, w)
        nu, nw = np.einsum("fki,fi->fk", dN, u), np.einsum("fki,fi->fk", dN, w)
        # Rows per edge: [eu, ew, 0] . (a, b, c) = nu and [0, eu, ew] . (a, b, c) = nw.
        A = np.zeros((len(f), 6, 3))
        A[:, 0::2, 0], A[:, 0::2, 1] = eu, ew
        A[:, 1::2, 1], A[:, 1::2, 2] = eu, ew
        rhs = np.empty((len(f), 6))
        rhs[:, 0::2], rhs[:, 1::2] = nu, nw
        AtA = np.einsum("fki,fkj->fij", A, A)
        Atb = np.einsum("fki,fk->fi", A, rhs)
        abc = np.linalg.solve(AtA, Atb[..., None])[..., 0]
        a, b, cc = abc[:, 0], abc[:, 1], abc[:, 2]
        Sf = (a[:, None, None] * np.einsum("fi,fj->fij", u, u)
              + b[:, None, None] * (np.einsum("fi,fj->fij", u, w) + np.einsum("fi,fj->fij", w, u))
              + cc[:, None, None] * np.einsum("fi,fj->fij", w, w))
        area = self.face_areas
        idx = f.ravel()
        wts = np.repeat(area, 3)
        acc = np.stack([np.bincount(idx, wts * np.repeat(Sf[:, i // 3, i % 3], 3), minlength=len(v))
                        for i in range(9)], axis=1).reshape(-1, 3, 3)
        wsum = np.bincount(idx, wts, minlength=len(v))
        S = acc / np.maximum(wsum, 1e-300)[:, None, None]
        return _project_tangent(S, nv)

    def _ring_average(self, S: np.ndarray) -> np.ndarray:
        """Mean of each vertex's tensor and its edge neighbours' tensors, re-projected."""
        e = self.edges
        V = len(self.vertices)
        flat = S.reshape(V, 9)
        acc = flat.copy()
        for i in range(9):
            acc[:, i] += np.bincount(e[:, 0], flat[e[:, 1], i], V) + np.bincount(e[:, 1], flat[e[:, 0], i], V)
        cnt = 1.0 + np.bincount(e[:, 0], minlength=V) + np.bincount(e[:, 1], minlength=V)
        return _project_tangent((acc / cnt[:, None]).reshape(V, 3, 3), self.vertex_normals)

    # --- faces and edges -------------------------------------------------------------------------
    @cached_property
    def edge_keys(self) -> np.ndarray:
        """(E,) int64 key of each edge, lo (V + 1) + hi: ascending (edges are sorted rows), so an
        edge (lo, hi) is found by a binary search."""
        n1 = len(self.vertices) + 1
        return self.edges[:, 0].astype(np.int64) * n1 + self.edges[:, 1]

    @cached_property
    def face_edges(self) -> np.ndarray:
        """(F, 3) index into edges of face edge k = (vertex k, vertex k+1)."""
        f = self.faces
        half = np.stack([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]], axis=1)  # (F, 3, 2)
        half = np.sort(half, axis=2)
        key = half[..., 0].astype(np.int64) * (len(self.vertices) + 1) + half[..., 1]
        return np.searchsorted(self.edge_keys, key)

    @cached_property
    def manifold_face_pairs(self) -> tuple[np.ndarray, np.ndarray]:
        """(E,) intp first and second face of each manifold edge, F (one past the last face)
        elsewhere: index a per-face array padded with one entry to compare the two faces of
        every edge at once."""
        F = len(self.faces)
        m = self.is_manifold
        ef = self.edge_faces
        return np.where(m, ef[:, 0], F).astype(np.intp), np.where(m, ef[:, 1], F).astype(np.intp)

    @cached_property
    def face_neighbours(self) -> np.ndarray:
        """(F, 3) int64 the faces across each face's manifold edges, -1 for a border or
        non-manifold edge (order not by edge)."""
        ef = self.edge_faces[self.edge_face_count == 2]
        src, dst = np.concatenate([ef[:, 0], ef[:, 1]]), np.concatenate([ef[:, 1], ef[:, 0]])
        order = np.argsort(src, kind="stable")
        src, dst = src[order], dst[order]
        first = np.searchsorted(src, src)
        rank = np.arange(len(src)) - first
        nb = np.full((len(self.faces), 3), -1, np.int64)
        keep = rank < 3
        nb[src[keep], rank[keep]] = dst[keep]
        return nb

    @cached_property
    def faces_int32(self) -> np.ndarray:
        """(F, 3) the faces as contiguous int32 (what the compiled z-buffer reads)."""
        return np.ascontiguousarray(self.faces, dtype=np.int32).reshape(-1, 3)

    @cached_property
    def regions(self) -> tuple[np.ndarray | None, np.ndarray, np.ndarray]:
        """(region (F,) int32 or None for a single one, material (G,), object (G,) of each
        region): the scene's distinct (material, object) pairs and each face's."""
        fm = np.asarray(self.face_material, np.int64).reshape(-1)
        fo = np.asarray(self.face_object, np.int64).reshape(-1)
        if len(fm) == 0:
            return None, np.zeros(1, np.int64), np.zeros(1, np.int64)
        # The pairs in (material, object) order, as one integer each: a 1-D unique (an axis=0
        # unique of the pairs sorts rows as structured values, ten times slower).
        m0, o0 = int(fm.min()), int(fo.min())
        n_obj = int(fo.max()) - o0 + 1
        keys, region = np.unique((fm - m0) * n_obj + (fo - o0), return_inverse=True)
        pairs = np.column_stack([keys // n_obj + m0, keys % n_obj + o0])
        return (region.reshape(-1).astype(np.int32) if len(pairs) > 1 else None, pairs[:, 0], pairs[:, 1])

    @cached_property
    def face_size(self) -> np.ndarray:
        """(F,) longest edge of each face (world units)."""
        v, f = self.vertices, self.faces
        return np.max(np.stack([np.linalg.norm(v[f[:, i]] - v[f[:, (i + 1) % 3]], axis=1) for i in range(3)]),
                      axis=0)

    @cached_per_value
    def face_scale(self, crease_angle_deg: float | None = None) -> np.ndarray:
        """(F,) a face's chord error scale in world units: longest edge x spread of its corner
        normals (|n_i - n_j| max, about the angle they span; the vertex normals, or with
        `crease_angle_deg` the normals split at creases, `split_normals`). A straight chord
        between two surface points a distance L apart whose normals turn by theta departs from
        the smooth surface by about L theta / 8."""
        v, f = self.vertices, self.faces
        if crease_angle_deg is None:
            N = self.vertex_normals[f]
        else:
            sn = self.split_normals(crease_angle_deg)
            N = sn.normals[sn.corner]
        L = np.max(np.stack([np.linalg.norm(v[f[:, i]] - v[f[:, (i + 1) % 3]], axis=1) for i in range(3)]), axis=0)
        spread = np.max(np.stack([np.linalg.norm(N[:, i] - N[:, (i + 1) % 3], axis=1) for i in range(3)]), axis=0)
        return L * spread

    @cached_per_value
    def flat_faces(self, crease_angle_deg: float = 60.0) -> np.ndarray:
        """(F,) faces whose corner normals, split at `crease_angle_deg`, are all their plane
        normal (within 1e-6 of the face size): a box's faces, a cylinder's caps."""
        return self.face_scale(crease_angle_deg) <= 1e-6 * self.face_size


def _project_tangent(S: np.ndarray, n: np.ndarray) -> np.ndarray:
    Pm = np.eye(3)[None] - np.einsum("vi,vj->vij", n, n)
    S = Pm @ S @ Pm
    return 0.5 * (S + np.transpose(S, (0, 2, 1)))


def view_function(scene, camera: Camera, normals: np.ndarray | None = None,
                  vertex: np.ndarray | None = None) -> np.ndarray:
    """(N,) g = n . (P - eye) (perspective) or n . fwd (orthographic) per node: > 0 where the
    normal faces away from the eye. Nodes are the vertices (normals (V, 3), default the vertex
    normals) or, with `vertex` (N,) the mesh vertex of each node, split-normal nodes."""
    n = scene.vertex_normals if normals is None else normals
    if camera.is_ortho:
        return n @ camera.ray_dir  # (fwd but for the oblique projections: their rays' direction)
    # Relative to the scene centre for precision far from the origin.
    c = scene.center
    rel = scene.vertices - c if vertex is None else scene.vertices[vertex] - c
    return np.einsum("ij,ij->i", n, rel) - n @ (np.asarray(camera.eye, float) - c)


# The per-row formulas of Scene's face and edge tables: a moving scene's frame computes them again
# for its moving faces only (scene.motion), with the same operations, so its tables are a static
# scene's.

def bounds_of(v: np.ndarray) -> np.ndarray:
    """(2, 3) min and max corners of points v (N, 3), reduced along contiguous rows (numpy's
    reductions down the three columns of an (N, 3) array are some 20 times slower)."""
    c = np.ascontiguousarray(v.T)
    return np.stack([c.min(axis=1), c.max(axis=1)])


def row_norms(d: np.ndarray) -> np.ndarray:
    """(N,) np.linalg.norm(d, axis=1) of rows d (N, 3), written out (the same values)."""
    x, y, z = d[:, 0], d[:, 1], d[:, 2]
    return np.sqrt(x * x + y * y + z * z)


def same_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(N,) (a == b).all(axis=1) of rows (N, 3), column by column."""
    return (a[:, 0] == b[:, 0]) & (a[:, 1] == b[:, 1]) & (a[:, 2] == b[:, 2])


def face_corners_of(v: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The corners (F, 3) each of faces (F, 3) over vertices v."""
    return v.take(faces[:, 0], axis=0), v.take(faces[:, 1], axis=0), v.take(faces[:, 2], axis=0)


def face_crosses_of(v: np.ndarray, faces: np.ndarray, corners: tuple | None = None) -> tuple[np.ndarray, np.ndarray]:
    """((F, 3) cross products (b - a) x (c - a) of faces (F, 3) over vertices v, (F,) their
    norms: twice each face's area, as the weld measures it). np.cross and np.linalg.norm's
    operations written out (the same values, without their overhead). `corners`: their
    face_corners_of, when gathered already."""
    # Relative to the first vertex for precision when the scene is far from the origin.
    a, b, c = face_corners_of(v, faces) if corners is None else corners
    e1, e2 = b - a, c - a
    x = e1[:, 1] * e2[:, 2] - e1[:, 2] * e2[:, 1]
    y = e1[:, 2] * e2[:, 0] - e1[:, 0] * e2[:, 2]
    z = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    return np.stack([x, y, z], axis=1), np.sqrt(x * x + y * y + z * z)


def face_normals_of(v: np.ndarray, faces: np.ndarray, crosses: tuple | None = None) -> np.ndarray:
    """(F, 3) unit normals of faces (F, 3) over vertices v (Scene.face_normals). `crosses`: their
    face_crosses_of, when made already."""
    n, norm = face_crosses_of(v, faces) if crosses is None else crosses
    return n / norm[:, None]


def face_offsets_of(v: np.ndarray, faces: np.ndarray, normals: np.ndarray, corners: tuple | None = None) -> np.ndarray:
    """(F,) n.P of each face's centroid (Scene.face_offsets). `corners`: as face_crosses_of's."""
    a, b, c = face_corners_of(v, faces) if corners is None else corners
    return np.einsum("ij,ij->i", normals, (a + b + c) / 3.0)  # (np.mean's sum and division)


def dihedral_cos_of(edge_faces: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """(E,) cosine between the normals of each edge's two faces, 1 for an edge with one (Scene.dihedral_cos)."""
    ok = edge_faces[:, 1] >= 0
    c = np.ones(len(edge_faces))
    if ok.all():
        c[:] = np.einsum("ij,ij->i", normals.take(edge_faces[:, 0], axis=0), normals.take(edge_faces[:, 1], axis=0))
        return c
    ef = edge_faces[ok]
    c[ok] = np.einsum("ij,ij->i", normals.take(ef[:, 0], axis=0), normals.take(ef[:, 1], axis=0))
    return c
