"""The exact reference for hidden lines: every candidate mesh edge sampled finely
on screen and the occlusion level of each sample counted by the definition (BRIEF 2: the
triangles the open segment from the point to the eye crosses, the edge's own faces excluded),
in float64; and the measures of a hidden-line drawing against it.

The count (`exact_levels`): Embree (float32) lists the triangles each segment meets, from the
point itself (no lift, no offset); the candidates are those triangles, every triangle sharing a
vertex with one of them (what float32 rounding might have missed beside a hit: a ray through
an edge hits one of its triangles), and the triangles around the edge's own two vertices (what a
ray leaving the surface may graze). Each candidate is tested in float64 (Moller-Trumbore, the
open segment 0 < t < 1, the closed triangle); crossings at one place (|dt| length <= 1e-9 of the
scene radius) on triangles that share a vertex and face the ray alike are one crossing (a ray
through an edge or a vertex); faces seen edge-on cross nothing.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from strokekit.camera.view import Camera
from strokekit.lines.facing import FrameView
from strokekit.lines.features import feature_edges
from strokekit.lines.visibility import clip_segments
from strokekit.metrics.accuracy import DEFAULT_TOLS, Accuracy, aggregate, frame_accuracy
from strokekit.model import MAX_OCCLUSION, N_KINDS, Strokes, row_norm
from strokekit.options import LineOptions
from strokekit.sampling import locate, resample_strokes
from strokekit.scene.load import Scene
from strokekit.scene.occluder import Occluder


def _vertex_faces(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """CSR (offsets (V + 1,), faces) of the faces around each vertex."""
    f = scene.faces.ravel()
    order = np.argsort(f, kind="stable")
    offsets = np.searchsorted(f[order], np.arange(len(scene.vertices) + 1))
    return offsets, order // 3


def _gather(offsets, items, keys, owner):
    """(owner, item) for every item of CSR rows `keys` (one owner per key)."""
    n = offsets[keys + 1] - offsets[keys]
    rows = np.repeat(np.arange(len(keys)), n)
    pos = np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n) + np.repeat(offsets[keys], n)
    return owner[rows], items[pos]


def exact_levels(scene: Scene, camera: Camera, points: np.ndarray, own: np.ndarray,
                 occluder: Occluder | None = None, batch: int = 20000) -> np.ndarray:
    """(N,) occlusion level of world points (N, 3) on mesh edges whose faces are `own` (N, 2),
    -1 for none: the triangles the open segment from each point to the eye (parallel cameras:
    along the projection rays to the near plane) crosses, own faces excluded, in float64 (see the
    module doc)."""
    occluder = Occluder(scene) if occluder is None else occluder
    out = np.zeros(len(points), np.int64)
    for s in range(0, len(points), batch):
        out[s:s + batch] = _exact_levels(scene, camera, points[s:s + batch], own[s:s + batch], occluder)
    return out


def _exact_levels(scene, camera, P, own, occ):
    n = len(P)
    if camera.is_ortho:
        _, _, fwd = camera.basis
        reach = (P - np.asarray(camera.eye, float)) @ fwd - camera.near_distance(scene.radius)
        D = -np.maximum(reach, 0.0)[:, None] * camera.ray_dir[None, :]
    else:
        D = np.asarray(camera.eye, float)[None, :] - P
    # Embree's candidates, from the point itself.
    k = occ.inv_scale
    rays = np.concatenate([(P - occ.origin) * k, D * k], axis=1).astype(np.float32)
    _, ray, prim = occ.list_intersections(rays)
    ray = ray.astype(np.int64)
    prim = occ.scene_faces(prim)
    F = scene.faces
    vo, vf = _vertex_faces(scene)
    # Expanded: the triangles sharing a vertex with a hit, and those around the own edge's vertices.
    r1, f1 = _gather(vo, vf, F[prim].ravel(), np.repeat(ray, 3))
    has = own[:, 0] >= 0
    if has.any():
        fa = F[own[has, 0]]
        fb = np.where(own[has, 1:2] >= 0, F[np.maximum(own[has, 1], 0)], -1)
        # The own edge's vertices: the vertices the two own faces share (or the first face's, alone).
        both = (fa[:, :, None] == fb[:, None, :]).any(axis=2)
        shared = np.where(both.sum(axis=1, keepdims=True) >= 2, np.where(both, fa, -1), fa)
        idx = np.flatnonzero(has)
        rows = np.repeat(idx, 3)
        vals = shared.ravel()
        good = vals >= 0
        r2, f2 = _gather(vo, vf, vals[good], rows[good])
    else:
        r2 = f2 = np.zeros(0, np.int64)
    cand = np.unique(np.concatenate([ray * len(F) + prim, r1 * len(F) + f1, r2 * len(F) + f2]))
    cr, cf = cand // len(F), cand % len(F)
    keep = (cf != own[cr, 0]) & (cf != own[cr, 1])
    cr, cf = cr[keep], cf[keep]
    # Moller-Trumbore in float64 on the open segment P -> P + D.
    V = scene.vertices
    A, B, C = V[F[cf, 0]], V[F[cf, 1]], V[F[cf, 2]]
    e1, e2 = B - A, C - A
    d = D[cr]
    pv = np.cross(d, e2)
    det = np.einsum("ij,ij->i", e1, pv)
    n_len = row_norm(np.cross(e1, e2)) * row_norm(d)
    ok = np.abs(det) > 1e-12 * n_len  # a face seen edge-on covers nothing
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / det
        tv = P[cr] - A
        u = np.einsum("ij,ij->i", tv, pv) * inv
        qv = np.cross(tv, e1)
        v = np.einsum("ij,ij->i", d, qv) * inv
        t = np.einsum("ij,ij->i", e2, qv) * inv
    hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0) & (t < 1)
    cr, cf, t, side = cr[hit], cf[hit], t[hit], det[hit] > 0
    o = np.lexsort((t, cr))
    cr, cf, t, side = cr[o], cf[o], t[o], side[o]
    dup = np.zeros(len(cr), bool)
    if len(cr) > 1:
        same = (cr[1:] == cr[:-1]) & ((t[1:] - t[:-1]) * row_norm(D[cr[1:]]) <= 1e-9 * scene.radius)
        fa, fb = F[cf[:-1]], F[cf[1:]]
        share = (fa[:, :, None] == fb[:, None, :]).any(axis=(1, 2))
        dup[1:] = same & share & (side[1:] == side[:-1])
    return np.bincount(cr[~dup], minlength=n)


def _world(camera: Camera, A, B, za, zb, seg, s):
    """World points at screen parameters s of the segments A -> B (view depths za, zb)."""
    lam = s if camera.is_ortho else s * za[seg] / ((1 - s) * zb[seg] + s * za[seg])
    return A[seg] + lam[:, None] * (B[seg] - A[seg])


def _own_faces(scene: Scene, va: np.ndarray, vb: np.ndarray) -> np.ndarray:
    """(N, 2) the faces of the mesh edges va-vb (-1: not a mesh edge, or a single face)."""
    V = len(scene.vertices)
    lo, hi = np.minimum(va, vb), np.maximum(va, vb)
    keys = scene.edge_keys
    q = lo * (V + 1) + hi
    pos = np.clip(np.searchsorted(keys, q), 0, len(keys) - 1)
    found = (keys[pos] == q) & (va >= 0) & (vb >= 0) & (va < V) & (vb < V)
    out = np.full((len(va), 2), -1, np.int64)
    out[found] = scene.edge_faces[pos[found]][:, :2]
    return out


def reference_drawing(scene: Scene, camera: Camera, options: LineOptions, step_px: float = 0.25,
                      occluder: Occluder | None = None) -> Strokes:
    """The exact hidden-line drawing of the mesh feature edges of `options.kinds` (not lines inside
    faces): each clipped edge sampled at the middles of parts at most `step_px` long on screen,
    each sample's exact level; a piece per run of equal levels, cut halfway between two samples
    that differ, its kind code carrying min(level, MAX_OCCLUSION) (model.MAX_OCCLUSION). One
    stroke per piece, surface points included."""
    occluder = Occluder(scene) if occluder is None else occluder
    fe = feature_edges(FrameView(scene, camera), options, with_lift=False)
    mesh = (fe.va >= 0) & (fe.vb >= 0) & (fe.va < len(scene.vertices)) & (fe.vb < len(scene.vertices))
    near = camera.near_distance(scene.radius)
    t0, t1 = clip_segments(fe.a, fe.b, camera, near)
    idx = np.flatnonzero((t1 > t0) & mesh)
    a, b = fe.a[idx], fe.b[idx]
    A = a + t0[idx, None] * (b - a)
    B = a + t1[idx, None] * (b - a)
    pa, za = camera.project(A)
    pb, zb = camera.project(B)
    L = row_norm(pb - pa)
    m = np.maximum(1, np.ceil(L / step_px)).astype(np.int64)
    # Samples at the middles of m equal parts (not at the ends: a mesh vertex belongs to every edge
    # around it, and a ray from it grazes them all); runs of equal level cut halfway between two
    # samples that differ, the first and last runs reaching the segment's ends.
    seg = np.repeat(np.arange(len(idx)), m)
    k = np.arange(m.sum()) - np.repeat(np.cumsum(m) - m, m)
    s = (k + 0.5) / m[seg]
    own = _own_faces(scene, fe.va[idx], fe.vb[idx])
    lev = exact_levels(scene, camera, _world(camera, A, B, za, zb, seg, s), own[seg], occluder)
    new = np.ones(len(seg), bool)
    new[1:] = (seg[1:] != seg[:-1]) | (lev[1:] != lev[:-1])
    first = np.flatnonzero(new)
    last = np.append(first[1:] - 1, len(seg) - 1)
    seg_start = (first == 0) | (seg[np.maximum(first - 1, 0)] != seg[first])
    seg_end = (last == len(seg) - 1) | (seg[np.minimum(last + 1, len(seg) - 1)] != seg[last])
    s0 = np.where(seg_start, 0.0, k[first] / m[seg[first]])  # halfway = the part boundary
    s1 = np.where(seg_end, 1.0, (k[last] + 1.0) / m[seg[last]])
    # Points of each run: its start, its samples, its end.
    counts = last - first + 3
    total = int(counts.sum())
    run = np.repeat(np.arange(len(first)), counts)
    j = np.arange(total) - np.repeat(np.cumsum(counts) - counts, counts)  # 0 .. count - 1
    smp = np.clip(first[run] + j - 1, first[run], last[run])
    s_pt = np.where(j == 0, s0[run], np.where(j == counts[run] - 1, s1[run], s[smp]))
    X3 = _world(camera, A, B, za, zb, seg[smp], s_pt)
    P2, _ = camera.project(X3)
    offs = np.concatenate([[0], np.cumsum(counts)])
    kinds = fe.kind[idx][seg[first]].astype(np.int64) + N_KINDS * np.minimum(lev[first], MAX_OCCLUSION)
    return Strokes.build(P2, X3, np.full(total, -1), offs, kinds.astype(np.int8), camera=camera)


@dataclass
class HiddenAccuracy:
    """A hidden-line drawing against the exact reference: precision / recall of the visible
    (level 0) and of the hidden (level >= 1) lines separately, and `level_right`: the share of
    the drawn length whose level is the exact level at its surface point."""

    visible: Accuracy
    hidden: Accuracy
    level_right: float
    drawn_length: float

    def to_json(self) -> dict:
        return {"visible": self.visible.to_json(), "hidden": self.hidden.to_json(), "level_right": self.level_right,
                "drawn_length_px": self.drawn_length}


def hidden_accuracy(scene: Scene, drawn: list[Strokes], reference: list[Strokes], tols=DEFAULT_TOLS,
                    step_px: float = 0.1, occluder: Occluder | None = None) -> HiddenAccuracy:
    """Measure hidden-line frames (mesh feature edges) against `reference_drawing` frames (same
    cameras, same order): precision / recall per class, and each drawn point's level (every 0.5
    px along the strokes) against `exact_levels` at its surface point, on its mesh edge."""
    occluder = Occluder(scene) if occluder is None else occluder
    vis, hid = [], []
    right = total = 0.0
    for d, r in zip(drawn, reference):
        vis.append(frame_accuracy(d.select(d.occlusion == 0), r.select(r.occlusion == 0), tols, step_px))
        hid.append(frame_accuracy(d.select(d.occlusion >= 1), r.select(r.occlusion >= 1), tols, step_px))
        smp = resample_strokes(d, 0.5)
        if len(smp) == 0:
            continue
        own, on_edge = _edge_faces_at(scene, d, smp)
        lev = exact_levels(scene, d.camera, smp.X, own, occluder)
        d_lev = d.occlusion[smp.stroke]
        right += float(smp.w[on_edge & (lev == np.minimum(d_lev, MAX_OCCLUSION))].sum())
        total += float(smp.w[on_edge].sum())
    return HiddenAccuracy(aggregate(vis), aggregate(hid), right / total if total else 1.0,
                          sum(f.drawn_length for f in vis + hid))


def _edge_faces_at(scene: Scene, strokes: Strokes, smp) -> tuple[np.ndarray, np.ndarray]:
    """The faces (M, 2) of the mesh edge each stroke sample's surface point lies on (the edge of
    the faces under the two stroke points around it nearest to it), and whether it does lie on
    one (within 1e-9 of the scene radius)."""
    i, j, _ = locate(strokes, smp.stroke, smp.s)
    faces = np.stack([strokes.face[i], strokes.face[j]], axis=1)
    fe = scene.face_edges[np.maximum(faces, 0)].reshape(len(j), 6)
    E = scene.edges[fe]
    a, b = scene.vertices[E[..., 0]], scene.vertices[E[..., 1]]
    ab = b - a
    X = smp.X[:, None, :]
    t = np.clip(np.einsum("mki,mki->mk", X - a, ab) / np.maximum(np.einsum("mki,mki->mk", ab, ab), 1e-300), 0, 1)
    dist = np.linalg.norm(a + t[..., None] * ab - X, axis=2)
    dist[np.repeat(faces < 0, 3, axis=1)] = np.inf
    k = dist.argmin(axis=1)
    e = fe[np.arange(len(j)), k]
    return scene.edge_faces[e][:, :2], dist[np.arange(len(j)), k] <= 1e-9 * scene.radius
