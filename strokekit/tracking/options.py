"""Options of the tracking pass (`TrackingOptions`) and its methods."""

from __future__ import annotations

import math
from dataclasses import dataclass

from strokekit.errors import UsageError
from strokekit.options import option

METHODS = ("kalnins", "seed", "none")


@dataclass(frozen=True)
class TrackingOptions:
    """Options of the tracking pass. Pixel values are image pixels.

    method: "kalnins" | "seed" | "none". The texture period P of u is the strokes' own
    (Strokes.period_px, from LineOptions.period_px).
    search_radius_px, min_tangent_dot: correspondence of carried samples (the coherence
    metrics' matching).
    vote_spacing_px: spacing of the samples carried from frame to frame (kalnins).
    stretch_weight: weight of "slope close to 1/P" against "u close to the votes" (kalnins): a
    stroke of length L stretched by a factor (1 + d) costs stretch_weight L d^2, as much as votes
    all missed by sqrt(stretch_weight) d periods; both scale with L, so short and long strokes
    trade sliding for stretch alike.
    outlier_px: votes farther than this from the fit are dropped (kalnins).
    min_id_px: matched length needed for an id to persist.
    min_segment_px: a chain is cut between runs of votes carrying different ids (Kalnins' segments);
    runs shorter than this are absorbed by their neighbours (kalnins).
    dense_spacing_px: spacing of the new strokes' samples that votes land on (positions along
    the stroke are refined below it by projecting on the sample's tangent).
    reverse_votes: new samples also look back for the nearest old sample (both ways, as the
    coherence metrics match).
    join_tol_px, join_angle_deg: segments with the same carried id whose strokes end within
    join_tol_px of each other, turning by at most join_angle_deg, are healed into one stroke
    (0 disables; above 1e-3 the joint bridges the gap, which adds at most join_tol_px of line).
    snap_boundaries: cuts between two carried ids go where the previous stroke ends project.
    chain_touching: join chains whose ends meet (join_tol_px, join_angle_deg) before cutting by
    votes (see the module doc); healing after the cut is then not needed.
    knot_spacing_px: u is piecewise linear with knots this far apart (0: one line per stroke);
    bend_weight: weight of even stretch between knots (kalnins).
    max_growth_px, min_carry_px, seed_search_px, seed_angle_penalty_px (the seed method): the
    most a stroke grows a frame, the shortest stroke carried over, the neighbourhood a stroke's
    match is looked for in and the direction penalty of a match (px per radian)."""

    method: str = "kalnins"
    search_radius_px: float = 6.0
    min_tangent_dot: float = 0.65
    vote_spacing_px: float = 4.0
    stretch_weight: float = 3e-3
    outlier_px: float = 3.0
    min_id_px: float = 2.0
    max_growth_px: float = option(20.0, "--max-growth", "With --coherence seed: a stroke grows at most N px per frame.",
                                  show_default=True, needs="seed")
    min_carry_px: float = option(
        10.0, "--min-carry", "With --coherence seed: strokes shorter than N px are not carried to the next frame.",
        show_default=True, needs="seed")
    seed_search_px: float = 12.0
    seed_angle_penalty_px: float = 10.0
    min_segment_px: float = 7.0
    knot_spacing_px: float = 24.0
    join_tol_px: float = 2.0
    join_angle_deg: float = 90.0
    dense_spacing_px: float = 5.0
    reverse_votes: bool = True
    bend_weight: float = 0.01
    snap_boundaries: bool = True
    chain_touching: bool = True

    def __post_init__(self):
        if self.method not in METHODS:
            raise UsageError(f"unknown coherence method {self.method!r} (known: {', '.join(METHODS)})")
        for name in ("search_radius_px", "vote_spacing_px", "seed_search_px", "dense_spacing_px"):
            if not 0 < getattr(self, name) < math.inf:
                raise UsageError(f"{name} must be a finite number > 0, got {getattr(self, name)}", option=name)
        for name in ("stretch_weight", "outlier_px", "min_id_px", "max_growth_px", "min_carry_px",
                     "seed_angle_penalty_px", "join_tol_px", "min_segment_px", "knot_spacing_px", "bend_weight"):
            if not getattr(self, name) >= 0:
                raise UsageError(f"{name} must be >= 0, got {getattr(self, name)}", option=name)
        if not 0 <= self.min_tangent_dot <= 1:
            raise UsageError(f"min tangent dot must be in [0, 1], got {self.min_tangent_dot}")
