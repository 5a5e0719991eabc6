"""The lines stage: a frame's feature edges (silhouettes, borders, creases, material boundaries,
smooth and suggestive contours, intersections), their visible runs split where visibility
changes, chained into strokes (`LineRenderer.render`). What one frame sees of the scene (which
faces face the eye, the contour edges) is its `FrameView`."""

from strokekit.lazy import exports

#: Public names and their modules, each imported when first used.
_EXPORTS = {
    "FrameView": "strokekit.lines.facing",
    "LineRenderer": "strokekit.lines.renderer",
}
__all__ = list(_EXPORTS)
__getattr__ = exports(__name__, _EXPORTS)
