"""Options declared once: a field's Flag is its command-line option (cli/flags.py), and the
request settles presets and modes in the library (RenderRequest, RasterOptions.preset)."""

from __future__ import annotations

from dataclasses import dataclass, fields

import click
import pytest
from click.testing import CliRunner

from strokekit.errors import UsageError
from strokekit.options import LineOptions, flag_of, option
from strokekit.raster.bands import RasterOptions
from strokekit.run.request import RenderRequest
from strokekit_cli.commands.render import command as render_command
from strokekit_cli.commands.render_options import NEEDS, RENDER_CLASSES
from strokekit_cli.flags import OPTION_CLASSES, field_values, flags_of, options_of, said, user_message


def test_every_render_option_is_made_from_one_field():
    """Each option of `strokekit render` comes from one field's Flag: no flag or value name twice,
    and every condition a Flag names is one NEEDS knows."""
    made = [flag for cls in RENDER_CLASSES for _, flag, _ in flags_of(cls)]
    names = [flag.name for flag in made]
    assert len(names) == len(set(names)) and len({f.dest for f in made}) == len(made)
    params = {p.name for p in render_command.params if isinstance(p, click.Option)} - {"help"}
    assert params == {f.dest for f in made}
    assert {f.needs for f in made if f.needs} <= set(NEEDS)


def test_a_field_name_in_two_classes_has_one_flag():
    """user_message maps a field name to its flag: a field flagged in one class must not be
    flagged otherwise in another."""
    seen: dict[str, str] = {}
    for cls in OPTION_CLASSES:
        for name, flag, _ in flags_of(cls):
            assert seen.setdefault(name, flag.name) == flag.name, name


def test_the_defaults_the_help_shows_are_the_fields():
    """A default shown by --help is the field's own (there is no second default to keep in step)."""
    by_dest = {p.name: p for p in render_command.params}
    assert by_dest["max_growth"].default == 20.0 and by_dest["light"].default == "-0.4,0.6,0.7"
    assert by_dest["kinds"].default == ", ".join(LineOptions().kinds)
    assert by_dest["alpha_mode"].default == "blend" and by_dest["coherence"].default == "kalnins"
    # Options whose default depends on a preset or on the run show none: their help says it.
    assert by_dest["supersample"].default is None and by_dest["sample_spacing"].default is None


def test_a_new_option_is_one_declaration():
    """A field declared with option() is a command-line option, and what is said on the command
    line comes back as the field's value; a value not said leaves the field's default."""

    @dataclass(frozen=True)
    class Knobs:
        width_px: float = option(2.0, "--width", "Width in px.", show_default=True)
        names: tuple[str, ...] = option(("a",), "--names", "Names.", text="names")
        shaded: bool = option(True, "--no-shading", "No shading.", switch=True, invert=True)
        hidden: int = 3  # set from Python only

    @click.command()
    @options_of(Knobs)
    def cmd(**o):
        click.echo(repr(Knobs(**field_values(Knobs, said(o)))))

    out = CliRunner().invoke(cmd, ["--names", "b, c", "--no-shading"]).output
    assert out.strip() == "test_a_new_option_is_one_declaration.<locals>.Knobs(width_px=2.0, names=('b', 'c'), " \
                          "shaded=False, hidden=3)"
    assert "[default: 2.0]" in CliRunner().invoke(cmd, ["--help"]).output
    assert flag_of(next(f for f in fields(Knobs) if f.name == "hidden")) is None


def test_an_error_about_a_field_names_its_flag():
    assert user_message(UsageError("sample_spacing_px must be > 0", option="sample_spacing_px")) == \
        "--sample-spacing (sample_spacing_px) must be > 0"
    assert user_message(UsageError("taper must be >= 0", option="taper")) == "--taper must be >= 0"
    assert user_message(UsageError("crease_angle_deg must be in (0, 180) degrees", option="crease_angle_deg")) == \
        "--crease-angle must be in (0, 180) degrees"
    # A field set from Python only keeps its name.
    assert user_message(UsageError("outlier_px must be >= 0", option="outlier_px")) == "outlier_px must be >= 0"


@pytest.mark.parametrize("request_, frames, strokes, tracking, carried", [
    (RenderRequest(), 24, "brush", None, True),  # a sequence: brush paths, carried
    (RenderRequest(), 1, "lines", None, False),  # one frame: its lines
    (RenderRequest(coherence="seed"), 24, "lines", "seed", True),  # a method named: tracked lines
    (RenderRequest(coherence="none"), 24, "lines", None, False),
    (RenderRequest(strokes="brush", coherence="none"), 24, "brush", None, False),  # paths made afresh
    (RenderRequest(strokes="lines"), 24, "lines", "kalnins", True),
    (RenderRequest(strokes="lines"), 1, "lines", None, False),
])
def test_the_request_settles_what_a_sequence_draws(request_, frames, strokes, tracking, carried):
    plan = request_.plan(frames)
    assert ("brush" if plan.paths is not None else "lines") == strokes
    assert (plan.tracking.method if plan.tracking is not None else None) == tracking
    assert plan.carried == carried
    if plan.paths is not None:
        assert plan.paths.history == (request_.coherence != "none")


def test_a_preset_settles_the_line_and_raster_options():
    """--quality exact: fine line sampling and K = 4 without edge resampling (the grid is as fine);
    a K said over the default preset turns the edge resampling off the same way."""
    exact = RenderRequest.preset("exact", raster={})
    assert exact.lines.sample_spacing_px == 0.25
    assert (exact.raster.supersample, exact.raster.edge_supersample) == (4, 0)
    assert (RasterOptions.preset("default").supersample, RasterOptions.preset("default").edge_supersample) == (1, 4)
    assert RasterOptions.preset("default", supersample=4).edge_supersample == 0
    assert RenderRequest.preset("draft").raster is None
    with pytest.raises(UsageError, match="tracks lines"):
        RenderRequest(strokes="brush", coherence="kalnins")
