"""`strokekit camera orbit|dolly SCENE`: write a camera path file (docs/camera-files.md) to stdout or a file."""

from __future__ import annotations

import json

import click

from strokekit.camera.limits import ANGLED, MAX_IMAGE_PX, MAX_PATH_FRAMES
from strokekit.errors import InputError, UsageError
from strokekit.fileio import atomic_write_text, check_not_an_input

from ..common import FINITE, FiniteFloatRange, hint_up_axis, say_warnings


def _up_given() -> bool:
    return click.get_current_context().get_parameter_source("up") == click.core.ParameterSource.COMMANDLINE


def _framed(scene, out, animation):
    """The scene's centre, radius and points to frame over `animation` (its load warnings said,
    an up-axis hint given), after checking that `out` is not the scene itself."""
    from strokekit.scene.load import load_scene

    check_not_an_input("--out", out, [("scene", scene)])
    s = load_scene(scene)
    say_warnings(s)
    hint_up_axis(s, scene, _up_given())
    return s.framing(animation)


def _emit(path, out):
    text = json.dumps(path.to_json(), indent=1) + "\n"
    if out:
        atomic_write_text(out, text)
    else:
        click.echo(text, nl=False)


_common = [
    click.argument("scene", type=click.Path()),
    click.option("--frames", type=click.IntRange(1, MAX_PATH_FRAMES), default=48, show_default=True,
                 help="Number of frames (at most as many as a camera file may have)."),
    click.option("--elevation", type=FiniteFloatRange(-90, 90), default=15.0, show_default=True, help="Degrees above the horizon."),
    click.option("--fov", type=FiniteFloatRange(0.1, 179.9), default=40.0, show_default=True, help="Vertical field of view, degrees."),
    click.option("--width", type=click.IntRange(min=1, max=MAX_IMAGE_PX), default=1024, show_default=True),
    click.option("--height", type=click.IntRange(min=1, max=MAX_IMAGE_PX), default=1024, show_default=True),
    click.option("--up", type=click.Choice(["y", "z"]), default="y", show_default=True, help="The scene's up axis."),
    click.option("-o", "--out", type=click.Path(), default=None, help="Write to a file instead of stdout."),
    click.option("--animation", default=None, help="A glTF scene's animation to frame the scene over, by name or "
                 "number [the first]."),
]


def _with_common(f):
    for deco in reversed(_common):
        f = deco(f)
    return f


@click.group("camera", short_help="Write camera path files (orbit, dolly, parallel projections).")
def command():
    """Generate camera path files (JSON, docs/camera-files.md) so every run can be reproduced from a file."""


@command.command("orbit")
@_with_common
@click.option("--degrees-per-frame", type=FINITE, default=None, help="Default: a full turn over the frames.")
@click.option("--fps", type=FiniteFloatRange(min=0, min_open=True), default=24.0, show_default=True,
              help="Frames per second (for glTF animation).")
def orbit(scene, frames, elevation, fov, width, height, up, out, animation, degrees_per_frame, fps):
    """A turntable orbit around the scene that keeps it in view (over its whole animation)."""
    from strokekit.camera.paths import orbit_path

    center, radius, _ = _framed(scene, out, animation)
    _emit(orbit_path(center, radius, frames, elevation=elevation, fov_y=fov, width=width, height=height,
                     fps=fps, degrees_per_frame=degrees_per_frame, up_axis=up), out)


@command.command("dolly")
@_with_common
@click.option("--start", type=FiniteFloatRange(min=0, min_open=True), default=1.0, show_default=True, help="Start distance factor.")
@click.option("--end", type=FiniteFloatRange(min=0, min_open=True), default=8.0, show_default=True, help="End distance factor.")
def dolly(scene, frames, elevation, fov, width, height, up, out, animation, start, end):
    """The camera moves straight away from (or toward) the scene, geometrically."""
    from strokekit.camera.paths import dolly_path

    center, radius, _ = _framed(scene, out, animation)
    _emit(dolly_path(center, radius, frames, start=start, end=end, fov_y=fov, width=width, height=height,
                     elevation=elevation, up_axis=up), out)


@command.command("parallel")
@click.argument("scene", type=click.Path())
@click.option("--projection", type=click.Choice(list(ANGLED) + ["orthographic"]), default="isometric",
              show_default=True, help="The parallel projection (docs/camera-files.md, parallel projections).")
@click.option("--azimuth", type=FINITE, default=None,
              help="Degrees about the up axis (isometric, dimetric: 45, 135, 225 or 315 [45]; trimetric: needed; "
                   "oblique and orthographic: [0], the front view).")
@click.option("--elevation", type=FiniteFloatRange(-90, 90, min_open=True, max_open=True), default=None,
              help="Degrees above the horizontal plane (dimetric, trimetric: needed; oblique and orthographic "
                   "[0]; isometric: fixed).")
@click.option("--oblique-angle", type=FINITE, default=None,
              help="Cavalier, cabinet: the receding axis's angle above the image horizontal, degrees [45].")
@click.option("--frames", type=click.IntRange(min=1), default=1, show_default=True,
              help="Number of frames (the same view in each: a still for a sequence).")
@click.option("--width", type=click.IntRange(min=1, max=MAX_IMAGE_PX), default=1024, show_default=True)
@click.option("--height", type=click.IntRange(min=1, max=MAX_IMAGE_PX), default=1024, show_default=True)
@click.option("--up", type=click.Choice(["y", "z"]), default="y", show_default=True, help="The scene's up axis.")
@click.option("-o", "--out", type=click.Path(), default=None, help="Write to a file instead of stdout.")
@click.option("--animation", default=None, help="A glTF scene's animation to frame the scene over, by name or number "
              "[the first].")
def parallel(scene, projection, azimuth, elevation, oblique_angle, frames, width, height, up, out, animation):
    """A parallel projection of technical drawing that frames the whole scene (its drawing centred,
    5% of the image around it): isometric, dimetric, trimetric, cavalier, cabinet, or orthographic
    from --azimuth / --elevation."""
    from strokekit.camera.paths import parallel_path

    center, radius, points = _framed(scene, out, animation)
    try:
        path = parallel_path(center, radius, projection, azimuth=azimuth, elevation=elevation,
                             oblique_angle=oblique_angle, frames=frames, width=width, height=height, up_axis=up,
                             points=points)
    except InputError as e:  # an angle the projection does not take: the options' fault (exit 2)
        raise UsageError(f"--projection {projection}: {e}") from None
    _emit(path, out)
