"""One frame's lines: scene + camera -> strokes. The stages in order, each a pure function."""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np

from strokekit.camera.view import Camera
from strokekit.errors import InputError
from strokekit.lines.chaining import chain_runs
from strokekit.lines.facing import FrameView
from strokekit.lines.features import feature_edges, static_features
from strokekit.lines.occlusion import occlusion_runs
from strokekit.lines.sightlines import eye_enclosed
from strokekit.lines.strokeops import drop_overlaps, drop_short, simplify, split_max_length
from strokekit.lines.surface import surface_lift
from strokekit.lines.visibility import visible_runs
from strokekit.model import Strokes
from strokekit.numba_cache import keyboard_interrupts
from strokekit.options import LineOptions
from strokekit.scene.load import Scene
from strokekit.scene.occluder import Occluder


@dataclass
class LineRenderer:
    """Holds what is built once per scene (BVH, static features) for many frames."""

    scene: Scene
    options: LineOptions
    backend: str | None = None
    occluder: Occluder = field(init=False)

    def __post_init__(self):
        self.occluder = Occluder(self.scene, self.backend)
        self.static = static_features(self.scene, self.options)
        if not self.options.retest_front_hits and self.occluder.backend == "open3d":
            _ = self.scene.face_normal_rows  # built with the scene, not by the first frame
        self._edge_on: tuple[bytes, Occluder] | None = None

    def occluder_for(self, view: FrameView) -> Occluder:
        """The occluder of this frame's rays: the scene, less the faces the camera sees exactly
        edge-on (they hide nothing: a camera in a model's symmetry plane must see the lines behind
        the faces that lie in it). Such a BVH is built once per set of faces (a still camera, or
        the frames of a path that return to it) and kept for the next frames."""
        edge_on = view.edge_on
        if not edge_on.any():
            return self.occluder
        key = np.packbits(edge_on).tobytes()
        kept = self._edge_on  # (read once: frames in other threads may replace it)
        if kept is None or kept[0] != key:
            kept = self._edge_on = (key, self.occluder.without_faces(edge_on))
        return kept[1]

    def check_camera(self, camera: Camera, frame: int = 0) -> None:
        if eye_enclosed(self.occluder, camera):
            raise InputError(f"frame {frame}: the camera eye is inside the mesh (nothing can be seen)",
                             self.scene.source or None)

    def render(self, camera: Camera, frame: int = 0, timings: dict | None = None) -> Strokes:
        """Visible strokes of one frame, in pixels, before tracking (ids in chain order).
        `timings`, if given, accumulates seconds per stage ('feature edges', 'visibility', 'chaining')."""
        with keyboard_interrupts():  # (a Ctrl-C in a hidden-line compiled loop stays a KeyboardInterrupt)
            return self._render(camera, frame, timings)

    def _render(self, camera: Camera, frame: int, timings: dict | None) -> Strokes:
        opts = self.options
        clock = _Clock(timings)
        view = FrameView(self.scene, camera)
        fe = feature_edges(view, opts, self.static, with_lift=True)
        if fe.lift is None:
            fe = replace(fe, lift=surface_lift(view, fe, opts.occlusion_offset))
        clock.lap("feature edges")
        occluder = self.occluder_for(view)
        if opts.occlusion is None:
            runs = visible_runs(fe, camera, occluder, opts, self.scene.radius)
            clock.lap("visibility")
        else:
            runs = occlusion_runs(fe, view, occluder, opts)
            clock.lap("occlusion levels")
        strokes = chain_runs(runs, opts, camera=camera, frame=frame)
        # A run visible at a single point (an edge touching the view only at one sample) has no
        # length to draw.
        has_length = strokes.lengths > 0.0
        if not has_length.all():
            strokes = strokes.select(has_length)
        strokes = drop_overlaps(strokes, opts.overlap_tol_px if opts.merge_overlaps else 0.0, opts.doubled_px,
                                compiled=opts.occlusion is not None)
        strokes = split_max_length(strokes, opts.max_length_px)
        strokes = drop_short(strokes, opts.min_length_px)
        strokes = simplify(strokes, opts.simplify_tol_px)
        clock.lap("chaining")
        return strokes


class _Clock:
    def __init__(self, sink: dict | None):
        self.sink = sink
        self.t = time.perf_counter()

    def lap(self, name: str) -> None:
        if self.sink is not None:
            now = time.perf_counter()
            self.sink[name] = self.sink.get(name, 0.0) + now - self.t
            self.t = now
