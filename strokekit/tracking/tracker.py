"""Strokes that persist along the camera path: ids, a parametrization that does not slide, and
self-similar texture levels. The tracking pass is the only stage that walks the frames in order;
everything before it (features, visibility, chaining) is per frame and independent.

`Tracker(options).step(strokes) -> strokes` takes one frame's strokes (as LineRenderer gives them)
and returns them with persistent `ids`, a coherent `u` (texture periods of the strokes' `period_px`,
set by LineOptions.period_px) and the
self-similar `level` / `level_weight`. Three methods:

- "kalnins" (default; Kalnins et al. 2003, "Coherent Stylized Silhouettes"): the previous frame's
  strokes are sampled every `vote_spacing_px`; each sample carries its surface point X, its u and
  its stroke id. X is projected with the new camera and votes on the nearest new sample within
  `search_radius_px` whose tangent agrees (the same correspondence the metrics of BRIEF 3 use);
  with `reverse_votes` every new sample also looks back for the nearest old sample. First,
  chains of one kind whose ends meet within `join_tol_px` are joined into one path
  (`chain_touching`; where two strands overlap at their ends, the joint point that would make
  the path turn back is dropped): where the chaining stops changes from frame to frame. Each path is then
  cut into segments where the id its votes carry changes (Kalnins' brush path segments; runs
  shorter than `min_segment_px` are absorbed), so ids, not this frame's chain ends, decide where
  strokes begin and end. A cut between two ids goes where the previous frame's stroke end
  projects (`snap_boundaries`: the boundary between two ids does not wander with the sample
  spacing from frame to frame). Closed loops are turned to start at the old loop's seam, and
  where an open stroke runs across an old loop's seam the votes are unwrapped by the loop's u
  span (no fold there). Each segment is oriented so that u increases along it: the way its
  carried u increases, or, where the votes do not tell, the way the old tangents ran (an edge
  turning through edge-on turns its image around while u keeps its order). With
  `chain_touching` off, segments with the same id whose chains end within `join_tol_px` are
  healed into one stroke afterwards, a short chain that no vote landed on carrying the id of
  the chain it continues. Per stroke,
  votes of other ids are shifted by whole periods (the texture is periodic) to meet the largest
  group, which heals strokes that merged. u is then fitted by least squares as a piecewise-linear
  function of arc length (knots every `knot_spacing_px`, inserted as points so that downstream
  linear interpolation of u is exact): close to the votes (no sliding), slope close to 1/P (no
  stretch, `stretch_weight`), even stretch between knots (`bend_weight`); votes farther than
  `outlier_px` from the fit are dropped and the fit redone. Parts without votes (growth) continue
  the fit; strokes without any vote start at u = s / P.
- "seed" (seed 000, section 2.2.2, as a baseline): strokes are re-cut so that they start near a
  previous start (strategy 1) in the preferred direction (strategy 2, weight = d + angle penalty),
  grow at most `max_growth_px` per frame (strategy 3), the rest of the lines is filled by the
  longest pieces left from the existing ends (strategy 4), and only strokes of at least
  `min_carry_px` are carried as bases (strategy 5). u = arc length / P from each start.
- "none" (`--no-coherence`): ids renumbered 0..S-1 every frame, u = arc length / P.

Ids: a previous id goes to the new stroke that holds most of its matched length, and a new stroke
takes the id holding most of its matched length (greedy on matched length, ties broken by stroke
index then id), so the largest persisting part of a stroke that splits or merges keeps the id;
every other stroke gets a fresh id from a counter. Everything is deterministic for a given input.

Self-similar levels (Benard et al. 2010): a stroke whose u is stretched by lambda = 1 / (P du/ds)
is drawn with the 1D texture octaves k = `level` and k + 1, octave k sampling the texture at
u * 2^-k; `level_weight` is the weight of octave `level` and 1 - level_weight that of octave
level + 1. With c = log2(P du/ds) (the fitted slope), level = floor(c) and
level_weight = 1 - frac(c): when a stroke shrinks 8 times under a dolly its marks do not; the
unstretched case is level 0, weight 1. Brush head and tail keep their size in the ribbon writer,
which only needs u and the stroke length.

Split criteria (angle, maximum length) and the removal of doubled contour pieces
(`drop_doubled`, LineOptions.doubled_px) belong to the per-frame line pass. With the default
`join_tol_px` the tracked frame draws the input lines with bridges of at most `join_tol_px` where
strokes are healed (0: exactly the input lines).
"""

from __future__ import annotations

import numpy as np

from strokekit.model import Strokes
from strokekit.numba_cache import keyboard_interrupts
from strokekit.tracking.kalnins import Kalnins
from strokekit.tracking.options import TrackingOptions
from strokekit.tracking.seed import Seed


def fresh(strokes: Strokes, period_px: float, first_id: int) -> tuple[Strokes, int]:
    """Strokes with no history: ids first_id, first_id + 1, ..., u = arc length / P, level 0;
    and the next unused id."""
    S = len(strokes)
    ids = first_id + np.arange(S, dtype=np.int64)
    return strokes.replace(ids=ids, u=strokes.arc_length / period_px, level=np.zeros(S),
                           level_weight=np.ones(S)), first_id + S


class Renumber:
    """`--coherence none`: ids 0..S-1 every frame, u = arc length / P."""

    name = "none"

    def track(self, prev: Strokes | None, cur: Strokes, o: TrackingOptions, next_id: int) -> tuple[Strokes, int]:
        return fresh(cur, cur.period_px, 0)[0], next_id


#: The tracking method of each TrackingOptions.method: an object with
#: track(prev, cur, options, next_id) -> (tracked cur, next unused id).
STRATEGIES = {"kalnins": Kalnins(), "seed": Seed(), "none": Renumber()}


class Tracker:
    """Carries the drawing from frame to frame. Call `step` on the frames in order."""

    def __init__(self, options: TrackingOptions | None = None):
        self.options = options or TrackingOptions()
        self.method = STRATEGIES[self.options.method]
        self.prev: Strokes | None = None
        self.next_id = 0

    def reset(self) -> None:
        self.prev, self.next_id = None, 0

    def step(self, strokes: Strokes) -> Strokes:
        """The tracked version of one frame's strokes (same lines, see the module doc; ids, u,
        level set; strokes may be re-cut, healed and reversed). The camera of `strokes` is required for
        carrying samples from the previous frame."""
        o = self.options
        no_history = self.prev is None or len(self.prev) == 0 or strokes.camera is None \
            or self.prev.camera is None or len(strokes) == 0
        if no_history and o.method != "none":
            out, self.next_id = fresh(strokes, strokes.period_px, self.next_id)
        else:
            with keyboard_interrupts():  # (a Ctrl-C in a compiled loop stays a KeyboardInterrupt)
                out, self.next_id = self.method.track(self.prev, strokes, o, self.next_id)
        if strokes.pose is not None:  # (a moving scene: where the frame's objects were, for the next frame)
            out = out.replace(pose=strokes.pose)
        self.prev = out
        return out


def track_frames(frames: list[Strokes], options: TrackingOptions | None = None) -> list[Strokes]:
    """Track a list of frames in order (convenience for tests and benchmarks)."""
    tr = Tracker(options)
    return [tr.step(f) for f in frames]
