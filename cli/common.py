"""Helpers shared by commands: parsing lists, reading cameras, JSON output."""

from __future__ import annotations

import json
import sys

import click

from strokekit.errors import UsageError


def split_list(value: str | None) -> tuple[str, ...] | None:
    if value is None:
        return None
    items = tuple(v.strip() for v in value.split(",") if v.strip())
    if not items:
        raise UsageError("empty list")
    return items


def echo_json(obj) -> None:
    click.echo(json.dumps(obj, indent=2, sort_keys=False))


def is_interactive(quiet: bool) -> bool:
    return not quiet and sys.stderr.isatty()
