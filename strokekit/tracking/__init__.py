"""The tracking stage: carries ids, the parametrization u and the self-similar level of the
strokes from frame to frame (`Tracker.step`, one method per strategy)."""

from strokekit.lazy import exports

#: Public names and their modules, each imported when first used.
_EXPORTS = {
    "METHODS": "strokekit.tracking.options",
    "Tracker": "strokekit.tracking.tracker",
    "TrackingOptions": "strokekit.tracking.options",
    "track_frames": "strokekit.tracking.tracker",
}
__all__ = list(_EXPORTS)
__getattr__ = exports(__name__, _EXPORTS)
