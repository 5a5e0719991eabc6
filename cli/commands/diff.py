"""`strokekit diff A B`: compare the stroke geometry of two SVG drawings (or two folders of them)
within a pixel tolerance. Exit 0 when equal, 1 when different, 2 for usage errors and missing paths."""

from __future__ import annotations

import click

from strokekit.errors import StrokekitError
from strokekit.fileio import check_not_an_input

from ..common import FINITE, FiniteFloatRange


@click.command("diff", short_help="Compare the strokes of two SVGs (or folders of them).")
@click.argument("a", type=click.Path())
@click.argument("b", type=click.Path())
@click.option("--tol", type=FINITE, default=0.05, show_default=True,
              help="Tolerance in px: every point of a stroke must lie this close to a stroke of the same kind "
                   "on the other side.")
@click.option("--json", "as_json", is_flag=True, help="Print the comparison as JSON (for machines).")
@click.option("--png", "png", type=click.Path(), default=None,
              help="Draw the difference: only in A red, only in B blue, common grey. With two folders, a folder "
                   "that receives one <name>.png per differing file.")
@click.option("--png-scale", type=FiniteFloatRange(min=0, min_open=True), default=1.0, show_default=True,
              help="Pixels of the difference image per SVG px.")
@click.option("--quiet", "-q", is_flag=True, help="Print nothing; the exit code tells.")
@click.pass_context
def command(ctx: click.Context, a: str, b: str, tol: float, as_json: bool, png: str | None, png_scale: float,
            quiet: bool):
    """Compare stroke geometry kind by kind (SVG layers) within --tol px, ignoring stroke ids,
    order, direction and splits. A is the reference (e.g. golden files), B the new output.

    Exit codes: 0 equal, 1 different (or an unreadable SVG), 2 usage error or a missing file or folder."""
    import orjson

    from strokekit.metrics.diff import diff_paths

    try:
        check_not_an_input("--png", png, [("A file", a), ("B file", b)])
        result = diff_paths(a, b, tol, png=png, png_scale=png_scale)
    except StrokekitError as e:
        # one line and the error's exit code, also when the command runs outside `strokekit` (tests)
        click.echo(f"strokekit: error: {e}", err=True)
        ctx.exit(e.exit_code)
    if as_json:
        click.echo(orjson.dumps(result.to_dict(), option=orjson.OPT_INDENT_2).decode())
    elif not quiet:
        click.echo(result.summary())
    ctx.exit(0 if result.equal else 1)
