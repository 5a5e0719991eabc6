"""The lines stage: a frame's feature edges (silhouettes, borders, creases, material boundaries,
smooth and suggestive contours, intersections), their visible runs split where visibility
changes, chained into strokes (`LineRenderer.render`). What one frame sees of the scene (which
faces face the eye, the contour edges) is its `FrameView`."""

from strokekit.lines.facing import FrameView
from strokekit.lines.renderer import LineRenderer

__all__ = ["FrameView", "LineRenderer"]
