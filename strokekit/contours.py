"""Smooth (interpolated) contours: the zero set of g = n . (P - eye) with n interpolated from
vertex normals (Hertzmann & Zorin 2000; Benard & Hertzmann tutorial section 6.2).

g is evaluated at the vertices and interpolated linearly along each mesh edge, so every face
where g changes sign holds exactly one straight segment whose endpoints lie on two of its edges.
The endpoint on edge e gets the chaining key V + e: the two faces of e produce the same key, so
`chaining.chain_runs` links the segments across faces into smooth curves.

Per-scene data (angle-weighted vertex normals, the face -> edge table) is computed once and kept
in a cache keyed by the Scene object (weakly, so it goes away with the scene).
"""

from __future__ import annotations

import weakref

import numpy as np

from .camera import Camera
from .model import KIND_INDEX, FeatureEdges
from .scene import Scene

_CACHE: "weakref.WeakKeyDictionary[Scene, dict]" = weakref.WeakKeyDictionary()

#: Lift of a contour point's occlusion ray origin, as a multiple of the face's own chord error
#: estimate (longest edge x normal spread); see `smooth_contour_edges`.
LIFT_GAIN = 0.5


def scene_cache(scene: Scene) -> dict:
    """A dict of derived per-scene arrays that lives as long as the scene."""
    d = _CACHE.get(scene)
    if d is None:
        d = {}
        _CACHE[scene] = d
    return d


def vertex_normals(scene: Scene) -> np.ndarray:
    """(V, 3) unit vertex normals: face normals weighted by the face's corner angle at the vertex
    (Thurmer & Wuthrich), so the result does not depend on how a region is triangulated. Cached."""
    c = scene_cache(scene)
    if "vertex_normals" not in c:
        v, f = scene.vertices, scene.faces
        P = v[f]  # (F, 3, 3)
        e1 = P[:, [1, 2, 0]] - P  # corner k: towards the next vertex
        e2 = P[:, [2, 0, 1]] - P  # corner k: towards the previous vertex
        cosang = np.einsum("fki,fki->fk", e1, e2) / (np.linalg.norm(e1, axis=2) * np.linalg.norm(e2, axis=2))
        ang = np.arccos(np.clip(cosang, -1.0, 1.0))  # (F, 3)
        w = ang[..., None] * scene.face_normals[:, None, :]  # (F, 3, 3)
        idx = f.ravel()
        n = np.stack([np.bincount(idx, w[..., i].ravel(), minlength=len(v)) for i in range(3)], axis=1)
        ln = np.linalg.norm(n, axis=1)
        # A vertex whose face normals cancel (a needle fold) falls back to its first face's normal.
        bad = ln < 1e-12
        if bad.any():
            first = np.full(len(v), -1, np.int64)
            first[f[::-1].ravel()] = np.repeat(np.arange(len(f))[::-1], 3)
            n[bad] = scene.face_normals[first[bad]]
            ln[bad] = 1.0
        c["vertex_normals"] = n / ln[:, None]
    return c["vertex_normals"]


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


def face_scale(scene: Scene) -> np.ndarray:
    """(F,) a face's chord error scale in world units: longest edge x spread of its vertex normals
    (|n_i - n_j| max, about the angle they span). A straight chord between two surface points a
    distance L apart whose normals turn by theta departs from the smooth surface by about
    L theta / 8. Cached."""
    c = scene_cache(scene)
    if "face_scale" not in c:
        v, f = scene.vertices, scene.faces
        nv = vertex_normals(scene)
        L = np.max(np.stack([np.linalg.norm(v[f[:, i]] - v[f[:, (i + 1) % 3]], axis=1) for i in range(3)]), axis=0)
        spread = np.max(np.stack([np.linalg.norm(nv[f[:, i]] - nv[f[:, (i + 1) % 3]], axis=1) for i in range(3)]),
                        axis=0)
        c["face_scale"] = L * spread
    return c["face_scale"]


def view_function(scene: Scene, camera: Camera, normals: np.ndarray | None = None) -> np.ndarray:
    """(V,) g = n . (P - eye) (perspective) or n . fwd (orthographic) at every vertex: > 0 where
    the vertex normal faces away from the eye."""
    n = vertex_normals(scene) if normals is None else normals
    if camera.is_ortho:
        _, _, fwd = camera.basis
        return n @ fwd
    # Relative to the scene centre for precision far from the origin.
    c = scene.center
    return np.einsum("ij,ij->i", n, scene.vertices - c) - n @ (np.asarray(camera.eye, float) - c)


def zero_set_segments(scene: Scene, g: np.ndarray, face_mask: np.ndarray | None = None):
    """The zero set of the vertex function g (V,) interpolated linearly along edges.

    Returns (faces (S,), edge_a (S,), edge_b (S,), t_edge (E,), crossing (E,)): one segment per
    face where g changes sign (restricted to `face_mask` (F,) if given), from its crossing point on
    edge_a to the one on edge_b, oriented so that the side g > 0 is on the right when the face is
    seen from its front (a consistent orientation of the curve across faces). The crossing point
    of edge e = (i, j) (i < j) is P_i + t_edge[e] (P_j - P_i). g == 0 counts as negative."""
    e = scene.edges
    pos = g > 0
    crossing = pos[e[:, 0]] != pos[e[:, 1]]
    ga, gb = g[e[:, 0]], g[e[:, 1]]
    with np.errstate(divide="ignore", invalid="ignore"):
        t_edge = np.where(crossing, ga / (ga - gb), 0.0)
    fe = face_edges(scene)
    cf = crossing[fe]  # (F, 3); each face has 0 or 2 crossing edges
    has = cf.any(axis=1)
    if face_mask is not None:
        has &= face_mask
    faces = np.flatnonzero(has)
    k = np.argmin(cf[faces], axis=1)  # the edge without a crossing
    rows = faces
    ea = fe[rows, (k + 1) % 3]  # edge (v_{k+1}, v_{k+2})
    eb = fe[rows, (k + 2) % 3]  # edge (v_{k+2}, v_k)
    # Going from the crossing on ea to the one on eb, the lone vertex v_{k+2} is on the right.
    lone_pos = pos[scene.faces[rows, (k + 2) % 3]]
    a_edge = np.where(lone_pos, ea, eb)
    b_edge = np.where(lone_pos, eb, ea)
    return faces, a_edge, b_edge, t_edge, crossing


def edge_points(scene: Scene, t_edge: np.ndarray, edges: np.ndarray, values: np.ndarray | None = None) -> np.ndarray:
    """Points (or per-vertex `values` (V, k)) interpolated at parameter t_edge[e] on edges e."""
    src = scene.vertices if values is None else values
    i, j = scene.edges[edges, 0], scene.edges[edges, 1]
    t = t_edge[edges][:, None]
    return src[i] + t * (src[j] - src[i])


def phong_edge_points(scene: Scene, t_edge: np.ndarray, edges: np.ndarray, normals: np.ndarray,
                      alpha: float = 0.5) -> np.ndarray:
    """(N, 3) points at t_edge[e] on edges e, lifted from the chord onto the smooth surface that
    the vertex normals describe (Phong tessellation, Boubekeur & Alexa 2008, on the edge).

    p = linear point; each end vertex i contributes its tangent-plane projection
    pi_i(p) = p + ((v_i - p) . n_i) n_i; P = p + alpha ((1-t) (pi_i - p) + t (pi_j - p)).
    alpha = 1/2 is the quadratic whose end tangents lie in the vertex tangent planes: it puts a
    chord of a circle back on the circle to second order (the chord's sagitta is L^2 k / 8, the
    correction is alpha L^2 k / 4), so contour points land on the smooth surface, not on its
    polyhedral approximation."""
    i, j = scene.edges[edges, 0], scene.edges[edges, 1]
    vi, vj = scene.vertices[i], scene.vertices[j]
    t = t_edge[edges][:, None]
    p = vi + t * (vj - vi)
    ni, nj = normals[i], normals[j]
    di = np.einsum("ij,ij->i", vi - p, ni)[:, None] * ni
    dj = np.einsum("ij,ij->i", vj - p, nj)[:, None] * nj
    return p + alpha * ((1 - t) * di + t * dj)


def screen_side(camera: Camera, points: np.ndarray, tangents: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """(N,) sign of det[screen tangent, screen normal] at world `points`: +1 / -1 (0 if degenerate).

    At a regular contour point the projected normal points across the silhouette and the oriented
    tangent along it, so this sign stays constant along the curve; it flips where the screen
    tangent reverses (a cusp)."""
    right, up, fwd = camera.basis
    q = points - np.asarray(camera.eye, float)

    def jac(u):  # screen velocity (y down) of a world direction u at the points, up to a positive factor
        ux, uy, uz = u @ right, u @ up, u @ fwd
        if camera.is_ortho:
            return np.stack([ux, -uy], axis=1)
        x, y, z = q @ right, q @ up, q @ fwd
        return np.stack([ux * z - x * uz, -(uy * z - y * uz)], axis=1)

    t2, n2 = jac(tangents), jac(normals)
    return np.sign(t2[:, 0] * n2[:, 1] - t2[:, 1] * n2[:, 0])


def smooth_contour_edges(scene: Scene, camera: Camera, lift_gain: float = LIFT_GAIN,
                         split_cusps: bool = True) -> FeatureEdges:
    """Smooth contour segments of one frame as FeatureEdges of kind "smooth_contour".

    a, b (S, 3) world endpoints on mesh edges (oriented consistently along each curve); va, vb =
    V + edge index (chaining keys), or -1 at a cusp so that strokes split there; face (S,) the
    face holding the segment; lift (S, 3): the interpolated normal at the segment's middle times
    `lift_gain` x the face's chord error scale, plus 1e-6 scene radii. The smooth contour runs on
    chords below the smooth surface, so a ray to the eye from the segment itself grazes (and often
    enters) the faces around it; lifting the ray origin off the surface by a few chord errors
    along the normal removes those false hits while staying far below any real occluder's size."""
    V = len(scene.vertices)
    nv = vertex_normals(scene)
    g = view_function(scene, camera, nv)
    faces, ea, eb, t_edge, crossing = zero_set_segments(scene, g)
    if len(faces) == 0:
        return FeatureEdges.empty()
    a = phong_edge_points(scene, t_edge, ea, nv)
    b = phong_edge_points(scene, t_edge, eb, nv)
    na = edge_points(scene, t_edge, ea, nv)
    nb = edge_points(scene, t_edge, eb, nv)
    nm = na + nb
    nm /= np.maximum(np.linalg.norm(nm, axis=1), 1e-300)[:, None]
    lift = contour_lift(scene, camera, faces, 0.5 * (a + b), nm, lift_gain)
    va = V + ea.astype(np.int64)
    vb = V + eb.astype(np.int64)
    if split_cusps:
        cusp = cusp_edges(scene, camera, faces, ea, eb, a, b, nm)
        va = np.where(cusp[ea], -1, va)
        vb = np.where(cusp[eb], -1, vb)
    kind = np.full(len(faces), KIND_INDEX["smooth_contour"], np.int8)
    return FeatureEdges(a=a, b=b, kind=kind, va=va, vb=vb, face=faces.astype(np.int64), lift=lift)


def face_size(scene: Scene) -> np.ndarray:
    """(F,) longest edge of each face (world units). Cached."""
    c = scene_cache(scene)
    if "face_size" not in c:
        v, f = scene.vertices, scene.faces
        c["face_size"] = np.max(np.stack([np.linalg.norm(v[f[:, i]] - v[f[:, (i + 1) % 3]], axis=1)
                                          for i in range(3)]), axis=0)
    return c["face_size"]


def contour_lift(scene: Scene, camera: Camera, faces: np.ndarray, mid: np.ndarray, normal: np.ndarray,
                 gain: float = LIFT_GAIN) -> np.ndarray:
    """(S, 3) occlusion-ray lift of segments that lie on `faces` near world points `mid` where the
    surface normal is `normal` (unit): `gain` x (chord error scale along the normal + face size
    toward the eye), plus 1e-6 scene radii along the normal.

    Why both: the ray from a contour point is tangent to the smooth surface and the mesh departs
    from that surface by up to about a chord error (`face_scale` / 8), so (1) the origin must rise
    above the facets by a few chord errors, and (2) a grazing ray stays within that band for about
    a face length, so hits closer than that along the ray are the point's own neighbourhood, not
    an occluder. Moving along the line of sight does not move the point's projection."""
    if camera.is_ortho:
        _, _, fwd = camera.basis
        toward = np.broadcast_to(-fwd, mid.shape)
    else:
        toward = np.asarray(camera.eye, float) - mid
        toward = toward / np.maximum(np.linalg.norm(toward, axis=1), 1e-300)[:, None]
    return (normal * (gain * face_scale(scene)[faces] + 1e-6 * scene.radius)[:, None]
            + toward * (gain * face_size(scene)[faces])[:, None])


def cusp_edges(scene: Scene, camera: Camera, faces, ea, eb, a, b, nm) -> np.ndarray:
    """(E,) True on mesh edges where the smooth contour has a cusp: the two segments meeting at the
    edge's crossing point have opposite `screen_side` (their screen tangent reverses)."""
    side = screen_side(camera, 0.5 * (a + b), b - a, nm)
    E = len(scene.edges)
    # Each crossing edge is the end (b) of one segment and the start (a) of the next.
    s_in = np.zeros(E)
    s_out = np.zeros(E)
    s_in[eb] = side
    s_out[ea] = side
    return (s_in * s_out) < 0
