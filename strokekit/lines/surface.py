"""The lift of occlusion-ray origins off the surface a frame's lines start on (`surface_lift`), so
a ray from a point on a face does not hit that face or its neighbours."""

from __future__ import annotations

import numpy as np

from strokekit.lines.facing import FrameView
from strokekit.model import KIND_INDEX, FeatureEdges, row_norm
from strokekit.scene.load import Scene


def surface_lift(view: FrameView, fe: FeatureEdges, fraction: float,
                 edge_index: np.ndarray | None = None, edge_faces: np.ndarray | None = None) -> np.ndarray:
    """(N, 3) ray-origin offsets for mesh-edge features: `fraction` x scene radius along the mean
    normal of the edge's faces that face the eye (all its faces, turned around, when none does).

    Why: a ray from a silhouette point toward the eye is tangent to the surface, so faces of the
    vertex's 1-ring lie within float32 rounding of it and Embree reports false hits. Lifting the
    origin off the surface by far more than the rounding (1e-5 r vs ~1e-7 r) removes them; true
    occluders closer than that are far below a pixel. Only the eye-facing side is used: the back
    face of a silhouette often rests on another object (a box on the ground), and a lift along
    it would start the ray inside that object.

    `edge_index` (N,), if given, is the scene edge of each feature (all mesh edges, va < vb as
    in scene.edges): it saves looking the edges up by their vertices; `edge_faces` (N, 2), with
    it, their scene.edge_faces rows."""
    scene = view.scene
    lift = np.zeros((len(fe), 3))
    V = len(scene.vertices)
    if edge_index is not None and edge_faces is not None:  # every feature is a mesh edge
        mesh = all_mesh = True
        pos = edge_index
        found = True
    else:
        mesh = (fe.va >= 0) & (fe.va < V) & (fe.vb >= 0) & (fe.vb < V)
        if not mesh.any():
            return lift
        all_mesh = edge_index is not None and bool(mesh.all())
    if edge_faces is not None and all_mesh:
        ef = edge_faces
    elif edge_index is not None:
        pos = np.asarray(edge_index)[mesh]
        found = np.ones(len(pos), bool)
    else:
        lo = np.minimum(fe.va[mesh], fe.vb[mesh])
        hi = np.maximum(fe.va[mesh], fe.vb[mesh])
        keys = scene.edge_keys
        q = lo * (V + 1) + hi
        pos = np.clip(np.searchsorted(keys, q), 0, len(keys) - 1)
        found = keys[pos] == q
    if not (edge_faces is not None and all_mesh):
        ef = np.take(scene.edge_faces, pos, axis=0)
    ff = view.front_facing
    if edge_faces is not None and all_mesh:
        rows = _lift_rows(scene, fe, ef, ff, fraction)
        if rows is not None:
            return rows
    n = scene.face_normals
    f1, any_front, w0, w1 = _lift_weights(ef, ff)
    m = w0[:, None] * np.take(n, ef[:, 0], axis=0) + w1[:, None] * np.take(n, f1, axis=0)
    m = np.where(any_front[:, None], m, -m)
    ln = row_norm(m)
    ok = found & (ln > 1e-6)
    # The size that matters is local: a small object beside a huge floor must not be lifted by a
    # fraction of the floor's size (its own silhouette would float past nearby occluders).
    a, b = (fe.a, fe.b) if all_mesh else (fe.a[mesh], fe.b[mesh])
    local = np.maximum(row_norm(0.5 * (a + b) - scene.center), row_norm(b - a))
    size = fraction * np.minimum(scene.radius, local)
    if all_mesh and ok.all():  # no masking needed
        lift = m / ln[:, None] * size[:, None]
    else:
        out = np.zeros((len(pos), 3))
        out[ok] = m[ok] / ln[ok, None] * size[ok, None]
        lift[mesh] = out
    # A non-manifold edge has no "first two faces" independent of face order: no lift, so that
    # renumbering faces cannot change the drawing.
    lift[fe.kind == KIND_INDEX["nonmanifold"]] = 0.0
    return lift


def _lift_weights(ef: np.ndarray, ff: np.ndarray):
    """For edges with faces ef (N, 2) (-1: none) and the faces' front-facing flags ff: the second
    face (0 where none), whether any face faces the eye, and the weights (N,) of the two faces'
    normals in the lift direction: the eye-facing faces', or where none faces the eye, all of
    them (the caller then reverses the sum)."""
    has1 = ef[:, 1] >= 0
    f1 = np.maximum(ef[:, 1], 0)
    front0, front1 = ff[ef[:, 0]], has1 & ff[f1]
    any_front = front0 | front1
    w0 = np.where(any_front, front0, True).astype(float)
    w1 = np.where(any_front, front1, has1).astype(float)
    return f1, any_front, w0, w1


def _lift_rows(scene: Scene, fe: FeatureEdges, ef: np.ndarray, ff: np.ndarray, fraction: float) -> np.ndarray | None:
    """surface_lift for mesh edges with their faces `ef`, computed on (3, N) rows: the same float64
    operations element by element (the same bits), without broadcasting (N, 3) arrays against
    (N, 1) or (3,) ones, whose 3-long inner loops cost more than the arithmetic. None where an
    edge's faces have no usable normal (the caller's general path handles it)."""
    nT = scene.face_normal_rows
    f1, any_front, w0, w1 = _lift_weights(ef, ff)
    m = w0 * nT.take(ef[:, 0], axis=1) + w1 * nT.take(f1, axis=1)
    m = np.where(any_front, m, -m)
    ln = np.sqrt((m[0] * m[0] + m[1] * m[1]) + m[2] * m[2])  # row_norm's order
    if not (ln > 1e-6).all():
        return None
    a, b = fe.a, fe.b
    mid = 0.5 * (a + b)
    c = scene.center
    x0, x1, x2 = mid[:, 0] - c[0], mid[:, 1] - c[1], mid[:, 2] - c[2]
    ab = b - a
    y0, y1, y2 = ab[:, 0], ab[:, 1], ab[:, 2]
    local = np.maximum(np.sqrt((x0 * x0 + x1 * x1) + x2 * x2), np.sqrt((y0 * y0 + y1 * y1) + y2 * y2))
    size = fraction * np.minimum(scene.radius, local)
    lift = np.ascontiguousarray((m / ln * size).T)
    lift[fe.kind == KIND_INDEX["nonmanifold"]] = 0.0
    return lift
