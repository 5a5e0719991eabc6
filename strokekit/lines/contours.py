"""Smooth (interpolated) contours: the zero set of g = n . (P - eye) with n interpolated from
vertex normals (Hertzmann & Zorin 2000; Benard & Hertzmann tutorial section 6.2).

Normals are split at creases (`split_normals`, Blender's "auto smooth" rule): the corners of a
vertex share one normal only across edges whose dihedral angle is below the crease threshold, so
each face interpolates its own corner normals and a flat face (all corners = its plane normal)
holds no zero crossing. Along the edges where the corner normals differ on the two sides (split
edges) the contour falls back to the mesh silhouette test, with the interpolated g of each side
(`sharp_edge_contours`): the part of the edge where one side faces the eye and the other does
not. Between two flat faces that is exactly the mesh silhouette; where a smooth side's g crosses
zero on the edge, the piece starts at that very crossing, so the smooth contour runs on into the
sharp edge.

g is evaluated at the vertices and interpolated linearly along each mesh edge, so every face
where g changes sign holds exactly one straight segment whose endpoints lie on two of its edges.
The endpoint on edge e gets the chaining key V + e: the two faces of e produce the same key, so
`chaining.chain_runs` links the segments across faces into smooth curves. On a split edge each
side has its own crossing, keyed V + E + 3 f + k (face f, its edge k); the sharp-edge piece that
starts there carries the same key, and sharp-edge pieces meet each other at mesh vertex keys
(< V). Where the contour's screen tangent reverses (a cusp) the key is -1 instead, so strokes
split there.

The crossing points are moved from the chord onto the Phong surface of the corner normals
(`phong_points`), which puts them on a sphere's analytic circle to second order. Their occlusion
rays get a lift (`contour_lift`) because they graze the facets around them.

Per-scene data (angle-weighted vertex normals, the face -> edge table, face sizes) is computed
once and kept in a cache keyed by the Scene object (weakly, so it goes away with the scene);
suggestive.py and intersections.py keep theirs there too.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from strokekit.camera.view import Camera
from strokekit.lines.facing import FrameView
from strokekit.lines.surface import surface_lift
from strokekit.model import KIND_INDEX, FeatureEdges
from strokekit.scene.load import Scene
from strokekit.scene.tables import SplitNormals

#: Lift of a smooth contour's occlusion ray origin (see `contour_lift`): LIFT_GAIN x the face's
#: chord error scale along the normal, VIEW_LIFT_GAIN x the face's longest edge toward the eye.
#: A smaller view lift reports more grazing contour as hidden; a larger one ignores occluders
#: within that depth, so hidden contour shows near T-junctions of bumpy scans. These values
#: balance the two (benchmarks/bench_line_types.py, section 3, measures both).
LIFT_GAIN = 0.25
VIEW_LIFT_GAIN = 3.5


@dataclass(frozen=True, eq=False)
class ZeroSet:
    """The zero set of a per-node function, one straight segment per face where it changes sign.

    faces (S,) the faces holding a segment; edges (C,) the mesh edge of each crossing point;
    t (C,) the crossing parameter on edge e = (i, j), i < j: P_i + t (P_j - P_i); ends (C, 2) the
    nodes at i and j (the vertices themselves unless normals are split); keys (C,) chaining keys:
    V + e, or V + E + 3 f + k on a split edge (each side, face f with edge k, has its own
    crossing); ia, ib (S,) the segment's start and end as indices into the crossings, oriented
    so that the side g > 0 is on the right when the face is seen from its front (one consistent
    orientation along every curve)."""

    faces: np.ndarray
    edges: np.ndarray
    t: np.ndarray
    ia: np.ndarray
    ib: np.ndarray
    ends: np.ndarray
    keys: np.ndarray

    def __len__(self) -> int:
        return len(self.faces)

    def interpolate(self, scene: Scene, values: np.ndarray) -> np.ndarray:
        """(C, k) per-node `values` (N, k) linearly interpolated at the crossing points (nodes
        are vertices unless the set was built on split normals)."""
        t = self.t[:, None]
        return values[self.ends[:, 0]] * (1 - t) + values[self.ends[:, 1]] * t


def zero_set_segments(scene: Scene, g: np.ndarray, face_mask: np.ndarray | None = None,
                      corner: np.ndarray | None = None, split: np.ndarray | None = None) -> ZeroSet:
    """The zero set of the node function g (N,), interpolated linearly along edges, on the faces
    where g changes sign (restricted to `face_mask` (F,) if given). Nodes are the vertices, or
    with `corner` (F, 3) the node of each face corner (split normals) and `split` (E,) the edges
    whose sides use different nodes. g == 0 counts as negative, so every face has 0 or 2 crossing
    edges and neighbours agree on the crossing of a shared unsplit edge."""
    f = scene.faces
    cn = f if corner is None else corner
    V, E = len(scene.vertices), len(scene.edges)
    pos = g > 0
    fpos = pos[cn]  # (F, 3)
    npos = fpos.sum(axis=1, dtype=np.int8)
    has = (npos == 1) | (npos == 2)
    if face_mask is not None:
        has &= face_mask
    faces = np.flatnonzero(has)
    fp = fpos[faces]
    lone_pos = npos[faces] == 1
    # The lone vertex L has the sign the other two do not have.
    L = np.where(lone_pos, np.argmax(fp, axis=1), np.argmin(fp, axis=1))
    ka = (L + 2) % 3  # face edge (v_{L-1}, v_L)
    kb = L  # face edge (v_L, v_{L+1})
    # From the crossing on ka to the one on kb the lone vertex lies on the right.
    k = np.concatenate([np.where(lone_pos, ka, kb), np.where(lone_pos, kb, ka)])
    ff = np.concatenate([faces, faces])
    e = scene.face_edges[ff, k]
    key = V + e.astype(np.int64)
    if split is not None:
        key = np.where(split[e], V + E + 3 * ff.astype(np.int64) + k, key)
    keys, first, inv = np.unique(key, return_index=True, return_inverse=True)
    cf, ck = ff[first], k[first]
    a, na, nb = f[cf, ck], cn[cf, ck], cn[cf, (ck + 1) % 3]
    lo_first = a < f[cf, (ck + 1) % 3]
    ends = np.stack([np.where(lo_first, na, nb), np.where(lo_first, nb, na)], axis=1)
    g0, g1 = g[ends[:, 0]], g[ends[:, 1]]
    t = g0 / (g0 - g1)  # g0 and g1 have opposite signs (or one is 0): no division by zero
    n = len(faces)
    inv = inv.ravel()
    return ZeroSet(faces=faces, edges=e[first], t=t, ia=inv[:n], ib=inv[n:], ends=ends, keys=keys)


def _phong(vi, vj, ni, nj, t, alpha=0.5):
    p = vi + t * (vj - vi)
    di = np.einsum("ij,ij->i", vi - p, ni)[:, None] * ni
    dj = np.einsum("ij,ij->i", vj - p, nj)[:, None] * nj
    return p + alpha * ((1 - t) * di + t * dj)


def phong_points(scene: Scene, zs: ZeroSet, normals: np.ndarray, alpha: float = 0.5) -> np.ndarray:
    """(C, 3) the crossing points of `zs`, lifted from the chord onto the smooth surface that
    the node normals (N, 3) describe (Phong tessellation, Boubekeur & Alexa 2008, on the edge).

    p = linear point; each end vertex i contributes its tangent-plane projection
    pi_i(p) = p + ((v_i - p) . n_i) n_i; P = p + alpha ((1-t) (pi_i - p) + t (pi_j - p)).
    alpha = 1/2 is the quadratic whose end tangents lie in the vertex tangent planes: it puts a
    chord of a circle back on the circle to second order (the chord's sagitta is L^2 k / 8, the
    correction is alpha L^2 k / 4), so contour points land on the smooth surface, not on its
    polyhedral approximation. Where both end normals are the plane normal of a flat face the
    point stays on the edge."""
    e = scene.edges[zs.edges]
    return _phong(scene.vertices[e[:, 0]], scene.vertices[e[:, 1]], normals[zs.ends[:, 0]],
                  normals[zs.ends[:, 1]], zs.t[:, None], alpha)


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
            if camera.is_oblique:
                kx, ky = camera.shear
                ux, uy = ux + kx * uz, uy + ky * uz
            return np.stack([ux, -uy], axis=1)
        x, y, z = q @ right, q @ up, q @ fwd
        return np.stack([ux * z - x * uz, -(uy * z - y * uz)], axis=1)

    t2, n2 = jac(tangents), jac(normals)
    return np.sign(t2[:, 0] * n2[:, 1] - t2[:, 1] * n2[:, 0])


def smooth_contour_edges(view: FrameView, lift_gain: float = LIFT_GAIN,
                         split_cusps: bool = True, crease_angle_deg: float = 60.0,
                         occlusion_offset: float = 1e-5) -> FeatureEdges:
    """Smooth contour segments of one frame as FeatureEdges of kind "smooth_contour" (the first
    element of `smooth_contours`)."""
    return smooth_contours(view, lift_gain, split_cusps, crease_angle_deg, occlusion_offset)[0]


def smooth_contours(view: FrameView, lift_gain: float = LIFT_GAIN, split_cusps: bool = True,
                    crease_angle_deg: float = 60.0, occlusion_offset: float = 1e-5
                    ) -> tuple[FeatureEdges, np.ndarray]:
    """Smooth contours of one frame with normals split at creases sharper than `crease_angle_deg`.

    Returns (FeatureEdges of kind "smooth_contour", (K,) indices of the mesh edges that a
    sharp-edge piece covers whole; feature_edges gives those no other kind, as a mesh silhouette
    overrides crease / material / border).

    Segments inside faces: a, b (S, 3) world endpoints, the crossing points on two mesh edges of
    the face moved onto the Phong surface of the corner normals (`phong_points`), oriented
    consistently along each curve; va, vb the crossings' chaining keys (`ZeroSet.keys`), or -1 at
    a cusp so that strokes split there; face (S,) the face holding the segment; lift (S, 3) from
    `contour_lift`. Flat faces (`flat_faces`) hold none. Then the pieces of `sharp_edge_contours`
    along split edges (their lift is described there; `occlusion_offset` as LineOptions'), with
    key -1 where the screen tangent reverses at a junction with a piece (`_split_reversals`)."""
    scene, camera = view.scene, view.camera
    sn = scene.split_normals(crease_angle_deg)
    g = sn.view_function(camera)
    flat = scene.flat_faces(crease_angle_deg)
    # g is constant on a flat face: no crossing there, whatever the rounding when it is edge-on.
    zs = zero_set_segments(scene, g, face_mask=~flat if flat.any() else None, corner=sn.corner, split=sn.split)
    parts = []
    if len(zs):
        pts = phong_points(scene, zs, sn.normals)
        nrm = zs.interpolate(scene, sn.normals)
        a, b = pts[zs.ia], pts[zs.ib]
        nm = nrm[zs.ia] + nrm[zs.ib]
        nm /= np.maximum(np.linalg.norm(nm, axis=1), 1e-300)[:, None]
        lift = contour_lift(scene, camera, zs.faces, 0.5 * (a + b), nm, lift_gain,
                            scale=scene.face_scale(crease_angle_deg))
        key = zs.keys
        if split_cusps:
            key = np.where(cusp_mask(camera, zs, a, b, nm), -1, key)
        kind = np.full(len(zs), KIND_INDEX["smooth_contour"], np.int8)
        parts.append(FeatureEdges(a=a, b=b, kind=kind, va=key[zs.ia], vb=key[zs.ib],
                                  face=zs.faces.astype(np.int64), lift=lift))
    sharp, full = sharp_edge_contours(view, sn, g, occlusion_offset, lift_gain, scene.face_scale(crease_angle_deg),
                                      flat)
    parts.append(sharp)
    fe = FeatureEdges.concat(parts)
    if split_cusps and len(sharp):
        fe = _split_reversals(camera, fe, len(fe) - len(sharp))
    return fe, full


def _split_reversals(camera: Camera, fe: FeatureEdges, first_piece: int) -> FeatureEdges:
    """`fe` with key -1 at every junction of two segments where the screen tangent reverses
    (both leave the shared key on the same side) and one of them is a sharp-edge piece (index
    >= `first_piece`): the cusps of the contour along sharp edges (smooth-smooth junctions had
    theirs from `cusp_mask`, with the same test)."""
    S = len(fe)
    pa, _ = camera.project(fe.a)
    pb, _ = camera.project(fe.b)
    key = np.concatenate([fe.va, fe.vb])
    away = np.concatenate([pb - pa, pa - pb])  # screen direction from each end into its segment
    is_piece = np.tile(np.arange(S) >= first_piece, 2)
    ends = np.flatnonzero(key >= 0)
    order = ends[np.argsort(key[ends], kind="stable")]
    ks = key[order]
    start = np.flatnonzero(np.r_[True, ks[1:] != ks[:-1]])
    count = np.diff(np.r_[start, len(ks)])
    p0, p1 = order[start[count == 2]], order[start[count == 2] + 1]
    cusp = (np.einsum("ij,ij->i", away[p0], away[p1]) > 0) & (is_piece[p0] | is_piece[p1])
    key = key.copy()
    key[p0[cusp]] = -1
    key[p1[cusp]] = -1
    return replace(fe, va=key[:S], vb=key[S:])


def sharp_edge_contours(view: FrameView, sn: SplitNormals, g: np.ndarray,
                        occlusion_offset: float = 1e-5, lift_gain: float = LIFT_GAIN,
                        scale: np.ndarray | None = None, flat: np.ndarray | None = None
                        ) -> tuple[FeatureEdges, np.ndarray]:
    """Contour pieces along the split manifold edges (kind "smooth_contour"), and (K,) the edges
    they cover whole.

    Each side s of a split edge (i, j) has its own g_s, linear along the edge from its corner
    nodes; the contour is where the two sides disagree, (g_0 > 0) != (g_1 > 0): one side faces
    the eye and the other does not. Two flat sides have constant g, so this is the mesh
    silhouette test and the piece is the whole edge (endpoints the vertices exactly). Where a
    side's g crosses zero on the edge (a smooth side) the piece ends at that crossing, at the same
    point and with the same key (V + E + 3 f + k) as the smooth segment of that face, so chaining
    goes on from one to the other; whole-edge ends carry the vertex ids, as mesh silhouettes.
    face: the side facing the eye along the piece. `g` (N,) the view function of the nodes of
    `sn`; `scale` (F,) the chord error scales for `contour_lift`; `flat` (F,) faces whose side
    takes its facing from the frame's front_facing (the mesh silhouette's own test, so that an
    edge-on face is decided as in mesh mode; default the scene's `flat_faces`).

    Occlusion lift: where one side is flat (its corner normals are its plane normal and it has
    an unsplit edge: a box, a cylinder's cap) that of a mesh silhouette (lines.surface_lift, `occlusion_offset` x scene
    radius), so flat geometry is drawn exactly as in mesh mode. Between two curved sides (noisy
    scans: the bunny has 110 edges sharper than 60 degrees) the ray grazes the 1-ring like a
    smooth contour's and gets `contour_lift` (with the mesh lift such pieces are hit by adjacent
    faces a few hundredths of a face size away and wrongly hidden)."""
    scene = view.scene
    E_s = np.flatnonzero(sn.split & scene.is_manifold)
    if len(E_s) == 0:
        return FeatureEdges.empty(), np.zeros(0, np.int64)
    f = scene.faces
    V, E = len(scene.vertices), len(scene.edges)
    ev, ef = scene.edges[E_s], scene.edge_faces[E_s]
    fe = scene.face_edges
    P = scene.vertices
    vi, vj = P[ev[:, 0]], P[ev[:, 1]]

    flat = scene.flat_faces(60.0) if flat is None else flat
    front = view.front_facing
    cuts, keys, gs, pts, nodes, crosses = [], [], [], [], [], []
    for side in (0, 1):
        fs = ef[:, side]
        k = np.argmax(fe[fs] == E_s[:, None], axis=1)  # the face's local edge index of e
        na, nb = sn.corner[fs, k], sn.corner[fs, (k + 1) % 3]
        lo_first = f[fs, k] == ev[:, 0]
        nlo, nhi = np.where(lo_first, na, nb), np.where(lo_first, nb, na)
        g0, g1 = g[nlo], g[nhi]
        # A flat side: g is constant along the edge, its sign that of the mesh facing test.
        fl = flat[fs]
        if fl.any():
            const = np.where(front[fs[fl]], -1.0, 1.0)
            g0, g1 = g0.copy(), g1.copy()
            g0[fl], g1[fl] = const, const
        cross = (g0 > 0) != (g1 > 0)
        # Same formula and operands as zero_set_segments: bit-identical t and point.
        t = np.where(cross, g0 / np.where(cross, g0 - g1, 1.0), 1.0)
        cuts.append(t)
        keys.append(V + E + 3 * fs.astype(np.int64) + k)
        gs.append((g0, g1))
        nodes.append((nlo, nhi))
        crosses.append(cross)
        pts.append(_phong(vi, vj, sn.normals[nlo], sn.normals[nhi], t[:, None]))
    S = len(E_s)
    # Breakpoints along each edge: lo vertex, side 0 crossing, side 1 crossing, hi vertex.
    bs = np.stack([np.zeros(S), cuts[0], cuts[1], np.ones(S)], axis=1)
    bkey = np.stack([ev[:, 0].astype(np.int64), keys[0], keys[1], ev[:, 1].astype(np.int64)], axis=1)
    bpt = np.stack([vi, pts[0], pts[1], vj], axis=1)  # (S, 4, 3)
    # Ties broken by type; a side without a crossing has a placeholder at s = 1 that sorts after
    # the hi vertex, so that no kept interval ends on it.
    typ = np.broadcast_to(np.arange(4), bs.shape)
    placeholder = np.stack([np.zeros(S, bool), ~crosses[0], ~crosses[1], np.zeros(S, bool)], axis=1)
    order = np.lexsort((typ, placeholder, bs), axis=-1)
    rows = np.arange(S)[:, None]
    bs, bkey, bpt = bs[rows, order], bkey[rows, order], bpt[rows, order]
    sa, sb = bs[:, :-1], bs[:, 1:]  # (S, 3) intervals
    m = 0.5 * (sa + sb)
    pos0 = (gs[0][0][:, None] + m * (gs[0][1] - gs[0][0])[:, None]) > 0
    pos1 = (gs[1][0][:, None] + m * (gs[1][1] - gs[1][0])[:, None]) > 0
    keep = (sb > sa) & (pos0 != pos1)
    r, c = np.nonzero(keep)
    if len(r) == 0:
        return FeatureEdges.empty(), np.zeros(0, np.int64)
    face = np.where(pos0[r, c], ef[r, 1], ef[r, 0]).astype(np.int64)
    a, b = bpt[r, c], bpt[r, c + 1]
    out = FeatureEdges(a=a, b=b, kind=np.full(len(r), KIND_INDEX["smooth_contour"], np.int8),
                       va=bkey[r, c], vb=bkey[r, c + 1], face=face)
    # The occlusion lift of a mesh silhouette (along the eye-facing face normals), looked up by
    # the edge's vertex ids.

    probe = FeatureEdges(a=a, b=b, kind=out.kind, va=ev[r, 0].astype(np.int64), vb=ev[r, 1].astype(np.int64),
                         face=face)
    lift = surface_lift(view, probe, occlusion_offset)
    scale = scene.face_scale() if scale is None else scale
    fsize = scene.face_size

    def curved(faces):
        # Flat: corner normals all the plane normal, and part of a region (one of its edges
        # unsplit; a scan's spike triangle cut off by sharp edges all round has its own normal).
        return (scale[faces] > 1e-6 * fsize[faces]) | sn.split[fe[faces]].all(axis=1)

    # A piece that ends on a smooth crossing grazes the smooth side there as the smooth contour
    # does (the polygon's own silhouette vertex is up to half an edge away): same lift.
    at_crossing = (bkey[r, c] >= V) | (bkey[r, c + 1] >= V)
    fold = (curved(ef[r, 0]) & curved(ef[r, 1])) | at_crossing
    if fold.any():
        # The interpolated normal of the side that faces the eye (the mean of both sides cancels
        # at the needle folds of scans and would put the origin inside the surface).
        mid = m[r, c][:, None]
        front1 = pos0[r, c]
        lo = np.where(front1, nodes[1][0][r], nodes[0][0][r])
        hi = np.where(front1, nodes[1][1][r], nodes[0][1][r])
        nrm = sn.normals[lo] * (1 - mid) + sn.normals[hi] * mid
        nrm /= np.maximum(np.linalg.norm(nrm, axis=1), 1e-300)[:, None]
        big = np.where(fsize[ef[r, 0]] >= fsize[ef[r, 1]], ef[r, 0], ef[r, 1])
        lift[fold] = contour_lift(scene, view.camera, big[fold], 0.5 * (a[fold] + b[fold]), nrm[fold], lift_gain,
                                  scale=scale)
    full = E_s[np.unique(r[(sa[r, c] == 0.0) & (sb[r, c] == 1.0)])]
    return replace(out, lift=lift), full


def contour_lift(scene: Scene, camera: Camera, faces: np.ndarray, mid: np.ndarray, normal: np.ndarray,
                 gain: float = LIFT_GAIN, view_gain: float | None = None,
                 scale: np.ndarray | None = None) -> np.ndarray:
    """(S, 3) occlusion-ray lift of segments that lie on `faces` near world points `mid` where the
    surface normal is `normal` (unit): `gain` x (chord error scale along the normal + face size
    toward the eye), plus 1e-6 scene radii along the normal.

    Why both: the ray from a contour point is tangent to the smooth surface and the mesh departs
    from that surface by up to about a chord error (`face_scale` / 8), so (1) the origin must rise
    above the facets by a few chord errors, and (2) a grazing ray stays within that band for about
    a face length, so hits closer than that along the ray are the point's own neighbourhood, not
    an occluder. Moving along the line of sight does not move the point's projection.
    `scale` (F,): the chord error scales to use (default `face_scale(scene)`, vertex normals)."""
    view = (VIEW_LIFT_GAIN if view_gain is None else view_gain) * scene.face_size[faces]
    if camera.is_ortho:
        toward = np.broadcast_to(-camera.view_dir, mid.shape)  # (-fwd but for oblique rays)
    else:
        toward = np.asarray(camera.eye, float) - mid
        dist = np.linalg.norm(toward, axis=1)
        toward = toward / np.maximum(dist, 1e-300)[:, None]
        # Long faces (a cylinder's sides span its height) must not carry the origin past the eye.
        view = np.minimum(view, 0.5 * dist)
    scale = scene.face_scale() if scale is None else scale
    return normal * (gain * scale[faces] + 1e-6 * scene.radius)[:, None] + toward * view[:, None]


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
