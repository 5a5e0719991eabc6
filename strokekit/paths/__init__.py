"""The brush path stage: strokes that persist, drawn over the frame's exact lines (Benard et al.,
"Active Strokes", NPAR 2012; Kalnins et al. 2003). Each path covers one or more nearby line
pieces of a compatible kind, is carried from frame to frame (its samples advected with the
surface, then relaxed onto the new lines), grows, shrinks, splits and keeps a persistent id, u and
self-similar level (`PathTracker.step(lines) -> BrushPaths`)."""

from strokekit.lazy import exports

#: Public names and their modules, each imported when first used.
_EXPORTS = {
    "PathOptions": "strokekit.paths.options",
    "PathTracker": "strokekit.paths.stage",
    "brush_frames": "strokekit.paths.stage",
    "brush_step": "strokekit.paths.stage",
}
__all__ = list(_EXPORTS)
__getattr__ = exports(__name__, _EXPORTS)
