"""What a sequence of frames is asked to draw (`RenderRequest`), and what that comes to for a
given number of frames (`SequencePlan`): presets, the brush-or-lines default and the tracking
settled here, once, for the library and the command line alike."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

from strokekit.errors import UsageError
from strokekit.options import LineOptions, option
from strokekit.paths.options import PathOptions
from strokekit.raster.options import RasterOptions
from strokekit.style.linesets import Style
from strokekit.tracking.options import METHODS, TrackingOptions

STROKES = ("brush", "lines")


@dataclass(frozen=True)
class RenderRequest:
    """What every frame of a sequence draws.

    lines: the line pass. strokes: what is drawn, "brush" (brush paths, the lines kept beside
    them) or "lines" (the exact lines); None: brush paths for a sequence, unless `coherence` is
    named (a method tracks lines), the lines for one frame. coherence: how the strokes carry
    over from frame to frame: "kalnins" or "seed" track the lines, "none" carries nothing (brush
    paths are then made afresh every frame); None: kalnins, or carried brush paths. tracking,
    paths: the line tracker's and the brush paths' own settings (their method and history
    follow `coherence`). raster: the raster pass (bands, masks, ids, depth); None: none.
    style: how the strokes are drawn (line sets, widths per point: strokekit.style), by every
    writer."""

    lines: LineOptions = field(default_factory=LineOptions)
    strokes: str | None = option(
        None, "--strokes", "What the SVG, the JSON's strokes and the ribbons draw: brush paths (smooth strokes that "
        "persist from frame to frame, each covering nearby line pieces; the JSON keeps the exact lines beside them) or "
        "the exact lines [brush for a sequence with coherence on, unless --coherence is given; lines for one frame or "
        "--no-coherence].", choices=STROKES)
    coherence: str | None = option(
        None, "--coherence", "Frame-to-frame tracking of the lines (--strokes lines): kalnins (samples carry ids and u "
        "to the next frame), seed (simple baseline: limited growth, short strokes not carried), or none.",
        choices=METHODS, show_default=True, shown="kalnins")
    tracking: TrackingOptions = field(default_factory=TrackingOptions)
    paths: PathOptions = field(default_factory=PathOptions)
    raster: RasterOptions | None = None
    animation: str | None = option(
        None, "--animation", "The animation of a glTF scene that moves its objects, by name or number [the first]; "
        "frame N shows it at (N - 1) / fps + --time-offset seconds.")
    time_offset: float = option(0.0, "--time-offset", "Seconds added to every frame's time in the scene's animation "
                                "[0].", show_default=False)
    style: Style = field(default_factory=Style)

    def __post_init__(self):
        if self.strokes not in (None, *STROKES):
            raise UsageError(f"strokes must be one of {', '.join(STROKES)}, got {self.strokes!r}", option="strokes")
        if self.coherence not in (None, *METHODS):
            raise UsageError(f"unknown coherence method {self.coherence!r} (known: {', '.join(METHODS)})")
        if not (isinstance(self.time_offset, (int, float)) and math.isfinite(self.time_offset)):
            raise UsageError(f"time offset must be a finite number of seconds, got {self.time_offset!r}",
                             option="time_offset")
        if self.strokes == "brush" and self.coherence not in (None, "none"):
            raise UsageError(f"coherence {self.coherence!r} tracks lines: it goes with strokes 'lines' (brush paths "
                             "carry their own ids; coherence 'none' makes them afresh every frame)",
                             option="coherence")
        self.style.check_draws(self.lines.kinds, self.lines.occlusion)

    @classmethod
    def preset(cls, quality: str = "default", *, lines: dict | None = None, raster: dict | None = None,
               **fields) -> RenderRequest:
        """The request of a quality preset (options.QUALITY_PRESETS: the line pass's accuracy and
        the raster pass's sampling), `lines` and `raster` giving the fields that differ from it
        (raster None: no raster pass; {}: the preset's); `fields`: the request's other fields."""
        return cls(lines=LineOptions.preset(quality, **(lines or {})),
                   raster=None if raster is None else RasterOptions.preset(quality, **raster), **fields)

    def plan(self, n_frames: int, fps: float = 24.0) -> SequencePlan:
        """What `n_frames` frames of this request draw and carry from frame to frame; `fps`: the
        camera path's, which times the scene's animation."""
        method = self.coherence or self.tracking.method
        strokes = self.strokes or ("brush" if n_frames >= 2 and self.coherence is None else "lines")
        clock = SceneClock(self.animation, float(self.time_offset), float(fps))
        if strokes == "brush":
            paths = replace(self.paths, history=method != "none")
            return SequencePlan(self.lines, None, paths, self.raster, carried=n_frames >= 2 and paths.history,
                                clock=clock, style=self.style)
        tracking = replace(self.tracking, method=method) if n_frames >= 2 and method != "none" else None
        return SequencePlan(self.lines, tracking, None, self.raster, carried=tracking is not None, clock=clock,
                            style=self.style)


@dataclass(frozen=True)
class SceneClock:
    """When each frame is in the scene's animation: frame N at (N - 1) / fps + offset seconds of
    the animation `animation` (a name or number; None: the first)."""

    animation: str | None = None
    offset: float = 0.0
    fps: float = 24.0

    def time(self, frame: int) -> float:
        return (frame - 1) / self.fps + self.offset


@dataclass(frozen=True)
class SequencePlan:
    """A request settled for a number of frames. tracking: the lines are tracked with it (None:
    not); paths: brush paths are drawn, made with it (None: the lines are drawn); carried:
    a frame's strokes depend on the frames before it (which then render in order); clock: each
    frame's time in the scene's animation; style: how the strokes are drawn."""

    lines: LineOptions
    tracking: TrackingOptions | None
    paths: PathOptions | None
    raster: RasterOptions | None
    carried: bool
    clock: SceneClock = field(default_factory=lambda: SceneClock())
    style: Style = field(default_factory=Style)

    def json_head(self) -> dict:
        """The frame JSON's keys before its strokes: how the strokes were made. Only brush frames
        say "strokes_are"; only hidden-line frames "occlusion" (the strokes then carry levels)."""
        if self.paths is not None:
            head = {"contours": self.lines.contours, "tracking": "brush" if self.carried else "none",
                    "strokes_are": "brush"}
        else:
            head = {"contours": self.lines.contours,
                    "tracking": self.tracking.method if self.carried else "none"}
        if self.lines.occlusion is not None:
            head["occlusion"] = list(self.lines.occlusion)
        return head
