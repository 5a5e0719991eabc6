"""Smooth (interpolated) contours: the zero set of g = n . (P - eye) with n interpolated from
vertex normals (Hertzmann & Zorin 2000; Benard & Hertzmann tutorial section 6.2).

g is evaluated at the vertices and interpolated linearly along each mesh edge, so every face
where g changes sign holds exactly one straight segment whose endpoints lie on two of its edges.
The endpoint on edge e gets the chaining key V + e: the two faces of e produce the same key, so
`chaining.chain_runs` links the segments across faces into smooth curves. Where the contour's
screen tangent reverses (a cusp) the key is -1 instead, so strokes split there.

The crossing points are moved from the chord onto the Phong surface of the vertex normals
(`phong_points`), which puts them on a sphere's analytic circle to second order. Their occlusion
rays get a lift (`contour_lift`) because they graze the facets around them.

Per-scene data (angle-weighted vertex normals, the face -> edge table, face sizes) is computed
once and kept in a cache keyed by the Scene object (weakly, so it goes away with the scene);
suggestive.py and intersections.py keep theirs there too.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np

from .camera import Camera
from .model import KIND_INDEX, FeatureEdges
from .scene import Scene

_CACHE: "weakref.WeakKeyDictionary[Scene, dict]" = weakref.WeakKeyDictionary()

#: Lift of a smooth contour's occlusion ray origin (see `contour_lift`): LIFT_GAIN x the face's
#: chord error scale along the normal, VIEW_LIFT_GAIN x the face's longest edge toward the eye.
#: Measured (benchmarks/bench_line_types.py, section 3; 16-24 frame bunny orbits): with
#: 0.25 / 3.5 the share of smooth contour wrongly reported hidden is 0 on a sphere, < 0.01 % on a
#: torus and about 0.03 % on the bunny (3.0: 0.10-0.13 %; 4.0: 0.02 %). The price is the other
#: way: a larger view lift ignores occluders within that depth, so near T-junctions of bumpy
#: scans some hidden contour shows (bunny: visible smooth contour farther than 2 px from any
#: visible mesh contour 0.6 % at 3.0, 0.9 % at 3.5, 1.4 % at 4.0). Larger normal lifts pop hidden
#: contour loops into view; a lift scaled by the radial curvature was tried and missed grazing
#: hits on the bunny (2.6-3 % wrongly hidden).
LIFT_GAIN = 0.25
VIEW_LIFT_GAIN = 3.5


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


@dataclass(frozen=True, eq=False)
class ZeroSet:
    """The zero set of a per-vertex function, one straight segment per face where it changes sign.

    faces (S,) the faces holding a segment; edges (C,) the mesh edges the set crosses (each once),
    t (C,) the crossing parameter on edge e = (i, j), i < j: P_i + t (P_j - P_i); ia, ib (S,) the
    segment's start and end as indices into `edges`, oriented so that the side g > 0 is on the
    right when the face is seen from its front (one consistent orientation along every curve)."""

    faces: np.ndarray
    edges: np.ndarray
    t: np.ndarray
    ia: np.ndarray
    ib: np.ndarray

    def __len__(self) -> int:
        return len(self.faces)

    def interpolate(self, scene: Scene, values: np.ndarray) -> np.ndarray:
        """(C, k) per-vertex `values` (V, k) linearly interpolated at the crossing points."""
        e = scene.edges[self.edges]
        t = self.t[:, None]
        return values[e[:, 0]] * (1 - t) + values[e[:, 1]] * t


def zero_set_segments(scene: Scene, g: np.ndarray, face_mask: np.ndarray | None = None) -> ZeroSet:
    """The zero set of the vertex function g (V,), interpolated linearly along edges, on the faces
    where g changes sign (restricted to `face_mask` (F,) if given). g == 0 counts as negative, so
    every face has 0 or 2 crossing edges and neighbours agree on the crossing of a shared edge."""
    f = scene.faces
    pos = g > 0
    fpos = pos[f]  # (F, 3)
    npos = fpos.sum(axis=1, dtype=np.int8)
    has = (npos == 1) | (npos == 2)
    if face_mask is not None:
        has &= face_mask
    faces = np.flatnonzero(has)
    fp = fpos[faces]
    lone_pos = npos[faces] == 1
    # The lone vertex L has the sign the other two do not have.
    L = np.where(lone_pos, np.argmax(fp, axis=1), np.argmin(fp, axis=1))
    fe = face_edges(scene)
    ea = fe[faces, (L + 2) % 3]  # edge (v_{L-1}, v_L)
    eb = fe[faces, L]  # edge (v_L, v_{L+1})
    # From the crossing on ea to the one on eb the lone vertex lies on the right.
    a_edge = np.where(lone_pos, ea, eb)
    b_edge = np.where(lone_pos, eb, ea)
    edges, inv = np.unique(np.concatenate([a_edge, b_edge]), return_inverse=True)
    n = len(faces)
    ev = scene.edges[edges]
    g0, g1 = g[ev[:, 0]], g[ev[:, 1]]
    t = g0 / (g0 - g1)  # g0 and g1 have opposite signs (or one is 0): no division by zero
    return ZeroSet(faces=faces, edges=edges, t=t, ia=inv[:n], ib=inv[n:])


def phong_points(scene: Scene, zs: ZeroSet, normals: np.ndarray, alpha: float = 0.5) -> np.ndarray:
    """(C, 3) the crossing points of `zs`, lifted from the chord onto the smooth surface that
    the vertex normals describe (Phong tessellation, Boubekeur & Alexa 2008, on the edge).

    p = linear point; each end vertex i contributes its tangent-plane projection
    pi_i(p) = p + ((v_i - p) . n_i) n_i; P = p + alpha ((1-t) (pi_i - p) + t (pi_j - p)).
    alpha = 1/2 is the quadratic whose end tangents lie in the vertex tangent planes: it puts a
    chord of a circle back on the circle to second order (the chord's sagitta is L^2 k / 8, the
    correction is alpha L^2 k / 4), so contour points land on the smooth surface, not on its
    polyhedral approximation."""
    e = scene.edges[zs.edges]
    vi, vj = scene.vertices[e[:, 0]], scene.vertices[e[:, 1]]
    t = zs.t[:, None]
    p = vi + t * (vj - vi)
    ni, nj = normals[e[:, 0]], normals[e[:, 1]]
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

    a, b (S, 3) world endpoints: the crossing points on two mesh edges of the face, moved onto the
    Phong surface (`phong_points`), oriented consistently along each curve; va, vb = V + edge
    index (chaining keys), or -1 at a cusp so that strokes split there; face (S,) the face holding
    the segment; lift (S, 3) from `contour_lift`."""
    V = len(scene.vertices)
    nv = vertex_normals(scene)
    g = view_function(scene, camera, nv)
    zs = zero_set_segments(scene, g)
    if len(zs) == 0:
        return FeatureEdges.empty()
    pts = phong_points(scene, zs, nv)
    nrm = zs.interpolate(scene, nv)
    a, b = pts[zs.ia], pts[zs.ib]
    nm = nrm[zs.ia] + nrm[zs.ib]
    nm /= np.maximum(np.linalg.norm(nm, axis=1), 1e-300)[:, None]
    lift = contour_lift(scene, camera, zs.faces, 0.5 * (a + b), nm, lift_gain)
    key = V + zs.edges.astype(np.int64)
    if split_cusps:
        key = np.where(cusp_mask(camera, zs, a, b, nm), -1, key)
    kind = np.full(len(zs), KIND_INDEX["smooth_contour"], np.int8)
    return FeatureEdges(a=a, b=b, kind=kind, va=key[zs.ia], vb=key[zs.ib], face=zs.faces.astype(np.int64),
                        lift=lift)


def face_size(scene: Scene) -> np.ndarray:
    """(F,) longest edge of each face (world units). Cached."""
    c = scene_cache(scene)
    if "face_size" not in c:
        v, f = scene.vertices, scene.faces
        c["face_size"] = np.max(np.stack([np.linalg.norm(v[f[:, i]] - v[f[:, (i + 1) % 3]], axis=1)
                                          for i in range(3)]), axis=0)
    return c["face_size"]


def contour_lift(scene: Scene, camera: Camera, faces: np.ndarray, mid: np.ndarray, normal: np.ndarray,
                 gain: float = LIFT_GAIN, view_gain: float | None = None) -> np.ndarray:
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
            + toward * ((VIEW_LIFT_GAIN if view_gain is None else view_gain) * face_size(scene)[faces])[:, None])


def cusp_mask(camera: Camera, zs: ZeroSet, a: np.ndarray, b: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """(C,) True at the crossing points of `zs` where the smooth contour has a cusp: the two
    segments meeting there have opposite `screen_side`, or their screen directions make an
    obtuse angle (the screen tangent reverses; on noisy meshes the projected normal of a tiny
    segment can turn with it, hiding the reversal from the side test)."""
    side = screen_side(camera, 0.5 * (a + b), b - a, normal)
    pa, _ = camera.project(a)
    pb, _ = camera.project(b)
    d = pb - pa
    C = len(zs.edges)
    # Each interior crossing point is the end (ib) of one segment and the start (ia) of the next.
    s_in, s_out = np.zeros(C), np.zeros(C)
    d_in, d_out = np.zeros((C, 2)), np.zeros((C, 2))
    s_in[zs.ib], d_in[zs.ib] = side, d
    s_out[zs.ia], d_out[zs.ia] = side, d
    return ((s_in * s_out) < 0) | (np.einsum("ij,ij->i", d_in, d_out) < 0)
