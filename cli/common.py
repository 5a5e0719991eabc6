"""Helpers shared by commands: parsing lists, reading cameras, JSON output."""

from __future__ import annotations

import json
import math
import sys

import click

from strokekit.errors import UsageError


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
