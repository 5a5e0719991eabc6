"""Limits of what a camera file (JSON or glTF) may ask for, and the projections a camera may
have, without numpy: the command line declares its options from them."""

from __future__ import annotations

#: Beyond these a run would fail late (a width of 1e30 px overflows the writers) or never end (a
#: frame_count of 1e12).
MAX_IMAGE_PX = 100_000  # per side
MAX_PATH_FRAMES = 100_000

#: Projections a camera may have. The five after "orthographic" take their direction from angles.
PROJECTIONS = ("perspective", "orthographic", "isometric", "dimetric", "trimetric", "cavalier", "cabinet")
ANGLED = PROJECTIONS[2:]
