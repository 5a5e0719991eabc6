"""One frame's lines: scene + camera -> strokes. The stages in order, each a pure function."""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

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
from strokekit.scene.occluder import Occluder, PosedRays


@dataclass
class LineRenderer:
    """Holds what is built once per scene (BVH, static features) for many frames. `occluder`:
    the scene's ray backend when built elsewhere (a posed scene's, see `at`)."""

    scene: Scene
    options: LineOptions
    backend: str | None = None
    occluder: Occluder | None = None

    def __post_init__(self):
        if self.occluder is None:
            self.occluder = Occluder(self.scene, self.backend)
        self.static = static_features(self.scene, self.options)
        if not self.options.retest_front_hits and self.occluder.backend == "open3d":
            _ = self.scene.face_normal_rows  # built with the scene, not by the first frame
        self._edge_on: tuple[bytes, Occluder] | None = None
        self._posed: dict = {}  # animation -> (PosedRays, the last posed scene's renderer)

    def at(self, time: float, animation: str | None = None) -> LineRenderer:
        """The renderer of the scene at `time` seconds of its animation `animation` (a name or
        number; None: the first): this renderer for a still scene (or one the animation leaves
        still), else one of the posed scene, whose objects keep their BVHs (PosedRays) from
        frame to frame."""
        motion = self.scene.motion
        if motion is None or self.scene.pose is not None:
            return self
        index = motion.animation(animation)
        if not motion.moves(index):
            return self
        nodes: dict = {}  # (the node matrices at this time, for both)
        D = motion.carried(index, time, nodes)
        if D is not None:
            return CarriedRenderer(self, D, motion.pose(self.scene, index, time, nodes),
                                   lambda: self._posed_at(time, index))
        return self._posed_at(time, index)

    def _posed_at(self, time: float, index: int) -> LineRenderer:
        """The renderer of the posed scene (scene.at) at `time` of animation `index`."""
        rays, last = self._posed.get(index) or (PosedRays(self.scene, index, self.backend), None)
        posed = self.scene.at(time, index)
        if last is None or last.scene is not posed:
            last = LineRenderer(posed, self.options, self.backend, rays.occluder(posed))
        self._posed[index] = (rays, last)
        return last

    @property
    def pose(self):
        """Where the scene's objects are (scene.pose): None for a scene at rest."""
        return self.scene.pose

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
        if self.scene.pose is not None:
            strokes = strokes.replace(pose=self.scene.pose)
        clock.lap("chaining")
        return strokes


class CarriedRenderer:
    """The renderer of a scene that one node carries as a whole (SceneMotion.carrier): its objects
    keep their rest BVH and tables, each frame's lines are the rest scene's seen by the camera
    taken back by the carrier's similarity D (what the frame's camera sees of the scene moved by
    D), their surface points moved by D. A camera that cannot be taken back so (an angled
    parallel projection, whose angles hold to the world's axes), the raster pass and world
    ribbons (`scene`, `occluder`) use the posed scene (`posed()`, built when first asked)."""

    def __init__(self, rest: LineRenderer, D: np.ndarray, pose, posed):
        self.rest, self.D, self.pose, self._posed, self._built = rest, D, pose, posed, None
        self.options = rest.options
        self.scale = float(np.cbrt(np.linalg.det(D[:3, :3])))
        self.R = D[:3, :3] / self.scale

    def posed(self) -> LineRenderer:
        if self._built is None:
            self._built = self._posed()
        return self._built

    @property
    def scene(self):
        return self.posed().scene

    @property
    def occluder(self):
        return self.posed().occluder

    def back(self, camera: Camera) -> Camera | None:
        """The camera in the rest scene's frame (None for an angled parallel projection)."""
        if camera.projection not in ("perspective", "orthographic"):
            return None
        s, R, t = self.scale, self.R, self.D[:3, 3]
        eye, target = (np.asarray(camera.eye) - t) @ R / s, (np.asarray(camera.target) - t) @ R / s
        return replace(camera, eye=tuple(eye), target=tuple(target), up=tuple(np.asarray(camera.up) @ R),
                       ortho_height=camera.ortho_height / s, near=None if camera.near is None else camera.near / s)

    def check_camera(self, camera: Camera, frame: int = 0) -> None:
        back = self.back(camera)
        (self.rest.check_camera(back, frame) if back is not None else self.posed().check_camera(camera, frame))

    def render(self, camera: Camera, frame: int = 0, timings: dict | None = None) -> Strokes:
        back = self.back(camera)
        if back is None:
            return self.posed().render(camera, frame, timings)
        st = self.rest.render(back, frame, timings)
        X = st.surface @ self.D[:3, :3].T + self.D[:3, 3]
        return st.replace(surface=X, camera=camera, pose=self.pose)


class _Clock:
    def __init__(self, sink: dict | None):
        self.sink = sink
        self.t = time.perf_counter()

    def lap(self, name: str) -> None:
        if self.sink is not None:
            now = time.perf_counter()
            self.sink[name] = self.sink.get(name, 0.0) + now - self.t
            self.t = now
