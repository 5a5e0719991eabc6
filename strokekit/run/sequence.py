"""A camera path rendered in memory, frame by frame (`render_sequence`)."""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from pathlib import Path

from strokekit.camera.view import Camera, CameraPath
from strokekit.lines.budget import check_lines_fit
from strokekit.lines.renderer import LineRenderer
from strokekit.run.frame import Frame, StrokeCarry, render_frame
from strokekit.run.request import RenderRequest
from strokekit.scene.load import Scene, load_scene
from strokekit.style.file import check_style_names


def render_sequence(scene: Scene | str | Path, cameras: CameraPath | Iterable[Camera] | Iterable[tuple[int, Camera]],
                    request: RenderRequest | None = None) -> Iterator[Frame]:
    """Yield a Frame per camera, in order, as `strokekit render` draws them: the same lines,
    strokes, ids and JSON bytes (Frame.to_json). `scene`: a loaded Scene or a scene file;
    `cameras`: a CameraPath or cameras (frames numbered from 1), or (frame number, camera)
    pairs (CameraPath.select). What the frames draw and carry over is settled for the whole
    sequence (RenderRequest.plan): by default a sequence draws brush paths, one camera its lines."""
    scene = scene if isinstance(scene, Scene) else load_scene(scene)
    fps = cameras.fps if isinstance(cameras, CameraPath) else 24.0  # (frame N shows the animation at (N - 1) / fps)
    shots = numbered(cameras)
    plan = (request or RenderRequest()).plan(len(shots), fps)
    check_lines_fit(scene, shots, plan.lines)
    check_style_names(plan.style, scene)
    renderer = LineRenderer(scene, plan.lines)
    carry = StrokeCarry(plan)
    for number, camera in shots:
        yield carry.step(render_frame(renderer, number, camera, plan))


def numbered(cameras) -> list[tuple[int, Camera]]:
    """(frame number, camera) pairs: a CameraPath's or a list's cameras numbered from 1, or the
    pairs given."""
    if isinstance(cameras, CameraPath):
        cameras = cameras.cameras
    items = list(cameras)
    if all(isinstance(c, Camera) for c in items):
        return list(enumerate(items, 1))
    return [(int(n), c) for n, c in items]
