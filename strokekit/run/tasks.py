"""The tasks a worker runs: a frame's drawing and raster files (`FrameTask`), and a carried
frame's files (`WriteTask`: SVG, JSON, GLB), each file written atomically. Tasks and results are
dataclasses: picklable, for a process pool or a dask cluster."""

from __future__ import annotations

import time
import traceback
from dataclasses import dataclass, field, replace

import numpy as np

from strokekit.camera.view import Camera
from strokekit.colour import srgb_encode
from strokekit.errors import StrokekitError
from strokekit.fileio import atomic_write_bytes
from strokekit.raster.bands import band_regions, render_raster
from strokekit.raster.hits import thread_workspace
from strokekit.raster.passes import compositing_passes
from strokekit.raster.rays import surface_depth_at
from strokekit.raster.strokes import stroke_coverage
from strokekit.run.frame import Frame, render_frame
from strokekit.run.request import SequencePlan
from strokekit.run.spec import OutputOptions
from strokekit.run.workers import SceneRef
from strokekit.scene.occluder import Occluder
from strokekit.writers.exr import exr_bytes, lines_sparse
from strokekit.writers.gltf import glb_for_frame
from strokekit.writers.png import png_files
from strokekit.writers.svg import bands_layer


@dataclass(frozen=True)
class WriteError:
    """A file that could not be written (disk full, no permission): the OSError's parts, which
    pickle where the error may not; the run raises it again (`error`) and stops."""

    errno: int | None
    strerror: str | None
    filename: str | None

    @classmethod
    def of(cls, e: OSError) -> WriteError:
        return cls(e.errno, e.strerror, e.filename)

    def error(self) -> OSError:
        return OSError(self.errno, self.strerror, self.filename)


@dataclass(frozen=True)
class WriteResult:
    """What a frame's writes did: the files written and their seconds per stage, or the error
    (`error`: the frame failed; `write_error`: a file could not be written, the run stops)."""

    number: int
    files: list[str] = field(default_factory=list)
    seconds: float = 0.0
    timings: dict = field(default_factory=dict)
    error: str | None = None
    write_error: WriteError | None = None


@dataclass(frozen=True)
class FrameResult:
    """What a frame task did. frame: the drawn frame (its raster written and dropped); None
    when it failed, or was written in the task and is not needed again. files: the raster
    files written; written: the frame's own files, when the task wrote them; ray_tracer: the
    occlusion backend that drew it. error / write_error: as WriteResult's."""

    number: int
    frame: Frame | None = None
    files: list[str] = field(default_factory=list)
    seconds: float = 0.0
    timings: dict = field(default_factory=dict)
    ray_tracer: str = ""
    written: WriteResult | None = None
    error: str | None = None
    write_error: WriteError | None = None
    traceback: str | None = None


@dataclass(frozen=True)
class FrameTask:
    """Draw one frame (`render_frame`) and write its raster files. outputs: where (None: the
    frame was kept from an earlier run and is drawn only for the frames after it: nothing is
    written). write: the frame needs no other frame (nothing is carried), so its own files are
    written here too, and the strokes go back only when `keep_frame` (sequence.glb needs them)."""

    scene: SceneRef
    plan: SequencePlan
    number: int
    camera: Camera
    outputs: OutputOptions | None
    write: bool = False
    keep_frame: bool = False
    raster_threads: int = 1  # the z-buffer's threads (RunSpec.raster_threads)

    def __call__(self) -> FrameResult:
        return frame_task(self)


@dataclass(frozen=True)
class WriteTask:
    """Write one frame's SVG, JSON and GLB. scene: the GLB's world ribbons lie on its surface."""

    frame: Frame
    outputs: OutputOptions
    scene: SceneRef

    def __call__(self) -> WriteResult:
        return write_task(self)


class _WriteFailed(Exception):
    """A file of the frame could not be written (atomic_write_bytes raised `error`): the task
    reports it as a write error, which stops the run, not as a failed frame."""

    def __init__(self, error: OSError):
        super().__init__(str(error))
        self.error = error


def _write(path, data: bytes) -> str:
    try:
        return str(atomic_write_bytes(path, data))
    except OSError as e:
        raise _WriteFailed(e) from None


def frame_task(task: FrameTask) -> FrameResult:
    """Run a FrameTask. Errors come back in the result, a failed frame must not lose the others."""
    t0 = time.perf_counter()
    n = task.number
    try:
        r = task.scene.renderer()
        plan = task.plan if task.outputs is not None else replace(task.plan, raster=None)
        frame = render_frame(r, n, task.camera, plan, work=thread_workspace() if plan.raster is not None else None,
                             raster_threads=task.raster_threads)
        timings = dict(frame.timings)
        files = raster_files(frame, task.outputs, timings, task.raster_threads) \
            if task.outputs is not None else []
        frame = replace(frame, raster=None)
        written = None
        if task.write and task.outputs is not None:
            written = write_task(WriteTask(frame, task.outputs, task.scene), occluder=_frame_renderer(r, frame).occluder)
            if not task.keep_frame:
                frame = None
        return FrameResult(n, frame, files, time.perf_counter() - t0, timings, r.occluder.backend, written)
    except _WriteFailed as w:
        return FrameResult(n, write_error=WriteError.of(w.error))
    except StrokekitError as e:
        return FrameResult(n, error=str(e))
    except Exception as e:
        return FrameResult(n, error=f"frame {n}: {type(e).__name__}: {e}", traceback=traceback.format_exc())


def write_task(task: WriteTask, occluder: Occluder | None = None) -> WriteResult:
    """Write one frame's SVG, JSON and GLB (atomic). The GLB's world ribbons lie on the scene's
    surface (raster.surface_depth_at): `occluder`, or this process's renderer of task.scene."""
    t0 = time.perf_counter()
    frame, outputs = task.frame, task.outputs
    try:
        files = []
        timings: dict = {}
        if outputs.svg:
            text = frame.to_svg(outputs.decimals, outputs.dash_paths, outputs.svg_lines)
            files.append(_write(outputs.frame_file(frame.number, ".svg"), text.encode()))
            timings["svg"] = time.perf_counter() - t0
        if outputs.json:
            files.append(_write(outputs.frame_file(frame.number, ".json"), frame.to_json()))
            timings["json"] = time.perf_counter() - t0 - sum(timings.values())
        if outputs.gltf and not outputs.gltf_sequence:
            if occluder is None and frame.time is not None:  # (world ribbons lie on the posed surface)
                occluder = _frame_renderer(task.scene.renderer(), frame).occluder
            files.append(_write(outputs.frame_file(frame.number, ".glb"), glb_for_frame(
                frame.styled, frame.strokes.camera, outputs.gltf_options,
                surface_depth(outputs, task.scene, occluder))))
            timings["ribbons + glTF"] = time.perf_counter() - t0 - sum(timings.values())
        return WriteResult(frame.number, files, time.perf_counter() - t0, timings)
    except _WriteFailed as w:
        return WriteResult(frame.number, write_error=WriteError.of(w.error))
    except Exception as e:
        return WriteResult(frame.number, error=f"frame {frame.number}: writing failed: {type(e).__name__}: {e}")


def _frame_renderer(renderer, frame: Frame):
    """The renderer of the scene as `frame` saw it (posed at its time, for a moving scene)."""
    return renderer if frame.time is None else renderer.at(frame.time, frame.animation)


def surface_depth(outputs: OutputOptions, scene: SceneRef | None, occluder: Occluder | None = None):
    """raster.surface_depth_at for world ribbons (None for image-space ones, or without a scene)."""
    if outputs.gltf_options is not None and outputs.gltf_options.space != "world":
        return None
    if occluder is None:
        if scene is None:
            return None
        occluder = scene.renderer().occluder
    return surface_depth_at(occluder)


def raster_files(frame: Frame, outputs: OutputOptions, timings: dict, threads: int = 1) -> list[str]:
    """Write one frame's image passes (PNGs, one folder per pass: its raster pass's images, the
    lines PNG) and EXR; returns the files written. The lines in them are the frame's as drawn,
    before any carry, at their widths in the frame's style. `timings` gets the seconds of each part;
    `threads`: the PNGs encoded at once."""
    files: list[str] = []
    raster, camera = frame.raster, frame.camera
    stem = outputs.stem(frame.number)
    covered: dict = {}

    def coverage() -> dict:
        """The strokes' coverage per kind, once for the lines PNG and the EXR's lines layer."""
        if not covered:
            lines = frame.styled_lines()
            covered[0] = stroke_coverage(lines.strokes, int(camera.width), int(camera.height), lines.width)
        return covered[0]

    if raster is not None:
        t1 = time.perf_counter()
        images = raster.images() if raster.options.pngs else {}
        timings["images"] = timings.get("images", 0.0) + (time.perf_counter() - t1)
        text = {}
        if "depth" in images:
            zn, zf = raster.depth_range()
            text["depth"] = {"near": repr(zn), "far": repr(zf)}
        if outputs.lines_png:
            t2 = time.perf_counter()
            images["lines"] = _lines_image(coverage(), camera)
            timings["lines PNG"] = time.perf_counter() - t2
        t2 = time.perf_counter()
        pngs = png_files(images, text, threads)
        timings["png"] = timings.get("png", 0.0) + (time.perf_counter() - t2)
        for name, data in pngs.items():
            files.append(_write(outputs.out_dir / name / f"{stem}.png", data))
        timings["raster pass"] = timings.get("raster pass", 0.0) + time.perf_counter() - t1 \
            - timings.get("lines PNG", 0.0)
        if outputs.exr is not None:
            t1 = time.perf_counter()
            passes = compositing_passes(raster, frame.lines, outputs.exr,
                                        coverage() if "lines" in outputs.exr.passes else None)
            files.append(_write(outputs.frame_file(frame.number, ".exr"), exr_bytes(passes, outputs.exr.codec,
                                                                                     outputs.exr.precision)))
            timings["EXR"] = time.perf_counter() - t1
    elif outputs.lines_png:
        t1 = time.perf_counter()
        images = {"lines": _lines_image(coverage(), camera)}
        for name, data in png_files(images).items():
            files.append(_write(outputs.out_dir / name / f"{stem}.png", data))
        timings["lines PNG"] = time.perf_counter() - t1
    return files


def _lines_image(cov: dict, camera: Camera) -> np.ndarray:
    """(H, W, 4) uint8 RGBA, sRGB-encoded straight alpha: the visible strokes in their colours, from
    their coverage per kind (raster.strokes.stroke_coverage)."""
    W, H = int(camera.width), int(camera.height)
    out = np.zeros((H * W, 4), np.uint8)
    if cov:
        pix, _, total = lines_sparse(cov)
        a = total[:, 3:4]
        with np.errstate(invalid="ignore", divide="ignore"):
            straight = np.where(a > 0, total[:, :3] / np.where(a > 0, a, 1.0), 0.0)
        px = np.concatenate([srgb_encode(np.clip(straight, 0, 1)), a], axis=1)
        out[pix] = np.round(np.clip(px, 0, 1) * 255.0).astype(np.uint8)
    return out.reshape(H, W, 4)


def raster_outputs(scene, camera: Camera, occluder: Occluder | None, options) -> dict[str, bytes]:
    """{pass: PNG bytes} of one frame for RasterOptions (see strokekit.raster; raster_files
    writes them as OUT/<pass>/frame_0001.png)."""
    return png_files(render_raster(scene, camera, occluder, options).images())


def raster_outputs_with_bands_layer(scene, camera: Camera, occluder: Occluder | None, options,
                                    timings: dict | None = None,
                                    work=None) -> tuple[dict[str, bytes], list]:
    """(PNG outputs, the SVG text of the 'bands' layer in a list, [] when options.band_polygons is
    off): pass it as svg_document(..., underlays=...) so the bands sit under the line layers.
    `timings` gets the raster stages' seconds (render_raster's, 'images', 'png'); `work`: the
    z-buffer workspace (raster.hits.thread_workspace()) whose buffers this frame reuses."""
    frame = render_raster(scene, camera, occluder, options, work=work, timings=timings)
    t0 = time.perf_counter()
    images = frame.images()
    t1 = time.perf_counter()
    pngs = png_files(images)
    if timings is not None:
        timings["images"] = timings.get("images", 0.0) + (t1 - t0)
        timings["png"] = timings.get("png", 0.0) + (time.perf_counter() - t1)
    return pngs, ([bands_layer(band_regions(frame))] if options.band_polygons else [])
