"""Helpers shared by commands: parsing lists, reading cameras, JSON output."""

from __future__ import annotations

import json
import math
import sys

import click

from strokekit.errors import UsageError

#: The command-line flag of each options field (LineOptions, TrackingOptions) whose name differs
#: from it; the others are the field name with dashes.
FLAGS = {"sample_spacing_px": "--sample-spacing", "bisection_tol_px": "--bisection-tol", "period_px": "--period",
         "max_length_px": "--max-length", "min_length_px": "--min-length", "simplify_tol_px": "--simplify",
         "doubled_px": "--doubled", "whole_edge_px": "--whole-edge", "max_growth_px": "--max-growth",
         "min_carry_px": "--min-carry", "suggestive_derivative_threshold": "--suggestive-threshold",
         "suggestive_kr_threshold": "--suggestive-kr-threshold", "crease_angle_deg": "--crease-angle",
         "split_angle_deg": "--split-angle", "codec": "--exr-codec", "merge_px": "--path-merge"}
#: Fields that only the library sets: no flag of their own.
_LIBRARY_ONLY = {"search_radius_px", "vote_spacing_px", "seed_search_px", "dense_spacing_px", "bend_weight",
                 "knot_spacing_px", "min_segment_px", "stretch_weight", "outlier_px", "min_id_px", "join_tol_px",
                 "join_angle_deg", "min_tangent_dot"}


def user_message(e: Exception) -> str:
    """The one-line text of an error for the command line: a UsageError about an options field
    names the field's flag first, then the field ('--sample-spacing (sample_spacing_px) must ...')."""
    text = str(e)
    field = getattr(e, "option", None)
    if field and field not in _LIBRARY_ONLY and text.startswith(field):
        flag = FLAGS.get(field, "--" + field.replace("_", "-"))
        text = (f"{flag} ({field})" if field in FLAGS and field not in ("crease_angle_deg", "split_angle_deg")
                else flag) + text[len(field):]
    return text


def say_warnings(scene) -> None:
    """Say a loaded scene's warnings on stderr, one line each, even with --quiet: the file is
    broken for other tools though the drawing is right (Scene.warnings)."""
    for w in scene.warnings:
        click.echo(f"strokekit: warning: {w}", err=True)


def split_list(value: str | None, option: str = "the list") -> tuple[str, ...] | None:
    """'a, b,c' -> ('a', 'b', 'c'); None stays None; an empty list is a usage error naming `option`."""
    if value is None:
        return None
    items = tuple(v.strip() for v in value.split(",") if v.strip())
    if not items:
        raise UsageError(f"{option} needs at least one name, got {value!r}")
    return items


def echo_json(obj) -> None:
    click.echo(json.dumps(obj, indent=2, sort_keys=False))


def is_interactive(quiet: bool) -> bool:
    return not quiet and sys.stderr.isatty()


def _check_finite(type_: click.ParamType, rv, value, param, ctx):
    if isinstance(rv, float) and not math.isfinite(rv):
        type_.fail(f"{value!r} is not a finite number.", param, ctx)
    return rv


class FiniteFloat(click.types.FloatParamType):
    """A float option that must be finite: click's FLOAT takes 'nan' and 'inf', which then break
    deep in the work (or pass silently)."""

    def convert(self, value, param, ctx):
        return _check_finite(self, super().convert(value, param, ctx), value, param, ctx)


class FiniteFloatRange(click.FloatRange):
    """click.FloatRange that refuses nan (which every range comparison lets through) and inf,
    saying "finite" (checked before the range)."""

    def convert(self, value, param, ctx):
        _check_finite(self, click.types.FloatParamType.convert(self, value, param, ctx), value, param, ctx)
        return super().convert(value, param, ctx)


#: The type of every float option: `type=FINITE` instead of `type=float`.
FINITE = FiniteFloat()
