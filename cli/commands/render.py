"""`strokekit render SCENE`: lines (and optional ribbons and masks) for every frame of a camera path."""

from __future__ import annotations

import json
import time
from dataclasses import replace
from pathlib import Path

import click

from strokekit.camera.limits import MAX_IMAGE_PX
from strokekit.errors import UsageError
from strokekit.extras import need
from strokekit.fileio import (
    atomic_write_text,
    check_not_an_input,
    check_output_file,
    check_output_folder,
    check_pattern,
)
from strokekit.run.request import RenderRequest
from strokekit.run.spec import OutputOptions, RunInterrupted, RunResult, RunSpec, RunWriteError

from ..common import StatusLine, hint_up_axis, is_interactive, process_started, say_warnings
from ..flags import options_of, said
from .render_options import RENDER_CLASSES, check_needs, outputs_from, request_from, wants_raster


def _check_option_pairs(x: dict, given: dict) -> None:
    """A usage error for two options given on the command line that contradict each other, or
    one that the run would ignore (NEEDS; one line, exit 2): a typo'd intent is said, not dropped."""
    if x["gltf_sequence"] and x["gltf"] is False and "gltf" in given:
        raise UsageError("--gltf-sequence writes glTF: it cannot go with --no-gltf")
    if "coherence" in given and x["no_coherence"] and x["coherence"] != "none":
        raise UsageError(f"--coherence {x['coherence']} and --no-coherence contradict each other")
    if x["strokes"] == "brush" and "coherence" in given and x["coherence"] != "none":
        raise UsageError(f"--coherence {x['coherence']} tracks lines: it goes with --strokes lines "
                         "(brush paths carry their own ids; --no-coherence makes them afresh every frame)")
    check_needs(x, given)


@click.command("render", short_help="Line drawings for every frame of a camera path.")
@click.argument("scene", type=click.Path())
@options_of(*RENDER_CLASSES)
def command(scene, **o):
    """Render the visible feature lines of SCENE for every frame of a camera path (--camera, or
    --orbit N; without either, a 48-frame orbit).

    Writes OUT/frame_0001.svg and .json (and .glb, band PNGs when asked) per frame. Exit codes: 0 done,
    1 bad input or unwritable output, 2 usage error, 3 some frames failed (the others are written),
    130 interrupted by Ctrl-C (the frames written so far stay, whole; --report lists them)."""
    from strokekit.camera.frames import parse_frames

    t_start = process_started()  # (the summary and the report count from here)
    given = said(o)
    size = _check_usage(scene, o, given)
    if o["scheduler"]:
        need("distributed", "--scheduler")
    request = request_from(o, given)
    path = _camera_file_path(o, size)
    frames = parse_frames(o["frames"], len(path) if path is not None else o["orbit"] or 48)
    for name in ("path_merge", "path_heal", "path_bridge"):
        if name in given and request.plan(len(frames)).paths is None:
            raise UsageError(f"--{name.replace('_', '-')} needs brush paths (--strokes brush; one frame, "
                             "--no-coherence or a --coherence method draw the lines by default)")
    # What the render waits for, said from its first second on a terminal until the progress bar:
    # the run's modules (open3d, trimesh, numba behind them) load from here on.
    status = StatusLine(is_interactive(o["quiet"]), f"loading {scene}")
    try:
        return _render(scene, o, given, size, request, path, frames, status, t_start)
    finally:
        status.stop()


def _render(scene: str, o: dict, given: dict, size, request: RenderRequest, path, frames, status: StatusLine,
            t_start: float) -> int:
    """The run of a render command whose options are checked: workers, the scene, the run, the
    report and the summary."""
    from strokekit.camera.paths import orbit_path
    from strokekit.run.kernels import RunKernels
    from strokekit.run.report import run_report
    from strokekit.run.runner import check_files_apart
    from strokekit.run.spec import pool_for
    from strokekit.run.workers import SceneRef, make_executor
    from strokekit.scene.load import load_scene

    lines = request.lines
    workers, kind = pool_for(len(frames), wants_raster(o), o["workers"], o["worker_kind"])
    workers = min(workers, len(frames))
    # The workers start before this process loads the scene: their start-up (imports, scene,
    # BVH: about a second) overlaps ours.
    if not Path(scene).is_file():
        load_scene(scene)  # its one-line error (missing file, a folder), before any worker starts

    def say_wait(line: str) -> None:  # (a wait the user may wonder about: the kernels' first compile)
        click.echo(f"strokekit: {line}", err=True)
        status.say(line)

    notice = None if o["quiet"] else say_wait
    # The kernels load (or compile, on a machine's first run): the raster ones beside the scene's
    # load (not beside a dask cluster: there the workers draw every frame).
    kernels = RunKernels(notice, raster=wants_raster(o) and not o["scheduler"])
    pool = make_executor(workers, o["scheduler"], warm=SceneRef(str(scene), "", lines), kind=kind)
    spec = None
    write_error: RunWriteError | None = None
    try:
        t_load = time.perf_counter()
        s = load_scene(scene)
        say_warnings(s)
        load_seconds = time.perf_counter() - t_load
        status.say("building the BVH" if not o["scheduler"] else f"sending the frames to {o['scheduler']}")
        if path is None:
            if not o["quiet"]:
                hint_up_axis(s, scene, "up" in given)
            width, height = size or (1024, 1024)
            center, radius, _ = s.framing(request.animation)  # (over the whole animation)
            path = orbit_path(center, radius, o["orbit"] or 48, elevation=o["elevation"], fov_y=o["fov"],
                              width=width, height=height, up_axis=o["up"])
        spec = RunSpec(scene_path=str(scene), cameras=tuple(path.select(frames)), request=request,
                       outputs=outputs_from(o, given, lines.occlusion, path.fps), workers=workers,
                       worker_kind=kind,
                       scheduler=o["scheduler"], skip_existing=o["skip_existing"], fail_fast=o["fail_fast"],
                       camera_source=str(o["camera"]) if o["camera"] else path.source, fps=path.fps)
        check_files_apart(spec, also_written=[("--report", o["report"])])
        try:
            res = _run_with_progress(spec, o["quiet"], status, dict(workers=pool, scene=s, load_seconds=load_seconds,
                                                                    started_at=t_start, notice=notice, kernels=kernels))
        except RunInterrupted as e:  # Ctrl-C: workers stopped, temporaries removed by the run
            res = e.result
        except RunWriteError as e:  # a file could not be written: the run stopped, frames whole or gone
            res, write_error = e.result, e
    except KeyboardInterrupt:
        if spec is not None:
            raise
        # Ctrl-C while the scene loads, before the run: nothing written; the report still says so.
        res = RunResult(interrupted=True, wall_seconds=time.perf_counter() - t_start)
        spec = RunSpec(scene_path=str(scene), cameras=tuple(path.select(frames)) if path is not None else (),
                       request=RenderRequest(lines=lines),
                       outputs=OutputOptions(out_dir=Path(o["out"]), pattern=o["pattern"]),
                       workers=workers, scheduler=o["scheduler"])
    finally:
        status.stop()  # (before the report and the summary: the status line is gone)
        pool.close()
    if o["report"]:
        try:
            atomic_write_text(o["report"], json.dumps(run_report(spec, res), indent=1) + "\n")
        except OSError:
            if write_error is None:
                raise
            # (the disk that was full for a frame is likely full for the report too: the first
            # error is the one to say)
    if write_error is not None:
        raise write_error  # one line naming the file, exit 1 (cli/main.py)
    _say_result(o, spec, res, len(frames))
    return res.exit_code


def _check_usage(scene: str, o: dict, given: dict) -> tuple[int, int] | None:
    """Usage errors before any work (one line, exit 2); outputs that cannot be written, or that
    would overwrite an input, are said now, not after every frame has been rendered. Returns
    --size as (width, height), or None."""
    if o["camera"] and o["orbit"]:
        raise UsageError("give either --camera or --orbit, not both")
    _check_option_pairs(o, given)
    if not (o["svg"] or o["json"] or o["gltf"] or o["gltf_sequence"] or o["bands"] or o["exr"] or o["lines_png"]):
        raise UsageError("nothing to write: every output is turned off")
    check_pattern(o["pattern"])
    size = None
    if o["size"]:
        try:
            width, height = (int(x) for x in o["size"].lower().split("x"))
        except Exception:
            raise UsageError(f"bad --size {o['size']!r}: use WxH, e.g. 1024x768") from None
        if not (0 < width <= MAX_IMAGE_PX and 0 < height <= MAX_IMAGE_PX):
            raise UsageError(f"bad --size {o['size']!r}: width and height must be positive and at most "
                             f"{MAX_IMAGE_PX} px (as in camera files)")
        size = (width, height)
    if not (0 < o["stroke_width"] <= MAX_IMAGE_PX):
        raise UsageError(f"--stroke-width must be a number > 0 px and at most {MAX_IMAGE_PX} px (the largest image "
                         f"side), got {o['stroke_width']:g}")
    out_dir, report_path = o["out"], o["report"]
    if not str(out_dir).strip():
        raise UsageError("--out needs a folder name (use --out . for the current folder)")
    check_output_folder(out_dir)
    if report_path is not None:
        if not report_path.strip():
            raise UsageError("--report needs a file name")
        check_output_file(report_path)
        if Path(report_path).resolve() == Path(out_dir).resolve():
            raise UsageError(f"--report {report_path} is the --out folder: name a file for the report")
        check_not_an_input("--report", report_path, [("scene", scene), ("camera file", o["camera"])])
    return size


def _camera_file_path(o: dict, size: tuple[int, int] | None):
    """The --camera file's CameraPath, resized by --size; None for an orbit (made once the scene
    is loaded)."""
    if not o["camera"]:
        return None
    from strokekit.camera.paths import load_camera_path
    from strokekit.camera.view import CameraPath

    path = load_camera_path(o["camera"])
    if size:
        path = CameraPath(cameras=tuple(replace(c, width=size[0], height=size[1]) for c in path.cameras),
                          fps=path.fps, source=path.source)
    return path


def _say_result(o: dict, spec: RunSpec, res: RunResult, n_frames: int) -> None:
    out_dir, report_path = Path(o["out"]), o["report"]
    if res.interrupted:
        # Said even with --quiet: it explains the exit code.
        msg = f"strokekit: interrupted: {len(res.frames_ok)} of {n_frames} frame(s) written to {out_dir}/"
        click.echo(msg + (f"; report in {report_path}" if report_path else ""), err=True)
        return
    if o["explain"]:
        click.echo("stages (time summed over all frames and processes):")
        n = max(len(res.frames_ok), 1)
        for st in res.stages:
            mark = "ran " if st.ran else "skip"
            timed = st.ran and (st.seconds > 0 or not st.name.startswith(" "))
            t = f"{st.seconds * 1e3:9.1f} ms" if timed else " " * 12
            per = f"{st.seconds * 1e3 / n:7.1f} ms/frame" if timed and st.name.strip() not in ONCE_A_RUN else " " * 16
            click.echo(f"  [{mark}] {st.name:<26} {t} {per}  {st.why}")
    if res.failures:
        # One line, even with --quiet (it explains the exit code): the first error, then what
        # became of the run; every error is in the --report.
        first = min(res.failures)
        msg = f"strokekit: error: {res.failures[first]}; {len(res.failures)} of {n_frames} frame(s) failed, " \
              f"{len(res.frames_ok)} written to {out_dir}/"
        if res.frames_skipped:
            msg += f" ({len(res.frames_skipped)} already there, skipped)"
        not_run = len(spec.cameras) - len(set(res.frames_ok) | set(res.frames_skipped) | set(res.failures))
        if spec.fail_fast and not_run:
            msg += f"; stopped at frame {first} (--fail-fast), {not_run} not run"
        if len(res.failures) > 1:
            msg += f"; every error in {report_path}" if report_path else "; give --report FILE to list every error"
        click.echo(msg, err=True)
    elif not o["quiet"]:
        msg = f"wrote {len(res.frames_ok)} frame(s) to {out_dir}/ in {res.wall_seconds:.2f} s"
        if res.frames_skipped:
            msg += f" ({len(res.frames_skipped)} already there, skipped)"
        click.echo(msg, err=True)


#: Stages --explain shows no time a frame for: they run once a run (or once per process).
ONCE_A_RUN = ("load scene + BVH", "raster kernels")


def _run_with_progress(spec: RunSpec, quiet: bool, status: StatusLine, run_args: dict):
    """run(spec) with a progress bar on an interactive terminal, started (in place of the status
    line) when the frames start."""
    from strokekit.run.runner import run

    if not is_interactive(quiet):
        return run(spec, **run_args)
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

    prog = Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                    TextColumn("{task.fields[fps]:.1f} frames/s"), TimeRemainingColumn(), transient=True)
    tasks = {}
    # Rates from the frames' start: a phase's first frame takes as long as the others.
    t0 = time.perf_counter()

    def cb(phase, done, total):
        nonlocal t0
        if not tasks:
            status.stop()
            prog.start()
            t0 = time.perf_counter()
        if phase not in tasks:
            tasks[phase] = prog.add_task(phase, total=total, fps=0.0)
        dt = time.perf_counter() - t0
        prog.update(tasks[phase], completed=done, total=total, fps=done / dt if dt > 0 else 0.0)

    try:
        return run(spec, progress=cb, **run_args)
    finally:
        prog.stop()
