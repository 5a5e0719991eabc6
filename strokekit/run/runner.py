"""A render run: which stages the requested outputs need, per-frame work in parallel (process
pool started with spawn, or a dask.distributed cluster), the tracking pass in frame order, then
writing, with atomic files, resumption (run.resume) and a run report.

Per-frame tasks carry only the scene path and content hash, the frame number and its camera;
each worker loads the scene and builds its BVH once (cached per process).
"""

from __future__ import annotations

import os
import time
from collections import deque
from pathlib import Path
from typing import Callable

from strokekit.errors import UsageError
from strokekit.fileio import atomic_write_bytes, check_pattern
from strokekit.lines.budget import check_lines_fit
from strokekit.raster.rays import check_raster_fits
from strokekit.run.cluster import check_workers
from strokekit.run.frame import Frame, StrokeCarry, objects_and_materials
from strokekit.run.kernels import RunKernels
from strokekit.run.manifest import write_run_manifest
from strokekit.run.resume import ResumePlan, clean_up, lines_needed, plan_resume, run_files
from strokekit.run.spec import (
    RunInterrupted,
    RunResult,
    RunSpec,
    RunWriteError,
    add_timings,
    plan_stages,
)
from strokekit.run.tasks import FrameResult, FrameTask, WriteResult, WriteTask, surface_depth, write_task
from strokekit.run.workers import SceneRef, Workers, make_executor
from strokekit.scene.load import Scene, load_scene
from strokekit.style.file import check_style_names
from strokekit.writers.gltf import glb_for_sequence


def _load_and_plan(spec: RunSpec, res: RunResult, scene: Scene | None = None, load_seconds: float = 0.0):
    """The main process's scene (hash, summary) and the stage plan, timed as the first stage.
    `scene`: the scene file already loaded by the caller (not loaded again) in `load_seconds`."""
    t = time.perf_counter() - load_seconds
    scene = load_scene(spec.scene_path) if scene is None else scene
    res.scene_hash = scene.content_hash
    res.scene_summary = {"faces": int(len(scene.faces)), "objects": len(scene.objects),
                         "materials": len(scene.materials)}
    if spec.raster is not None:  # the ids the object-id PNGs and Cryptomatte use
        res.scene_summary["ids"] = objects_and_materials(scene)
    res.stages = plan_stages(scene, spec)
    res.stages[0].seconds = time.perf_counter() - t
    return scene


def run(spec: RunSpec, progress: Callable[[str, int, int], None] | None = None, *,
        workers: Workers | None = None, scene: Scene | None = None, load_seconds: float = 0.0,
        started_at: float | None = None, notice: Callable[[str], None] | None = None,
        kernels: RunKernels | None = None) -> RunResult:
    """Render every frame of `spec`. `progress(phase, done, total)` is called when the frames
    start ("lines", 0, total) and as they finish.
    `workers`: make_executor(spec.workers, spec.scheduler, SceneRef(spec.scene_path, "", spec.lines)) started
    by the caller (and closed by it), e.g. before it loads the scene, so the workers start sooner;
    `scene`: spec.scene_path already loaded by the caller, in `load_seconds` (reported as the
    load stage); `started_at`: the caller's time.perf_counter() when the run began for the user
    (the report's wall time counts from there: the pool start and the load are part of it);
    `notice(line)`: told when the run has to wait for something the user may wonder about (the
    first compile of the kernels on a machine); `kernels`: a run.kernels.RunKernels the caller
    started (earlier: beside its scene load), else the run starts one.

    The steps: check the request, start the workers, load and plan the stages, plan the resume
    (`plan_resume`), stream the frames through line work, tracking and writing (`FrameStream`),
    write sequence.glb, and on Ctrl-C or failures clean up (`clean_up`).

    A file that cannot be written (disk full, no permission, a failing device; here or in a
    worker) stops the run at the first one: the frames it left part-written are removed, and
    RunWriteError (an OSError naming that file) is raised with the result."""
    t_start = time.perf_counter() if started_at is None else started_at
    res = RunResult()
    check_run(spec)
    resume: ResumePlan | None = None
    write_error: OSError | None = None
    # Workers start first: their imports and scene load overlap the main process's own load.
    own = workers is None
    raster = spec.raster is not None
    if own:
        workers = make_executor(spec.workers, spec.scheduler, warm=SceneRef(spec.scene_path, "", spec.lines),
                                kind=spec.worker_kind)
    # The raster kernels load (or, on a machine's first run, compile) beside the main process's work.
    if kernels is None:
        kernels = RunKernels(notice, raster=raster and workers.main_helps)
    try:
        scene = _load_and_plan(spec, res, scene, load_seconds if scene is not None else 0.0)
        check_lines_fit(scene, spec.cameras, spec.lines)  # before anything is written
        check_style_names(spec.request.style, scene)
        check_workers(spec, workers)  # a cluster's workers see the scene and the output folder
        stage = {s.name: s for s in res.stages}
        resume = plan_resume(spec, scene)
        res.frames_skipped = sorted(resume.done_before)
        try:
            res.outputs.append(str(write_run_manifest(spec.outputs.out_dir, resume.manifest, resume.entries)))
        except OSError as e:
            write_error = e
        if write_error is None:
            kernels.ready(spec, workers.main_helps, work=bool(lines_needed(spec, resume)), moving=moves(scene, spec))
            write_error = _stream_frames(spec, scene, res, stage, resume, progress, workers)
        for name, seconds in kernels.seconds().items():
            stage[name].seconds += seconds
    except KeyboardInterrupt:
        # Ctrl-C: the frames in progress are abandoned. The workers stop now (also the caller's:
        # their tasks belong to this run), then the temporary files of the writes they were in
        # are removed; every file left is complete (written whole, then renamed).
        workers.close()
        clean_up(spec, res, resume, interrupted=True)
        res.interrupted = True
        _finish(res, t_start)
        raise RunInterrupted(res) from None
    finally:
        if own:
            workers.close()
    if write_error is not None:
        res.write_error = f"{write_error.filename}: {write_error.strerror}"
        clean_up(spec, res, resume)
        _finish(res, t_start)
        raise RunWriteError(write_error, res)
    if res.failures:
        clean_up(spec, res, resume)
    return _finish(res, t_start)


def _stream_frames(spec: RunSpec, scene: Scene, res: RunResult, stage: dict, resume: ResumePlan,
                   progress: Callable[[str, int, int], None] | None, workers: Workers) -> OSError | None:
    """Every frame through line work, tracking and writing (FrameStream), then sequence.glb.
    Returns the first write error (the stream stopped there), or None."""
    if workers.main_helps:
        # Frames rendered here use this load; building the renderer (open3d, the BVH) is part
        # of the load stage.
        t = time.perf_counter()
        SceneRef(spec.scene_path, scene.content_hash, spec.lines).keep(scene)
        stage["load scene + BVH"].seconds += time.perf_counter() - t
    stream = FrameStream(spec, scene, res, stage, resume, progress)
    if progress is not None and stream.n_lines:
        progress("lines", 0, stream.n_lines)  # the frames start (the scene, its BVH and kernels ready)
    try:
        workers.map(stream.pending, stream.handle)
        if spec.fail_fast and res.failures and stream.write_error is None:
            stream.write_before_failure()
    finally:
        # The run manifest's update may fail too (a full disk): the clean-up of part-written
        # frames must still run, and the first error is the one to say.
        try:
            stream.enter_written()
        except OSError as e:
            stream.write_failed(None, e)
    if stream.write_error is None:
        try:
            write_sequence_glb(spec, scene, res, stage, stream)
        except OSError as e:
            stream.write_failed(None, e)
    return stream.write_error


def moves(scene: Scene, spec: RunSpec) -> bool:
    """Whether the run's animation moves the scene's objects (its frames are posed)."""
    m = scene.motion
    return m is not None and m.moves(m.animation(spec.request.animation))


def check_files_apart(spec: RunSpec, also_written=()) -> None:
    """UsageError when one of the run's outputs would overwrite one of its inputs (the scene, the
    camera file) or a file also written ((what, name) pairs `also_written`, e.g. the run report)."""
    written = {os.path.realpath(p) for p in run_files(spec)}  # (links resolved: --out may be one)
    for what, name in (("scene", spec.scene_path), ("camera file", spec.camera_source)):
        if name and os.path.realpath(name) in written and Path(name).is_file():
            raise UsageError(f"{name}: the {what} is also one of the run's outputs (it would be overwritten); "
                             "choose another --out or --pattern")
    for what, name in also_written:
        if name and os.path.realpath(name) in written:
            raise UsageError(f"{what} {name} is also one of the run's outputs: name another file")


def check_run(spec: RunSpec) -> None:
    """UsageError before any work: a file pattern that names two frames alike, an output over
    an input, a raster pass larger than the machine's memory."""
    check_pattern(spec.outputs.pattern)
    spec.outputs.check_names((f for f, _ in spec.cameras), spec.raster)
    check_files_apart(spec)
    if spec.raster is not None:
        for w, h in sorted({(c.width, c.height) for _, c in spec.cameras}):
            check_raster_fits(w, h, spec.raster.supersample, spec.raster.fill)


class FrameStream:
    """The frames of a run on their way: drawn (`render_frame`, in any process), carried over
    (`StrokeCarry`, here, in frame order) and written. `pending` is the queue of tasks the workers
    take from; `handle` takes each task's result. Frames go on in frame order as soon as every
    earlier one is drawn: the carry (the only sequential step) runs beside the workers' drawing,
    and each carried frame's write task goes first in line, so output appears from the start and
    no stage waits for all frames."""

    def __init__(self, spec: RunSpec, scene: Scene, res: RunResult, stage: dict, resume: ResumePlan,
                 progress: Callable[[str, int, int], None] | None):
        self.spec, self.res, self.stage, self.resume, self.progress = spec, res, stage, resume, progress
        out, plan = spec.outputs, spec.plan
        self.frames = [f for f, _ in spec.cameras]
        cams = dict(spec.cameras)
        done_before = resume.done_before
        self.need_lines = lines_needed(spec, resume)
        self.to_write = [f for f in self.need_lines if f not in done_before]
        self.keep_frames = out.gltf and out.gltf_sequence
        self.scene = SceneRef(spec.scene_path, scene.content_hash, spec.lines)
        self.carry = StrokeCarry(plan)
        # A frame that carries nothing over is written where it is drawn (brush paths are made
        # here, in frame order, even one frame at a time).
        self.write_in_task = not self.carry.needed
        self.pending = deque(FrameTask(self.scene, plan, f, cams[f], out if f not in done_before else None,
                                       write=self.write_in_task, keep_frame=self.keep_frames,
                                       raster_threads=spec.raster_threads)
                             for f in self.need_lines)
        self.n_lines = len(self.pending)
        self.drawn: dict[int, Frame | None] = {}  # frames drawn, then carried over, until written
        self.finished: set[int] = set()  # frames whose lines are done or failed
        self.lines_failed: set[int] = set()
        self.ordered: list[int] = []  # frames drawn, in frame order, carried over
        self.n_done = self.n_written = 0
        self.cursor = 0
        #: The first file that could not be written (an OSError naming it): the run stops there.
        self.write_error: OSError | None = None

    def handle(self, r: FrameResult | WriteResult) -> bool:
        """Take one task result; False stops the run (a file that cannot be written, or
        --fail-fast after a failure)."""
        if isinstance(r, WriteResult):
            self.written(r)
        else:
            self.lines_done(r)
        if self.write_error is not None:
            return False
        failed = r.error is not None or (isinstance(r, FrameResult) and r.written is not None
                                         and r.written.error is not None)
        return not (self.spec.fail_fast and failed)

    def write_failed(self, frame: int | None, error: OSError) -> None:
        """A write failed (of `frame`'s files, or of a file of the run): the first one is kept
        and said; the frame counts as failed (its files are removed by the clean-up)."""
        if self.write_error is None:
            self.write_error = error
        if frame is not None:
            self.res.failures.setdefault(frame, f"{error.filename}: {error.strerror}")

    def lines_done(self, r: FrameResult) -> None:
        res = self.res
        self.n_done += 1
        f = r.number
        self.finished.add(f)
        if r.write_error is not None:  # a raster PNG: the run stops, nothing more is carried
            self.write_failed(f, r.write_error.error())
            return
        if r.error is not None:
            res.failures[f] = r.error
            self.lines_failed.add(f)
        else:
            self.drawn[f] = r.frame
            res.ray_tracers.add(r.ray_tracer)
            res.frame_seconds[f] = r.seconds
            res.outputs += r.files
            add_timings(self.stage, r.timings)
        if self.progress:
            self.progress("lines", self.n_done, self.n_lines)
        if r.written is not None:
            self.written(r.written)
        self.advance()

    def advance(self) -> None:
        """Carry over and queue for writing every frame whose earlier frames are all drawn."""
        need, done_before = self.need_lines, self.resume.done_before
        while self.cursor < len(need) and need[self.cursor] in self.finished and self.write_error is None:
            f = need[self.cursor]
            if f in self.lines_failed and self.spec.fail_fast:
                return  # --fail-fast: no frame after a failed one is carried over or written
            self.cursor += 1
            if f not in self.drawn:
                continue
            self.ordered.append(f)
            if self.write_in_task:
                continue  # written by its frame task
            frame = self.drawn[f] = self.carry.step(self.drawn[f])
            for name in ("tracking", "brush paths"):
                if name in frame.timings:
                    self.stage[name].seconds += frame.timings[name]
            if f not in done_before:
                self.pending.appendleft(WriteTask(frame, self.spec.outputs, self.scene))
            elif not self.keep_frames:
                self.drawn.pop(f)

    def written(self, r: WriteResult) -> None:
        res = self.res
        self.n_written += 1
        f = r.number
        if r.write_error is not None:
            self.write_failed(f, r.write_error.error())
        elif r.error is not None:
            res.failures[f] = r.error
        else:
            res.outputs += r.files
            res.frames_ok.append(f)
            res.frame_seconds[f] = res.frame_seconds.get(f, 0.0) + r.seconds
            add_timings(self.stage, r.timings)
        if not self.keep_frames:
            self.drawn.pop(f, None)
        if self.progress:
            # Frames whose lines failed are never written: they leave the total.
            failed = len(self.lines_failed.intersection(self.to_write))
            self.progress("write", self.n_written, len(self.to_write) - failed)

    def write_before_failure(self) -> None:
        """After a stop at a failure (--fail-fast): the frames before it whose lines are done are
        carried over (advance) and written, here, in frame order (their write tasks were left in
        line)."""
        order = {f: k for k, f in enumerate(self.frames)}
        stop_at = min((order[f] for f in self.res.failures), default=len(self.frames))
        rest = sorted((t for t in self.pending if isinstance(t, WriteTask) and order[t.frame.number] < stop_at),
                      key=lambda t: order[t.frame.number])
        self.pending.clear()
        for task in rest:
            self.written(write_task(task))
            if self.write_error is not None:
                break

    def enter_written(self) -> None:
        """Enter the frames written since the start in the run manifest (see ResumePlan)."""
        resume, out = self.resume, self.spec.outputs
        done = resume.enter_later.intersection(self.res.frames_ok)
        resume.entries.update((f, resume.manifest["frames"][f]) for f in done)
        stale = []
        if self.spec.plan.carried and self.lines_failed:
            # The frames after a frame whose lines failed were carried over without it: they are
            # not what a run with it gives, so they leave the manifest and a resume renders
            # them again (their digests chain through the failed frame).
            first = self.frames.index(min(self.lines_failed, key=self.frames.index))
            stale = [f for f in self.frames[first + 1:] if resume.entries.pop(f, None) is not None]
        if done or stale:
            write_run_manifest(out.out_dir, resume.manifest, resume.entries)


def write_sequence_glb(spec: RunSpec, scene: Scene, res: RunResult, stage: dict, stream: FrameStream) -> None:
    """sequence.glb (--gltf-sequence): every carried frame of the run, one node per frame."""
    out = spec.outputs
    if not (out.gltf and out.gltf_sequence and stream.ordered):
        return
    t = time.perf_counter()
    frames = [stream.drawn[f] for f in stream.ordered]
    seq = [f.styled for f in frames]
    depth_at = surface_depth(out, stream.scene)
    if depth_at is not None and any(f.time is not None for f in frames):
        # Each frame's ribbons lie on the scene as posed in that frame: the depth function of the
        # frame whose camera asks (each frame's strokes hold their own camera object).
        base = stream.scene.renderer()
        by_camera = {id(f.strokes.camera): surface_depth(out, None, base.at(f.time, f.animation).occluder)
                     for f in frames}

        def depth_at(camera, pixels):
            return by_camera[id(camera)](camera, pixels)
    res.outputs.append(str(atomic_write_bytes(out.out_dir / "sequence.glb",
                                              glb_for_sequence(seq, out.gltf_options, depth_at))))
    stage["ribbons + glTF"].seconds += time.perf_counter() - t


def _finish(res: RunResult, t_start: float) -> RunResult:
    res.frames_ok.sort()
    res.outputs.sort()
    res.wall_seconds = time.perf_counter() - t_start
    return res
