"""`strokekit bench`: what accuracy costs in time."""

from __future__ import annotations

import json

import click

from strokekit.camera.limits import MAX_PATH_FRAMES
from strokekit.errors import UsageError
from strokekit.extras import need
from strokekit.fileio import check_not_an_input, check_output_file

from ..common import is_interactive, say_warnings


@click.command("bench", short_help="What accuracy costs in time: presets and a sweep.")
@click.argument("scene_path", metavar="SCENE", type=click.Path())
@click.option("--camera", "camera_path", type=click.Path(), default=None,
              help="Camera path JSON (format: docs/camera-files.md); default: an orbit around the scene.")
@click.option("--frames", type=click.IntRange(1, MAX_PATH_FRAMES), default=8, show_default=True,
              help="Orbit frames, or the first N frames of --camera.")
@click.option("--repeats", type=click.IntRange(1, 1000), default=3, show_default=True,
              help="Timed passes; the median is reported.")
@click.option("--sweep", default=None,
              help="Comma-separated values of sample_spacing_px to sweep (default 0.5,1,2,4,8,16).")
@click.option("--raster-frames", type=click.IntRange(0, MAX_PATH_FRAMES), default=2, show_default=True,
              help="Frames for the raster section (IoU vs Embree rays at supersample 4); 0 skips it.")
@click.option("--plot", "plot_path", type=click.Path(), default=None,
              help="Write accuracy against time as a PNG (one curve per knob).")
@click.option("--json", "as_json", is_flag=True, help="Print the results as JSON instead of a table.")
def command(scene_path, camera_path, frames, repeats, sweep, raster_frames, plot_path, as_json):
    """Time every --quality preset and a sweep of the sample spacing on SCENE, with precision and
    recall at 0.5/1/2 px against the `exact` preset, and the raster pass (the z-buffer) at
    supersample 1, 2, 4 and at render's default (1, edge pixels resampled 4 x 4), and that default
    cast with Embree rays, with their IoU against Embree rays at supersample 4."""
    from strokekit.camera.paths import load_camera_path
    from strokekit.metrics.bench import DEFAULT_SWEEP, default_cameras, format_table, plot_bench, result_json, run_bench
    from strokekit.scene.load import load_scene

    values = DEFAULT_SWEEP
    if sweep:
        try:
            values = tuple(float(v) for v in sweep.split(",") if v.strip())
        except ValueError:
            raise UsageError(f"--sweep must be comma-separated numbers, got {sweep!r}") from None
        if not values or min(values) <= 0:
            raise UsageError("--sweep values must be > 0")
    if plot_path is not None:
        need("matplotlib", "--plot")  # (said now, not after a minute of timing)
        check_output_file(plot_path)
        check_not_an_input("--plot", plot_path, [("scene", scene_path), ("camera file", camera_path)])
    scene = load_scene(scene_path)
    say_warnings(scene)
    if camera_path:
        cams = list(load_camera_path(camera_path).cameras)[:frames]
    else:
        cams = default_cameras(scene, frames)
    # Progress lines on a terminal only: piped, the table (or JSON) on stdout is the whole output.
    log = (lambda m: click.echo(m, err=True)) if is_interactive(as_json) else None
    result = run_bench(scene, cams, repeats=repeats, sweep=values, raster_frames=raster_frames, log=log)
    if plot_path:
        plot_bench(result, plot_path)
    if as_json:
        click.echo(json.dumps(result_json(result), indent=1))
    else:
        click.echo(format_table(result))
        if plot_path:
            click.echo(f"plot written to {plot_path}")
