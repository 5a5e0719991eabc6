"""Helpers shared by commands: parsing lists, reading cameras, JSON output."""

from __future__ import annotations

import json
import math
import os
import sys
import time

import click

from strokekit.errors import UsageError, did_you_mean


def say_warnings(scene) -> None:
    """Say a loaded scene's warnings on stderr, one line each, even with --quiet: the file is
    broken for other tools though the drawing is right (Scene.warnings)."""
    for w in scene.warnings:
        click.echo(f"strokekit: warning: {w}", err=True)


def hint_up_axis(scene, scene_path, up_given: bool) -> None:
    """A hint on stderr when an orbit or a view is made about Y for a scene that looks modelled
    Z-up (camera.paths.looks_z_up); not when --up was given, nor for glTF (Y-up by its
    specification: a scene that rests on -Z there was modelled so)."""
    from strokekit.camera.paths import looks_z_up

    if up_given or str(scene_path).lower().endswith((".gltf", ".glb")):
        return
    if looks_z_up(scene.vertices, scene.faces):
        click.echo(f"strokekit: hint: {scene_path} looks modelled Z-up (it rests on a flat base facing -Z): "
                   "--up z turns the view about its Z axis (--up y: this view, without this line)", err=True)


def split_list(value: str | None, option: str = "the list") -> tuple[str, ...] | None:
    """'a, b,c' -> ('a', 'b', 'c'); None stays None; an empty list is a usage error naming `option`."""
    if value is None:
        return None
    items = tuple(v.strip() for v in value.split(",") if v.strip())
    if not items:
        raise UsageError(f"{option} needs at least one name, got {value!r}")
    return items


def floats(text: str, what: str, n: int | None = None) -> tuple[float, ...]:
    """'1, 2.5' -> (1.0, 2.5); a usage error naming `what` when they are not numbers, or not `n` of them."""
    try:
        vals = tuple(float(x) for x in text.split(","))
    except ValueError:
        raise UsageError(f"bad {what} {text!r}: give numbers separated by commas") from None
    if n is not None and len(vals) != n:
        raise UsageError(f"bad {what} {text!r}: give {n} numbers")
    return vals


def echo_json(obj) -> None:
    click.echo(json.dumps(obj, indent=2, sort_keys=False))


def is_interactive(quiet: bool) -> bool:
    return not quiet and sys.stderr.isatty()


#: time.perf_counter() when this module was first imported: the process start where /proc cannot tell.
_IMPORTED = time.perf_counter()


def process_started() -> float:
    """time.perf_counter() at this process's start, the interpreter's own start-up included
    (Linux: its start time in /proc/self/stat, to a clock tick; elsewhere when this module was
    imported)."""
    try:
        with open("/proc/self/stat") as f:
            ticks = int(f.read().rsplit(")", 1)[1].split()[19])  # field 22, starttime
        age = time.clock_gettime(time.CLOCK_BOOTTIME) - ticks / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError, AttributeError):
        return _IMPORTED
    return time.perf_counter() - age if 0 <= age < 3600 else _IMPORTED


class StatusLine:
    """One line on stderr saying what a command waits for (loading the scene, building the BVH),
    with a spinner, on an interactive terminal only (`on`), until `stop` (a progress bar takes
    its place). Lines printed meanwhile appear above it."""

    def __init__(self, on: bool, text: str):
        self._live = self._spinner = None
        if on:
            from rich.console import Console
            from rich.live import Live
            from rich.spinner import Spinner

            self._spinner = Spinner("dots", text, style="green")
            self._live = Live(self._spinner, console=Console(stderr=True), transient=True, refresh_per_second=12.5)
            self._live.start(refresh=True)  # (drawn now, not at the first tick)

    def say(self, text: str) -> None:
        if self._live is not None:
            self._spinner.update(text=text)
            self._live.refresh()

    def stop(self) -> None:
        if self._live is not None:
            self._live.stop()
            self._live = None


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


class Choice(click.Choice):
    """click.Choice whose refusal names the closest choice ("did you mean 'smooth'?")."""

    def convert(self, value, param, ctx):
        try:
            return super().convert(value, param, ctx)
        except click.BadParameter as e:
            hint = did_you_mean(value, self.choices)
            if hint:
                e.message = f"{e.message.rstrip('.')}: {hint.strip()}"
            raise


#: The type of every float option: `type=FINITE` instead of `type=float`.
FINITE = FiniteFloat()
