"""`strokekit render SCENE`: lines (and optional ribbons and masks) for every frame of a camera path."""

from __future__ import annotations

import json
import os
import time
from dataclasses import replace
from pathlib import Path

import click
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

from strokekit.camera.frames import parse_frames
from strokekit.camera.paths import load_camera_path, orbit_path
from strokekit.camera.view import MAX_IMAGE_PX, MAX_PATH_FRAMES, CameraPath
from strokekit.errors import UsageError
from strokekit.fileio import atomic_write_text, check_output_file, check_output_folder, check_pattern
from strokekit.options import (
    DEFAULT_KINDS,
    MAX_DOUBLED_PX,
    MAX_PERIOD_PX,
    MIN_BISECTION_TOL_PX,
    MIN_SAMPLE_SPACING_PX,
    QUALITY_PRESETS,
    LineOptions,
)
from strokekit.raster.hits import KernelWarmup
from strokekit.run.report import run_report
from strokekit.run.request import RenderRequest
from strokekit.run.runner import check_files_apart, run
from strokekit.run.spec import OutputOptions, RunInterrupted, RunResult, RunSpec, RunWriteError
from strokekit.run.workers import MAX_WORKERS, SceneRef, make_executor
from strokekit.scene.load import load_scene
from strokekit.tracking.options import TrackingOptions

from ..common import FINITE, FiniteFloatRange, is_interactive, say_warnings, split_list
from .render_options import (
    dashes_from,
    exr_options_from,
    gltf_options_from,
    occlusion_from,
    path_options_from,
    raster_options_from,
    render_extra_options,
    strokes_mode,
    tracking_options_from,
    wants_raster,
)

#: Options that only mean something beside another: (options, what they need, when it is there).
_NEEDS = (
    (("elevation", "fov", "up"), "--orbit (they shape the orbit; a --camera file has its own)",
     lambda cam, svg, x: not cam),
    (("max_growth", "min_carry"), "--coherence seed", lambda cam, svg, x: x.get("coherence_method") == "seed"
     and not x.get("no_coherence") and x.get("strokes_mode") != "brush"),
    (("fill_pattern", "fill_period"), "--fill", lambda cam, svg, x: x.get("fill")),
    (("exr_layers", "exr_codec"), "--exr", lambda cam, svg, x: x.get("exr")),
    (("path_merge",), "brush paths (--strokes brush, the default for a sequence)",
     lambda cam, svg, x: x.get("strokes_mode") != "lines"),
    (("band_polygons",), "the SVG (they are a layer of it; not --no-svg)", lambda cam, svg, x: svg),
    (("ribbon_width", "taper", "brush", "alpha_mode", "ribbon_space"), "--gltf or --gltf-sequence",
     lambda cam, svg, x: x.get("gltf") or x.get("gltf_sequence")),
    (("shading", "light", "light_space", "gooch", "no_shade", "supersample", "edge_supersample"),
     "a raster output (--bands, --masks, --fill, --objectid, --depth, --band-polygons or --exr)",
     lambda cam, svg, x: wants_raster(x) or x.get("exr")),
    (("suggestive_threshold", "suggestive_kr_threshold"), "suggestive in --kinds",
     lambda cam, svg, x: "suggestive" in (split_list(x.get("kinds"), "--kinds") or ())),
    (("decimals",), "the SVG (its coordinates; not --no-svg)", lambda cam, svg, x: svg),
    (("workers",), "no --scheduler (a dask cluster's workers draw the frames)", lambda cam, svg, x: not x.get("scheduler")),
)


def _check_option_pairs(camera_file, svg: bool, extra: dict) -> None:
    """A usage error for an option given on the command line that the run would ignore, or two
    that contradict each other (one line, exit 2): a typo'd intent is said, not dropped."""
    ctx = click.get_current_context()

    def given(name: str) -> bool:
        return ctx.get_parameter_source(name) == click.core.ParameterSource.COMMANDLINE

    if extra.get("gltf_sequence") and extra.get("gltf") is False and given("gltf"):
        raise UsageError("--gltf-sequence writes glTF: it cannot go with --no-gltf")
    if given("coherence_method") and extra.get("no_coherence") and extra.get("coherence_method") != "none":
        raise UsageError(f"--coherence {extra.get('coherence_method')} and --no-coherence contradict each other")
    if extra.get("strokes_mode") == "brush" and given("coherence_method") and extra.get("coherence_method") != "none":
        raise UsageError(f"--coherence {extra.get('coherence_method')} tracks lines: it goes with --strokes lines "
                         "(brush paths carry their own ids; --no-coherence makes them afresh every frame)")
    for names, need, present in _NEEDS:
        said = [n for n in names if given(n)]
        if said and not present(camera_file, svg, extra):
            flags = ", ".join("--" + n.replace("_", "-") for n in said)
            raise UsageError(f"{flags} {'needs' if len(said) == 1 else 'need'} {need}")


@click.command("render", short_help="Line drawings for every frame of a camera path.")
@click.argument("scene", type=click.Path())
@click.option("--camera", "camera_file", type=click.Path(), default=None,
              help="Camera path JSON (format: README, camera path files), or a glTF/GLB file with a camera node "
                   "(its animation, if any, sampled at 24 fps).")
@click.option("--orbit", type=click.IntRange(1, MAX_PATH_FRAMES), default=None,
              help="Orbit the scene in N frames (instead of --camera; at most as many as a camera file may have).")
@click.option("--elevation", type=FiniteFloatRange(-90, 90), default=15.0, show_default=True, help="Orbit elevation, degrees.")
@click.option("--fov", type=FiniteFloatRange(0.1, 179.9), default=40.0, show_default=True, help="Orbit field of view, degrees.")
@click.option("--up", type=click.Choice(["y", "z"]), default="y", show_default=True, help="Orbit up axis.")
@click.option("--size", default=None, help="Image size WxH (overrides the camera file), e.g. 1024x1024.")
@click.option("--frames", "frame_spec", default=None, help="Frames to render, 1-based: 1-24 or 1,3,5-9 (default all).")
@click.option("--out", "out_dir", type=click.Path(), default="out", show_default=True,
              help="Folder for the frame files (created if missing).")
@click.option("--pattern", default="frame_{frame:04d}", show_default=True, help="File name pattern (no extension).")
@click.option("--kinds", default=", ".join(DEFAULT_KINDS), show_default=True,
              help="Line kinds, comma-separated: silhouette, border, crease, material, nonmanifold, smooth_contour, "
                   "suggestive, intersection.")
@click.option("--contours", type=click.Choice(["mesh", "smooth"]), default="mesh", show_default=True,
              help="Mesh contours (silhouette edges) or smooth interpolated contours.")
@click.option("--quality", type=click.Choice(list(QUALITY_PRESETS)), default="default", show_default=True,
              help="Accuracy preset: draft (fast), default, exact (slow reference).")
@click.option("--crease-angle", type=FINITE, default=None, help="Crease threshold in degrees [60].")
@click.option("--whole-edge", "whole_edge", type=FINITE, default=None,
              help="Edges shorter than N px get one visibility ray and are drawn whole or not at all "
                   "(draft: 12; default 0: every edge is split where its visibility changes) (overrides --quality).")
@click.option("--sample-spacing", type=FINITE, default=None,
              help=f"Visibility samples every N px, at least {MIN_SAMPLE_SPACING_PX:g} (overrides --quality; a spacing "
                   "whose samples would not fit in this machine's memory is refused before any work).")
@click.option("--bisection-tol", type=FINITE, default=None,
              help=f"Visibility change located to N px, at least {MIN_BISECTION_TOL_PX:g} (overrides --quality).")
@click.option("--split-angle", type=FINITE, default=None, help="Split strokes at turns sharper than N degrees [90].")
@click.option("--max-length", type=FINITE, default=None,
              help="Split lines longer than N px, at their points (a piece may pass N by one segment) [no limit]; "
                   "brush paths are drawn over the lines, whole.")
@click.option("--min-length", type=FINITE, default=None,
              help="Drop lines shorter than N px [0]; brush paths are drawn over the lines left.")
@click.option("--simplify", "simplify_tol", type=FINITE, default=None, help="Simplify strokes within N px (Douglas-Peucker) [0: off].")
@click.option("--doubled", type=FINITE, default=None,
              help="Drop parts of contour lines running beside a longer one within N px (mesh-contour "
                   f"shingles) [0: every visible contour edge is kept; brush paths share one stroke among them; "
                   f"at most {MAX_DOUBLED_PX:g}].")
@click.option("--drop-retraced/--keep-retraced", "drop_retraced", default=None,
              help="Drop strokes that retrace a longer stroke of their kind within 0.5 px (zig-zag spurs, "
                   "coincident copies) [default: drop; draft: keep].")
@click.option("--period", type=FINITE, default=None,
              help=f"Texture period P in px for the parametrization u [30; at most {MAX_PERIOD_PX:g}].")
@click.option("--suggestive-threshold", type=FINITE, default=None,
              help="Suggestive contours: minimum derivative of radial curvature, scale-free [50].")
@click.option("--suggestive-kr-threshold", type=FINITE, default=None,
              help="Suggestive contours: skip faces whose radial curvature stays below this / scene radius [0].")
@click.option("--svg/--no-svg", default=True, show_default=True, help="Write frame_NNNN.svg (the drawing).")
@click.option("--json/--no-json", "write_json", default=True, show_default=True,
              help="Write frame_NNNN.json (strokes with ids, kinds and u, for tools).")
@click.option("--decimals", type=click.IntRange(0, 8), default=2, show_default=True, help="SVG coordinate decimals.")
@click.option("--stroke-width", type=FINITE, default=1.5, show_default=True, help="SVG stroke width in px.")
@click.option("--workers", type=click.IntRange(1, MAX_WORKERS), default=None,
              help="Processes rendering frames: this one and N-1 started beside it (default: the machine's "
                   "cores for 8 frames or more, 16 with a raster output, else 1; at most 4 per core, 8 on smaller "
                   "machines).")
@click.option("--scheduler", default=None, help="dask.distributed scheduler address, e.g. tcp://host:8786.")
@click.option("--skip-existing", is_flag=True, help="Resume: do not rewrite frames whose files all exist and were rendered from the same scene, options "
                   "and camera (OUT/.strokekit-run.json says so); frames of another scene or other options "
                   "are a usage error.")
@click.option("--fail-fast", is_flag=True,
              help="Stop at the first failed frame (frames already written stay; the run streams them out in order).")
@click.option("--quiet", "-q", is_flag=True, help="No progress and no summary.")
@click.option("--report", "report_path", type=click.Path(), default=None, help="Write a JSON run report.")
@click.option("--explain", is_flag=True, help="List the stages that ran, why, and their time.")
@render_extra_options
def command(scene, **o):
    """Render the visible feature lines of SCENE for every frame of a camera path (--camera, or
    --orbit N; without either, a 48-frame orbit).

    Writes OUT/frame_0001.svg and .json (and .glb, band PNGs when asked) per frame. Exit codes: 0 done,
    1 bad input or unwritable output, 2 usage error, 3 some frames failed (the others are written),
    130 interrupted by Ctrl-C (the frames written so far stay, whole; --report lists them)."""
    size = _check_usage(o)
    lines = _line_options(o)
    path = _camera_file_path(o, size)
    frames = parse_frames(o["frame_spec"], len(path) if path is not None else o["orbit"] or 48)
    # A pool pays off from 8 frames on; with a raster output from 16 (each process also starts
    # numba for the raster kernels: about a second of CPU; README "Batch at scale").
    workers = o["workers"] or ((os.cpu_count() or 1) if len(frames) >= (16 if wants_raster(o) else 8) else 1)
    workers = min(workers, len(frames))
    # The workers start before this process loads the scene: their start-up (imports, scene,
    # BVH: about a second) overlaps ours.
    if not Path(scene).is_file():
        load_scene(scene)  # its one-line error (missing file, a folder), before any worker starts
    notice = None if o["quiet"] else (lambda line: click.echo(f"strokekit: {line}", err=True))
    kernels = None
    if wants_raster(o) and not o["scheduler"]:  # (on a dask cluster the workers draw every frame)
        raster_options_from(o, o["quality"])  # (its usage errors first)
        # The raster kernels load (or compile, on a machine's first run) beside the scene's load.
        kernels = KernelWarmup(notice)
    t_start = time.perf_counter()
    pool = make_executor(workers, o["scheduler"], warm=SceneRef(str(scene), "", lines))
    spec = None
    write_error: RunWriteError | None = None
    try:
        t_load = time.perf_counter()
        s = load_scene(scene)
        say_warnings(s)
        load_seconds = time.perf_counter() - t_load
        if path is None:
            width, height = size or (1024, 1024)
            path = orbit_path(s.center, s.radius, o["orbit"] or 48, elevation=o["elevation"], fov_y=o["fov"],
                              width=width, height=height, up_axis=o["up"])
        spec = _run_spec(scene, o, lines, path, frames, workers)
        check_files_apart(spec, also_written=[("--report", o["report_path"])])
        try:
            res = _run_with_progress(spec, o["quiet"], dict(workers=pool, scene=s, load_seconds=load_seconds,
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
                       outputs=OutputOptions(out_dir=Path(o["out_dir"]), pattern=o["pattern"]),
                       workers=workers, scheduler=o["scheduler"])
    finally:
        pool.close()
    if o["report_path"]:
        try:
            atomic_write_text(o["report_path"], json.dumps(run_report(spec, res), indent=1) + "\n")
        except OSError:
            if write_error is None:
                raise
            # (the disk that was full for a frame is likely full for the report too: the first
            # error is the one to say)
    if write_error is not None:
        raise write_error  # one line naming the file, exit 1 (cli/main.py)
    _say_result(o, spec, res, len(frames))
    return res.exit_code


def _check_usage(o: dict) -> tuple[int, int] | None:
    """Usage errors before any work (one line, exit 2); outputs that cannot be written are said now,
    not after every frame has been rendered. Returns --size as (width, height), or None."""
    if o["camera_file"] and o["orbit"]:
        raise UsageError("give either --camera or --orbit, not both")
    _check_option_pairs(o["camera_file"], o["svg"], o)
    if not (o["svg"] or o["write_json"] or o.get("gltf") or o.get("gltf_sequence") or o.get("bands")
            or o.get("exr") or o.get("lines_png")):
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
    out_dir, report_path = o["out_dir"], o["report_path"]
    if not str(out_dir).strip():
        raise UsageError("--out needs a folder name (use --out . for the current folder)")
    check_output_folder(out_dir)
    if report_path is not None:
        if not report_path.strip():
            raise UsageError("--report needs a file name")
        check_output_file(report_path)
        if Path(report_path).resolve() == Path(out_dir).resolve():
            raise UsageError(f"--report {report_path} is the --out folder: name a file for the report")
    return size


def _line_options(o: dict) -> LineOptions:
    return LineOptions.preset(o["quality"], kinds=split_list(o["kinds"], "--kinds"), contours=o["contours"],
                              crease_angle_deg=o["crease_angle"], whole_edge_px=o["whole_edge"],
                              sample_spacing_px=o["sample_spacing"], bisection_tol_px=o["bisection_tol"],
                              split_angle_deg=o["split_angle"], max_length_px=o["max_length"],
                              min_length_px=o["min_length"], simplify_tol_px=o["simplify_tol"],
                              doubled_px=o["doubled"], merge_overlaps=o["drop_retraced"], period_px=o["period"],
                              suggestive_derivative_threshold=o["suggestive_threshold"],
                              suggestive_kr_threshold=o["suggestive_kr_threshold"], occlusion=occlusion_from(o))


def _camera_file_path(o: dict, size: tuple[int, int] | None) -> CameraPath | None:
    """The --camera file's path, resized by --size; None for an orbit (made once the scene is loaded)."""
    if not o["camera_file"]:
        return None
    path = load_camera_path(o["camera_file"])
    if size:
        path = CameraPath(cameras=tuple(replace(c, width=size[0], height=size[1]) for c in path.cameras),
                          fps=path.fps, source=path.source)
    return path


def _run_spec(scene, o: dict, lines: LineOptions, path: CameraPath, frames: list[int], workers: int) -> RunSpec:
    gltf_options = gltf_options_from(o, lines, path.fps)
    outputs = OutputOptions(out_dir=Path(o["out_dir"]), pattern=o["pattern"], svg=o["svg"], json=o["write_json"],
                            decimals=o["decimals"], stroke_width_px=o["stroke_width"],
                            gltf=gltf_options is not None, gltf_sequence=bool(o.get("gltf_sequence")),
                            gltf_options=gltf_options,
                            hidden_dashes=dashes_from(o, lines.occlusion), dash_paths=o["dash_paths"],
                            exr=exr_options_from(o, o["stroke_width"]), lines_png=o["lines_png"])
    ctx = click.get_current_context()
    given = ctx.get_parameter_source("coherence_method") == click.core.ParameterSource.COMMANDLINE
    mode = strokes_mode(o, len(frames), given)
    if mode != "brush" and ctx.get_parameter_source("path_merge") == click.core.ParameterSource.COMMANDLINE:
        raise UsageError("--path-merge needs brush paths (--strokes brush; one frame, --no-coherence or a --coherence "
                         "method draw the lines by default)")
    tracking = tracking_options_from(o, 2, "lines")
    paths = path_options_from(o, "brush")
    request = RenderRequest(lines=lines, strokes=mode, coherence="none" if o["no_coherence"] else o["coherence_method"] if given else None,
                            tracking=tracking or TrackingOptions(), paths=paths,
                            raster=raster_options_from(o, o["quality"]))
    return RunSpec(scene_path=str(scene), cameras=tuple(path.select(frames)), request=request, outputs=outputs,
                   workers=workers,
                   scheduler=o["scheduler"], skip_existing=o["skip_existing"], fail_fast=o["fail_fast"],
                   camera_source=str(o["camera_file"]) if o["camera_file"] else path.source)


def _say_result(o: dict, spec: RunSpec, res: RunResult, n_frames: int) -> None:
    out_dir, report_path = Path(o["out_dir"]), o["report_path"]
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
            msg += f"; every error in {report_path}" if report_path else "; --report lists every error"
        click.echo(msg, err=True)
    elif not o["quiet"]:
        msg = f"wrote {len(res.frames_ok)} frame(s) to {out_dir}/ in {res.wall_seconds:.2f} s"
        if res.frames_skipped:
            msg += f" ({len(res.frames_skipped)} already there, skipped)"
        click.echo(msg, err=True)


#: Stages --explain shows no time a frame for: they run once a run (or once per process).
ONCE_A_RUN = ("load scene + BVH", "raster kernels")


def _run_with_progress(spec: RunSpec, quiet: bool, run_args: dict):
    if not is_interactive(quiet):
        return run(spec, **run_args)

    with Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                  TextColumn("{task.fields[fps]:.1f} frames/s"), TimeRemainingColumn(), transient=True) as prog:
        tasks = {}
        # Rates from the run's start: a phase's first report comes when its first frame is done,
        # so timing from there missed that frame's time (0 frames/s, then a burst).
        t0 = time.perf_counter()

        def cb(phase, done, total):
            if phase not in tasks:
                tasks[phase] = prog.add_task(phase, total=total, fps=0.0)
            dt = time.perf_counter() - t0
            prog.update(tasks[phase], completed=done, total=total, fps=done / dt if dt > 0 else 0.0)

        return run(spec, progress=cb, **run_args)
