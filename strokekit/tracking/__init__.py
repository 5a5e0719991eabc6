"""The tracking stage: carries ids, the parametrization u and the self-similar level of the
strokes from frame to frame (`Tracker.step`, one method per strategy)."""

from strokekit.tracking.options import METHODS, TrackingOptions
from strokekit.tracking.tracker import Tracker, track_frames

__all__ = ["METHODS", "Tracker", "TrackingOptions", "track_frames"]
