"""A frame's way: `render_frame` draws what needs no other frame (its lines, its raster pass),
`StrokeCarry.step` then carries the strokes over from the frame before (tracked lines or brush
paths), in frame order. The in-memory sequence and the file-writing run both go this way."""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from functools import cached_property

from strokekit.camera.view import Camera
from strokekit.cryptomatte import name_to_hex
from strokekit.lines.renderer import LineRenderer
from strokekit.model import BrushPaths, Strokes
from strokekit.paths.stage import PathTracker
from strokekit.raster.bands import RasterFrame, band_regions, render_raster
from strokekit.raster.hits import ensure_kernels
from strokekit.raster.rays import surface_depth_at
from strokekit.run.request import SequencePlan
from strokekit.style.linesets import Style
from strokekit.style.widths import StyleContext, StyledStrokes, apply_style, style_context
from strokekit.tracking.tracker import Tracker
from strokekit.writers.strokes_json import strokes_json
from strokekit.writers.svg import bands_layer, svg_document


@dataclass(frozen=True)
class Frame:
    """One frame of a sequence.

    lines: the visible lines (tracked: ids and u carried from the frames before, when the
    request tracks lines); paths: the brush paths drawn instead of the lines (None: the lines
    are drawn); `strokes` is what is drawn. raster: the raster pass (None when not asked, or
    once its images are written); raster_info: what the frame JSON says of it (depth range,
    object and material ids); underlays: SVG layers under the lines (the bands as polygons).
    json_head: the frame JSON's keys before the strokes; layers: the SVG's layers. style: how
    the strokes are drawn, style_context: what the style needed of the scene for this frame
    (strokekit.style.style_context); `styled`: the strokes in their style, as every writer
    draws them. timings: seconds per stage of this frame."""

    number: int
    camera: Camera
    lines: Strokes
    json_head: dict
    layers: tuple[str, ...]
    paths: BrushPaths | None = None
    #: The frame's time in the scene's animation, and which animation (None: a still scene).
    time: float | None = None
    animation: str | None = None
    raster: RasterFrame | None = None
    raster_info: dict = field(default_factory=dict)
    underlays: tuple[str, ...] = ()
    timings: dict = field(default_factory=dict)
    style: Style = field(default_factory=Style)
    style_context: StyleContext | None = None

    @property
    def strokes(self) -> Strokes:
        """What the frame draws: its brush paths, or its lines."""
        return self.paths.strokes if self.paths is not None else self.lines

    @cached_property
    def styled(self) -> StyledStrokes:
        """The frame's strokes in its style: the strokes drawn, their widths and line sets."""
        return apply_style(self.strokes, self.layers, self.style, self.style_context)

    def styled_lines(self) -> StyledStrokes:
        """The frame's lines in its style (the raster outputs draw the lines, not brush paths)."""
        return self.styled if self.paths is None else apply_style(self.lines, self.layers, self.style,
                                                                  self.style_context)

    def to_json(self) -> bytes:
        """The frame JSON (writers.strokes_json), as the run writes it."""
        head = {**self.json_head, "raster": self.raster_info} if self.raster_info else self.json_head
        if self.strokes.pose is not None:  # a moving scene: where its objects were
            head = {**head, "animation": self.animation, **self.strokes.pose.to_json()}
        cam = self.strokes.camera
        return strokes_json(self.strokes, cam.width, cam.height, self.number, extra=head, paths=self.paths,
                            styled=self.styled, layers=self.layers)

    def to_svg(self, decimals: int = 2, dash_paths: bool = False, lines: str = "outline") -> str:
        """The frame's SVG (writers.svg.svg_document), as the run writes it with these outputs
        (lines: writers.options.SVG_LINES)."""
        cam = self.strokes.camera
        return svg_document(self.strokes, cam.width, cam.height, self.layers, decimals=decimals,
                            underlays=list(self.underlays) or None, dash_paths=dash_paths, styled=self.styled,
                            lines=lines)


def render_frame(renderer: LineRenderer, number: int, camera: Camera, plan: SequencePlan, work=None,
                 raster_threads: int = 1) -> Frame:
    """What a frame draws without the frames before it: its lines and raster pass. `work`: a
    z-buffer workspace (raster.hits.thread_workspace) the raster pass reuses; the frame's
    raster then lives until the next pass in that workspace. `raster_threads`: the z-buffer's."""
    timings: dict = {}
    clock = plan.clock
    time_s = clock.time(number)
    t = time.perf_counter()
    posed = renderer.at(time_s, clock.animation)
    if posed is not renderer:
        timings["pose scene"] = time.perf_counter() - t
    renderer = posed
    renderer.check_camera(camera, number)
    lines = renderer.render(camera, number, timings)
    context = None
    if plan.style.needs_scene_depths or plan.style.needs_faces:
        t = time.perf_counter()
        context = style_context(plan.style, renderer.scene, camera, lines, surface_depth_at(renderer.occluder))
        timings["style"] = time.perf_counter() - t
    raster, info, underlays = None, {}, ()
    if plan.raster is not None:
        # The kernels' load (a process's first raster frame) is the 'raster kernels' stage, not this frame's.
        timings["kernels"] = ensure_kernels()
        t = time.perf_counter()
        raster = render_raster(renderer.scene, camera, renderer.occluder, plan.raster, work=work, timings=timings,
                               threads=raster_threads)
        info = raster_info(raster)
        if plan.raster.band_polygons:
            underlays = (bands_layer(band_regions(raster)),)
        timings["raster pass"] = time.perf_counter() - t
    moving = renderer.pose is not None
    return Frame(number, camera, lines, plan.json_head(), plan.lines.layers, raster=raster, raster_info=info,
                 underlays=underlays, timings=timings, style=plan.style, style_context=context,
                 time=time_s if moving else None, animation=clock.animation if moving else None)


def raster_info(raster: RasterFrame) -> dict:
    """What the frame JSON says of a raster pass: the depth PNG's range (when written), the
    objects and materials with their ids."""
    info: dict = {}
    if raster.options.pngs and raster.options.depth:
        info["depth_range"] = list(raster.depth_range())
    info.update(objects_and_materials(raster.scene))
    return info


def objects_and_materials(scene) -> dict:
    """The scene's objects and materials for the frame JSON and the report: name, the value of
    its pixels in the object-id PNG (objects: index + 1; 0 is background) and its Cryptomatte id
    (8 hex digits of the float32 bits, as in the EXR's manifest)."""
    return {"objects": [{"name": n, "objectid": i + 1, "cryptomatte": name_to_hex(n)}
                        for i, n in enumerate(scene.objects)],
            "materials": [{"name": m.name, "index": i, "cryptomatte": name_to_hex(m.name)}
                          for i, m in enumerate(scene.materials)]}


class StrokeCarry:
    """Carries a sequence's strokes from frame to frame: `step` takes the frames in order and
    tracks their lines, or makes their brush paths from the paths before."""

    def __init__(self, plan: SequencePlan):
        self.tracker = Tracker(plan.tracking) if plan.tracking is not None else None
        self.paths = PathTracker(plan.paths) if plan.paths is not None else None

    @property
    def needed(self) -> bool:
        """Whether `step` changes a frame (else a frame is done where it was drawn)."""
        return self.tracker is not None or self.paths is not None

    def step(self, frame: Frame) -> Frame:
        timings = dict(frame.timings)
        lines, paths = frame.lines, None
        if self.tracker is not None:
            t = time.perf_counter()
            lines = self.tracker.step(lines)
            timings["tracking"] = time.perf_counter() - t
        if self.paths is not None:
            t = time.perf_counter()
            paths = self.paths.step(lines)
            if lines.pose is not None:  # (the paths lie on the frame's posed scene too)
                paths = replace(paths, strokes=paths.strokes.replace(pose=lines.pose),
                                lines=paths.lines.replace(pose=lines.pose))
            timings["brush paths"] = time.perf_counter() - t
        return replace(frame, lines=lines, paths=paths, timings=timings)
