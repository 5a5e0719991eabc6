"""Options of the brush path stage (`PathOptions`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from strokekit.errors import UsageError
from strokekit.options import option
from strokekit.tracking.options import TrackingOptions


def path_tracking() -> TrackingOptions:
    """TrackingOptions of the brush paths: closer knots and a tenth of the stretch weight. Paths
    are several times longer than tracked lines, so u must bend over longer spans between its
    votes (less sliding for a little more texture stretch)."""
    return TrackingOptions(knot_spacing_px=16.0, stretch_weight=3e-4)


@dataclass(frozen=True)
class PathOptions:
    """Options of the brush paths. Pixel values are image pixels.

    history: carry the paths from frame to frame (False: every frame's paths are made afresh,
    ids 0..S-1, u = arc length / P: `--coherence none`).
    sample_px: spacing of the line samples that carry the labels (which path each piece of line
    belongs to); cuts between paths fall within half of it. reverse_px: spacing of the line
    samples that look back for the nearest previous path sample (votes the other way).
    cover_px: a piece of contour line running beside a path of higher rank within this many px
    (tangents agreeing) is covered by that path, not drawn by a path of its own (the shingles of a
    mesh contour share one path). With the default 2 px every line stays within 2 px of a path.
    join_px: pieces of one path whose ends are within this many px are drawn as one stroke (the
    bridge between them is drawn: beyond 2 px, only where all of it lies within 1 px of a line);
    a piece no path claims joins a path, or another such piece, within new_join_px.
    join_angle_deg: the most a path may turn where two pieces join, and at a vertex of its line:
    a line turning more is cut there (a brush stroke ends at a corner). Below 90: the corners of
    a CAD model turn by about 90 degrees on screen, one frame as one line round the corner and
    the next as two lines meeting there, and a path that ran round one split off a fresh id.
    min_run_px: along a line, a run of samples claimed by one path shorter than this is given
    to its neighbours (labels do not flicker between two paths on a few samples).
    merge_px: a path shorter than this (in this frame and the last) gives way: its pieces join
    the path they touch like pieces no path claims (it merges; its id ends). Each merge costs M1
    its length once; without merges every split leaves an id behind for good and the paths
    crumble over a long sequence (0: never merge). Short strands are held back (hold_px), so
    a small merge length does.
    orphan_px: a path of pieces whose label's id goes to another path (the longest of that
    label: an orphan, a piece the votes of a path that runs elsewhere reached), at most this
    long, is linked again as pieces no path claims: it joins the path it touches instead of
    taking a fresh id of its own (a line that grows at its end, past a junction with another
    path, grows the path it continues; 0: never).
    other_id_weight: in the fit of u along a path that holds votes of its own id, the weight of
    the votes of other ids (the pieces it took over: orphans, merges, heals): its own texture
    gives way to theirs only a little, so it does not slide to meet them (1: as its own).
    hold_px: a new path shorter than this lying beside the drawn paths (within 3 px all along)
    is held back one frame: drawn from the next frame on if it is still there, so that a piece
    that shows for one frame costs no id (0: never hold).
    heal_px: a path shorter than this that meets another end to end on one line heals into it
    (its id gives way) where the cut is new this frame or lasts two frames (paths.heal; 0: never).
    bridge_px: a piece cut off a carried path this frame (a fresh path whose votes came mostly
    from that path's id) whose end meets the path's within this many px, on one line (the bridge
    running on along both ends and lying on the drawn lines), stays part of it: a split of one
    line that the labels or the cover make costs no id (paths.heal.bridge_splits; 0: never).
    tracking: the correspondence of carried samples (search radius, tangent agreement, vote
    spacing) and the fit of u (stretch, knots, outliers), as the Kalnins tracker has them; the
    paths' own default (`path_tracking`) lets u follow the votes more closely."""

    history: bool = True
    sample_px: float = 1.0
    reverse_px: float = 1.0
    cover_px: float = 2.0
    join_px: float = 6.0
    new_join_px: float = 2.0
    join_angle_deg: float = 70.0
    min_run_px: float = 1.5
    merge_px: float = option(
        5.0, "--path-merge", "With brush paths: a path shorter than N px (two frames running) merges into the path "
        "it touches [5; 0: never, the highest id persistence, but paths crumble over long sequences].",
        needs="brush")
    hold_px: float = 8.0
    orphan_px: float = 25.0
    other_id_weight: float = 0.2
    heal_px: float = option(
        6.0, "--path-heal", "With brush paths: a path shorter than N px that meets another end to end on one line "
        "heals into it where the cut is new or lasts two frames [6; 0: never; 20: about half the path ends, a little "
        "less id persistence: see docs/coherence.md].", needs="brush")
    bridge_px: float = option(
        20.0, "--path-bridge", "With brush paths: a piece cut off a carried path by a gap of up to N px along the "
        "drawn lines stays part of it (no fresh id) [20; 0: never: see docs/coherence.md].", needs="brush")
    tracking: TrackingOptions = field(default_factory=path_tracking)

    def __post_init__(self):
        for name in ("sample_px", "reverse_px"):
            v = getattr(self, name)
            if not (v > 0 and math.isfinite(v)):
                raise UsageError(f"{name} must be a finite number > 0, got {v}", option=name)
        for name in ("cover_px", "join_px", "new_join_px", "min_run_px", "merge_px", "hold_px", "heal_px", "bridge_px",
                     "orphan_px"):
            v = getattr(self, name)
            if not (v >= 0 and math.isfinite(v)):
                raise UsageError(f"{name} must be a finite number >= 0 px, got {v}", option=name)
        if not 0 <= self.other_id_weight <= 1:
            raise UsageError(f"other_id_weight must be in [0, 1], got {self.other_id_weight}", option="other_id_weight")
        for name in ("join_angle_deg",):
            if not 0 < getattr(self, name) <= 180:
                raise UsageError(f"{name} must be in (0, 180] degrees, got {getattr(self, name)}", option=name)
