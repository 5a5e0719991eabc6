"""Accuracy of a line drawing (BRIEF 2): precision and recall of visible line length.

precision = share of the drawn length that lies within `tol` px of the reference lines;
recall    = share of the reference length that lies within `tol` px of a drawn line.
The reference is the tool's own slowest setting (the `exact` preset). Both drawings are cut into
pieces of at most `step_px` (default 0.1 px); each piece counts with its length at its midpoint,
and its distance to the other drawing is measured with a k-d tree over that drawing's points
resampled at the same step (strokekit.strokeops.resample), so distances are exact to step/2 px.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from .model import Strokes
from .strokeops import resample

#: Default distance tolerances (px) reported by `strokekit bench`.
DEFAULT_TOLS: tuple[float, ...] = (0.5, 1.0, 2.0)


def length_samples(strokes: Strokes, step_px: float = 0.1) -> tuple[np.ndarray, np.ndarray]:
    """Midpoints (M, 2) px of pieces of at most `step_px` px along every stroke, and each piece's
    length (M,) px. The weights sum to the total drawn length."""
    if len(strokes) == 0 or len(strokes.points) == 0:
        return np.zeros((0, 2)), np.zeros(0)
    seg = strokes.segment_lengths  # length of the segment ending at each point
    seg_idx = np.flatnonzero(seg > 0)
    if len(seg_idx) == 0:  # only zero-length strokes: nothing drawn
        return np.zeros((0, 2)), np.zeros(0)
    n = np.ceil(seg[seg_idx] / step_px).astype(np.int64)
    rep = np.repeat(seg_idx, n)
    k = np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)
    t = ((k + 0.5) / np.repeat(n, n))[:, None]
    mid = strokes.points[rep - 1] * (1 - t) + strokes.points[rep] * t
    return mid, np.repeat(seg[seg_idx] / n, n)


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


def _ratio(near: float, total: float, other_total: float) -> float:
    # Nothing to measure: perfect when the other side is empty too, else nothing matched.
    if total <= 0:
        return 1.0 if other_total <= 0 else 0.0
    return float(min(1.0, near / total))


def _near_length(query: Strokes, against: Strokes, tols: tuple[float, ...], step_px: float) -> tuple[float, np.ndarray]:
    mid, w = length_samples(query, step_px)
    total = float(w.sum())
    if len(mid) == 0:
        return total, np.zeros(len(tols))
    pts, _ = resample(against, step_px)
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
