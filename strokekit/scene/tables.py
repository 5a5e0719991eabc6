"""Per-scene tables derived once and kept with the scene (`scene_cache`, weakly keyed): angle-
weighted vertex normals, normals split at creases, the face -> edge table, face sizes, and the
per-vertex view function g = n . (P - eye) that contours are the zero set of."""

from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np

from strokekit.camera.view import Camera
from strokekit.scene.load import Scene

_CACHE: "weakref.WeakKeyDictionary[Scene, dict]" = weakref.WeakKeyDictionary()


def scene_cache(scene: Scene) -> dict:
    """A dict of derived per-scene arrays that lives as long as the scene."""
    d = _CACHE.get(scene)
    if d is None:
        d = {}
        _CACHE[scene] = d
    return d


def _corner_weights(scene: Scene) -> np.ndarray:
    """(F, 3, 3) each face corner's contribution to its vertex normal: the face normal x the
    corner angle (Thurmer & Wuthrich), so the result does not depend on how a region is
    triangulated."""
    v, f = scene.vertices, scene.faces
    P = v[f]  # (F, 3, 3)
    e1 = P[:, [1, 2, 0]] - P  # corner k: towards the next vertex
    e2 = P[:, [2, 0, 1]] - P  # corner k: towards the previous vertex
    cosang = np.einsum("fki,fki->fk", e1, e2) / (np.linalg.norm(e1, axis=2) * np.linalg.norm(e2, axis=2))
    ang = np.arccos(np.clip(cosang, -1.0, 1.0))  # (F, 3)
    return ang[..., None] * scene.face_normals[:, None, :]


def _accumulate_normals(scene: Scene, node: np.ndarray, n_nodes: int) -> np.ndarray:
    """(n_nodes, 3) unit normals: the corner weights summed per node (`node` (3F,) the node of
    each corner in face-major order). A node whose face normals cancel (a needle fold) falls
    back to its first face's normal."""
    w = _corner_weights(scene)
    n = np.stack([np.bincount(node, w[..., i].ravel(), minlength=n_nodes) for i in range(3)], axis=1)
    ln = np.linalg.norm(n, axis=1)
    bad = ln < 1e-12
    if bad.any():
        first = np.full(n_nodes, -1, np.int64)
        first[node[::-1]] = np.arange(len(node))[::-1] // 3
        n[bad] = scene.face_normals[first[bad]]
        ln[bad] = 1.0
    return n / ln[:, None]


def vertex_normals(scene: Scene) -> np.ndarray:
    """(V, 3) unit vertex normals: face normals weighted by the face's corner angle at the vertex
    (Thurmer & Wuthrich), so the result does not depend on how a region is triangulated. Cached."""
    c = scene_cache(scene)
    if "vertex_normals" not in c:
        c["vertex_normals"] = _accumulate_normals(scene, scene.faces.ravel(), len(scene.vertices))
    return c["vertex_normals"]


@dataclass(frozen=True, eq=False)
class SplitNormals:
    """Vertex normals split at creases. The corners of a vertex are grouped into nodes: corners
    of two faces sharing an edge are in one node when the edge is manifold and its dihedral
    angle is at most the crease threshold (transitively, around the vertex).

    corner (F, 3) node of each face corner; vertex (N,) the mesh vertex of each node; normals
    (N, 3) unit angle-weighted normal of each node; split (E,) mesh edges whose two sides use
    different nodes at one of its ends (plus every non-manifold edge): there the interpolated
    normal jumps, and so does g."""

    corner: np.ndarray
    vertex: np.ndarray
    normals: np.ndarray
    split: np.ndarray

    def view_function(self, scene: Scene, camera: Camera) -> np.ndarray:
        """(N,) g = n . (P - eye) of every node (see `view_function`), with the nodes' positions
        relative to the scene centre kept from the first call (they do not change per frame)."""
        if camera.is_ortho:
            return view_function(scene, camera, self.normals)
        rel = self.__dict__.get("_centred")
        if rel is None:
            rel = scene.vertices[self.vertex] - scene.center
            object.__setattr__(self, "_centred", rel)
        return np.einsum("ij,ij->i", self.normals, rel) - self.normals @ (np.asarray(camera.eye, float) - scene.center)


def split_normals(scene: Scene, crease_angle_deg: float = 60.0) -> SplitNormals:
    """Corner normals split at creases sharper than `crease_angle_deg` (degrees), the "auto
    smooth" rule of Blender and the split normals Freestyle users get. On a mesh without such
    edges the nodes are the vertices and the normals are exactly `vertex_normals`. Cached per
    threshold."""
    key = ("split_normals", float(crease_angle_deg))
    c = scene_cache(scene)
    if key in c:
        return c[key]
    f = scene.faces
    F, V, E = len(f), len(scene.vertices), len(scene.edges)
    count = scene.edge_face_count
    gentle = scene.is_manifold & ~scene.crease_mask(crease_angle_deg)
    if not ((count >= 2) & ~gentle).any():
        out = SplitNormals(corner=f, vertex=np.arange(V), normals=vertex_normals(scene), split=np.zeros(E, bool))
        c[key] = out
        return out
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    # Link the two corners of each end of every gentle edge; nodes are the connected groups.
    sel = np.flatnonzero(gentle)
    ev, ef = scene.edges[sel], scene.edge_faces[sel]
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
    em, efm = scene.edges[m], scene.edge_faces[m]
    for end in (0, 1):
        v = em[:, end][:, None]
        n0 = corner[efm[:, 0], np.argmax(f[efm[:, 0]] == v, axis=1)]
        n1 = corner[efm[:, 1], np.argmax(f[efm[:, 1]] == v, axis=1)]
        split[m] |= n0 != n1
    out = SplitNormals(corner=corner, vertex=vertex, normals=_accumulate_normals(scene, node, n_nodes),
                       split=split)
    c[key] = out
    return out


def face_edges(scene: Scene) -> np.ndarray:
    """(F, 3) index into scene.edges of face edge k = (vertex k, vertex k+1). Cached."""
    c = scene_cache(scene)
    if "face_edges" not in c:
        f = scene.faces
        half = np.stack([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]], axis=1)  # (F, 3, 2)
        half = np.sort(half, axis=2)
        n1 = len(scene.vertices) + 1
        key = half[..., 0].astype(np.int64) * n1 + half[..., 1]
        ekey = scene.edges[:, 0].astype(np.int64) * n1 + scene.edges[:, 1]
        c["face_edges"] = np.searchsorted(ekey, key)
    return c["face_edges"]


def face_scale(scene: Scene, crease_angle_deg: float | None = None) -> np.ndarray:
    """(F,) a face's chord error scale in world units: longest edge x spread of its corner normals
    (|n_i - n_j| max, about the angle they span; the vertex normals, or with `crease_angle_deg`
    the normals split at creases, `split_normals`). A straight chord between two surface points
    a distance L apart whose normals turn by theta departs from the smooth surface by about
    L theta / 8. Cached."""
    c = scene_cache(scene)
    key = "face_scale" if crease_angle_deg is None else ("face_scale", float(crease_angle_deg))
    if key not in c:
        v, f = scene.vertices, scene.faces
        if crease_angle_deg is None:
            N = vertex_normals(scene)[f]
        else:
            sn = split_normals(scene, crease_angle_deg)
            N = sn.normals[sn.corner]
        L = np.max(np.stack([np.linalg.norm(v[f[:, i]] - v[f[:, (i + 1) % 3]], axis=1) for i in range(3)]), axis=0)
        spread = np.max(np.stack([np.linalg.norm(N[:, i] - N[:, (i + 1) % 3], axis=1) for i in range(3)]), axis=0)
        c[key] = L * spread
    return c[key]


def face_size(scene: Scene) -> np.ndarray:
    """(F,) longest edge of each face (world units). Cached."""
    c = scene_cache(scene)
    if "face_size" not in c:
        v, f = scene.vertices, scene.faces
        c["face_size"] = np.max(np.stack([np.linalg.norm(v[f[:, i]] - v[f[:, (i + 1) % 3]], axis=1)
                                          for i in range(3)]), axis=0)
    return c["face_size"]


def view_function(scene: Scene, camera: Camera, normals: np.ndarray | None = None,
                  vertex: np.ndarray | None = None) -> np.ndarray:
    """(N,) g = n . (P - eye) (perspective) or n . fwd (orthographic) per node: > 0 where the
    normal faces away from the eye. Nodes are the vertices (normals (V, 3), default the vertex
    normals) or, with `vertex` (N,) the mesh vertex of each node, split-normal nodes."""
    n = vertex_normals(scene) if normals is None else normals
    if camera.is_ortho:
        return n @ camera.ray_dir  # (fwd but for the oblique projections: their rays' direction)
    # Relative to the scene centre for precision far from the origin.
    c = scene.center
    rel = scene.vertices - c if vertex is None else scene.vertices[vertex] - c
    return np.einsum("ij,ij->i", n, rel) - n @ (np.asarray(camera.eye, float) - c)
