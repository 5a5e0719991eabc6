"""The lines stage: a frame's feature edges (silhouettes, borders, creases, material boundaries,
smooth and suggestive contours, intersections), their visible runs split where visibility
changes, chained into strokes (`LineRenderer.render`)."""

from strokekit.lines.renderer import LineRenderer

__all__ = ["LineRenderer"]
