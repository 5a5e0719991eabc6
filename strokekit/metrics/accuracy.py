"""Accuracy of a line drawing (BRIEF 2): precision and recall of visible line length.

precision = share of the drawn length that lies within `tol` px of the reference lines;
recall    = share of the reference length that lies within `tol` px of a drawn line.
The reference is the tool's own slowest setting (the `exact` preset). Both drawings are cut into
pieces of at most `step_px` (default 0.1 px); each piece counts with its length at its midpoint,
and its distance to the other drawing is measured with a k-d tree over that drawing's points
resampled at the same step (both `sampling.segment_samples`), so distances are exact to step/2 px.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from strokekit.lines.contours import smooth_contour_edges
from strokekit.lines.facing import FrameView
from strokekit.lines.sightlines import visible
from strokekit.lines.surface import surface_lift
from strokekit.model import FeatureEdges, Strokes
from strokekit.sampling import segment_samples
from strokekit.scene.occluder import Occluder

#: Default distance tolerances (px) reported by `strokekit bench`.
DEFAULT_TOLS: tuple[float, ...] = (0.5, 1.0, 2.0)


@dataclass
class FrameAccuracy:
    """Length bookkeeping of one frame. For each tol: drawn length within tol of the reference
    (`drawn_near`), reference length within tol of the drawing (`ref_near`). Lengths in px."""

    tols: tuple[float, ...]
    drawn_length: float
    ref_length: float
    drawn_near: np.ndarray = field(repr=False)
    ref_near: np.ndarray = field(repr=False)

    @property
    def precision(self) -> dict[float, float]:
        return {t: _ratio(n, self.drawn_length, self.ref_length) for t, n in zip(self.tols, self.drawn_near)}

    @property
    def recall(self) -> dict[float, float]:
        return {t: _ratio(n, self.ref_length, self.drawn_length) for t, n in zip(self.tols, self.ref_near)}


#: Drawn length below which a frame has nothing to measure (px): a stroke of 1e-27 px is resampled
#: to no point on the other side, so it would count as missed.
NOTHING_PX = 1e-9


def _ratio(near: float, total: float, other_total: float) -> float:
    # Nothing to measure: perfect when the other side is empty too, else nothing matched.
    if total <= NOTHING_PX:
        return 1.0 if other_total <= NOTHING_PX else 0.0
    return float(min(1.0, near / total))


def _near_length(query: Strokes, against: Strokes, tols: tuple[float, ...], step_px: float) -> tuple[float, np.ndarray]:
    mid, _, w = segment_samples(query.points, query.offsets, step_px, middles=True)
    total = float(w.sum())
    if len(mid) == 0:
        return total, np.zeros(len(tols))
    pts, _, _ = segment_samples(against.points, against.offsets, step_px)
    if len(pts) == 0:
        return total, np.zeros(len(tols))
    tree = cKDTree(pts)
    # One query up to the largest tol (plus the sampling slack) answers every tol.
    dist, _ = tree.query(mid, distance_upper_bound=max(tols) + step_px)
    return total, np.array([w[dist <= t].sum() for t in tols])


def frame_accuracy(drawn: Strokes, reference: Strokes, tols=DEFAULT_TOLS, step_px: float = 0.1) -> FrameAccuracy:
    """Precision/recall bookkeeping of one frame's drawing against the reference drawing of the
    same camera. tols: distances in px; step_px: resampling step (<= 0.1 px for BRIEF 2)."""
    tols = tuple(float(t) for t in tols)
    d_len, d_near = _near_length(drawn, reference, tols, step_px)
    r_len, r_near = _near_length(reference, drawn, tols, step_px)
    return FrameAccuracy(tols, d_len, r_len, d_near, r_near)


@dataclass
class Accuracy:
    """Precision and recall aggregated over frames, length-weighted (long frames count more)."""

    tols: tuple[float, ...]
    precision: dict[float, float]
    recall: dict[float, float]
    drawn_length: float
    ref_length: float
    frames: int

    def to_json(self) -> dict:
        return {"tols_px": list(self.tols), "precision": {f"{t:g}": p for t, p in self.precision.items()},
                "recall": {f"{t:g}": r for t, r in self.recall.items()}, "drawn_length_px": self.drawn_length,
                "reference_length_px": self.ref_length, "frames": self.frames}


def aggregate(frames: list[FrameAccuracy]) -> Accuracy:
    """Sum the lengths of several frames (same tols) into one precision/recall per tol."""
    if not frames:
        raise ValueError("no frames to aggregate")
    tols = frames[0].tols
    d_len = sum(f.drawn_length for f in frames)
    r_len = sum(f.ref_length for f in frames)
    d_near = np.sum([f.drawn_near for f in frames], axis=0)
    r_near = np.sum([f.ref_near for f in frames], axis=0)
    return Accuracy(tols, {t: _ratio(n, d_len, r_len) for t, n in zip(tols, d_near)},
                    {t: _ratio(n, r_len, d_len) for t, n in zip(tols, r_near)}, d_len, r_len, len(frames))


def accuracy(drawn: list[Strokes], reference: list[Strokes], tols=DEFAULT_TOLS, step_px: float = 0.1) -> Accuracy:
    """Precision and recall of a sequence of frames against the reference frames (same order)."""
    if len(drawn) != len(reference):
        raise ValueError(f"{len(drawn)} drawn frames but {len(reference)} reference frames")
    return aggregate([frame_accuracy(d, r, tols, step_px) for d, r in zip(drawn, reference)])


# --- smooth contours: visibility and cusps (shared by tests and benchmarks) ---

def mesh_contour_samples(scene, camera, n: int = 16) -> tuple[np.ndarray, np.ndarray]:
    """Samples (M, 3) world of the mesh contour edges (BRIEF 2 silhouettes), n per edge, and their
    occlusion-ray lifts (M, 3) as the line pass tests them (lines.surface_lift)."""

    view = FrameView(scene, camera)
    E = scene.edges[view.silhouettes]
    a, b = scene.vertices[E[:, 0]], scene.vertices[E[:, 1]]
    fe = FeatureEdges(a=a, b=b, kind=np.zeros(len(E), np.int8), va=E[:, 0], vb=E[:, 1],
                      face=np.zeros(len(E), np.int64))
    lift = surface_lift(view, fe, 1e-5)
    t = (np.arange(n) + 0.5) / n
    Q = (a[:, None] * (1 - t)[None, :, None] + b[:, None] * t[None, :, None]).reshape(-1, 3)
    return Q, np.repeat(lift, n, axis=0)


def smooth_contour_wrongly_hidden(scene, cameras, tol_px: float = 1.0, samples_per_segment: int = 8,
                                  lift: bool = True, all_visible: bool = False) -> tuple[float, float]:
    """How much of the smooth contour the occlusion test hides wrongly, over `cameras`.

    Truth: a smooth contour sample is visible where a visible exact mesh contour (BRIEF 2) runs
    within `tol_px` on screen and two face sizes in space (`all_visible`: every sample is, e.g.
    a lone sphere). Returns (wrongly hidden length / truly visible length, length reported
    visible farther than 2 px from any visible mesh contour / length reported visible), both by
    screen length. `lift=False` tests the plain rays, to show what the lift buys."""

    occ = Occluder(scene)
    ns = samples_per_segment
    s = (np.arange(ns) + 0.5) / ns
    wrong = total = far = total_vis = 0.0
    for cam in cameras:
        fe = smooth_contour_edges(FrameView(scene, cam))
        P = (fe.a[:, None] * (1 - s)[None, :, None] + fe.b[:, None] * s[None, :, None]).reshape(-1, 3)
        seg = np.repeat(np.arange(len(fe)), ns)
        pp, _ = cam.project(P)
        w = np.repeat(np.linalg.norm(cam.project(fe.b)[0] - cam.project(fe.a)[0], axis=1) / ns, ns)
        vis = visible(occ, P, cam, 1e-5, fe.lift[seg] if lift else None)
        Q, q_lift = mesh_contour_samples(scene, cam)
        Qv = Q[visible(occ, Q, cam, 1e-5, q_lift)]
        tree = cKDTree(cam.project(Qv)[0])
        if all_visible:
            truth = np.ones(len(P), bool)
        else:
            dist, i = tree.query(pp, distance_upper_bound=tol_px)
            near = np.isfinite(dist)
            truth = np.zeros(len(P), bool)
            truth[near] = np.linalg.norm(Qv[i[near]] - P[near], axis=1) < 2 * scene.face_size[fe.face[seg[near]]]
        wrong += w[truth & ~vis].sum()
        total += w[truth].sum()
        d2, _ = tree.query(pp, distance_upper_bound=2.0)
        far += w[vis & ~np.isfinite(d2)].sum()
        total_vis += w[vis].sum()
    return wrong / max(total, 1e-300), far / max(total_vis, 1e-300)


def screen_reversals(fe, camera) -> int:
    """Number of junctions between linked feature segments (segment i's end key vb equals
    segment j's start key va) where the screen tangent turns back (negative dot product)."""
    d = camera.project(fe.b)[0] - camera.project(fe.a)[0]
    order = np.argsort(fe.vb)
    ok = np.flatnonzero(fe.va >= 0)
    if len(order) == 0 or len(ok) == 0:
        return 0
    pos = np.minimum(np.searchsorted(fe.vb[order], fe.va[ok]), len(order) - 1)
    hit = fe.vb[order][pos] == fe.va[ok]
    i, j = order[pos[hit]], ok[hit]  # segment i ends where segment j starts
    return int((np.einsum("ij,ij->i", d[i], d[j]) < 0).sum())
