"""The brush path stage: strokes that persist, drawn over the frame's exact lines (Benard et al.,
"Active Strokes", NPAR 2012; Kalnins et al. 2003). Each path covers one or more nearby line
pieces of a compatible kind, is carried from frame to frame (its samples advected with the
surface, then relaxed onto the new lines), grows, shrinks, splits and keeps a persistent id, u and
self-similar level (`PathTracker.step(lines) -> BrushPaths`)."""

from strokekit.paths.options import PathOptions
from strokekit.paths.stage import PathTracker, brush_frames, brush_step

__all__ = ["PathOptions", "PathTracker", "brush_frames", "brush_step"]
