"""One frame's lines: scene + camera -> strokes. The stages in order, each a pure function."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .camera import Camera
from .chaining import chain_runs
from .errors import InputError
from .features import feature_edges, static_feature_mask
from .model import Strokes
from .options import LineOptions
from .scene import Scene
from .strokeops import drop_retraced, drop_short, simplify, split_max_length
from .visibility import Occluder, visible_runs


@dataclass
class LineRenderer:
    """Holds what is built once per scene (BVH, static edge masks) for many frames."""

    scene: Scene
    options: LineOptions
    backend: str | None = None
    occluder: Occluder = field(init=False)

    def __post_init__(self):
        self.occluder = Occluder(self.scene, self.backend)
        self.static = static_feature_mask(self.scene, self.options)

    def check_camera(self, camera: Camera, frame: int = 0) -> None:
        if self.occluder.eye_enclosed(camera):
            raise InputError(f"frame {frame}: the camera eye is inside the mesh (nothing can be seen)",
                             self.scene.source or None)

    def render(self, camera: Camera, frame: int = 0) -> Strokes:
        """Visible strokes of one frame, in pixels, before tracking (ids in chain order)."""
        opts = self.options
        fe = feature_edges(self.scene, camera, opts, self.static)
        runs = visible_runs(fe, camera, self.occluder, opts, self.scene.radius)
        strokes = chain_runs(runs, opts, camera=camera, frame=frame)
        if opts.merge_overlaps:
            strokes = drop_retraced(strokes, opts.overlap_tol_px)
        strokes = split_max_length(strokes, opts.max_length_px)
        strokes = drop_short(strokes, opts.min_length_px)
        strokes = simplify(strokes, opts.simplify_tol_px)
        return strokes
