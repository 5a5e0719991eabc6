"""Click options made from the options fields' Flags (strokekit.options.Flag), and the values
said on the command line turned back into fields: an option is declared once, beside its field."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import MISSING, fields

import click

from strokekit.options import Flag, LineOptions, flag_of
from strokekit.paths.options import PathOptions
from strokekit.raster.options import PassOptions, RasterOptions
from strokekit.run.request import RenderRequest
from strokekit.run.spec import OutputOptions, RunSpec
from strokekit.style.linesets import Style
from strokekit.tracking.options import TrackingOptions
from strokekit.writers.options import GltfOptions

from .common import FINITE, Choice, FiniteFloatRange, floats, split_list

#: The library's options classes whose fields have flags.
OPTION_CLASSES = (LineOptions, RenderRequest, TrackingOptions, PathOptions, OutputOptions, Style, GltfOptions,
                  RasterOptions, PassOptions, RunSpec)


def flags_of(cls) -> list[tuple[str, Flag, object]]:
    """(field name, Flag, field default) of each field of `cls` given on the command line."""
    out = []
    for f in fields(cls):
        flag = flag_of(f)
        if flag is not None:
            default = f.default if f.default is not MISSING else (
                f.default_factory() if f.default_factory is not MISSING else None)
            out.append((f.name, flag, default))
    return out


def field_flags() -> dict[str, Flag]:
    """{field name: its Flag} over OPTION_CLASSES (a field name in two classes has one flag)."""
    return {name: flag for cls in OPTION_CLASSES for name, flag, _ in flags_of(cls)}


def user_message(e: Exception) -> str:
    """The one-line text of an error for the command line: a UsageError about an options field
    names the field's flag first, then the field when the flag does not spell it
    ('--sample-spacing (sample_spacing_px) must ...'; an angle's message says degrees already)."""
    text = str(e)
    field = getattr(e, "option", None)
    flag = field_flags().get(field) if field else None
    if flag is not None and text.startswith(field):
        spelt = flag.name == "--" + field.replace("_", "-") or field.endswith("_deg")
        text = (flag.name if spelt else f"{flag.name} ({field})") + text[len(field):]
    return text


def shown_default(flag: Flag, default):
    """The default as the command line spells it (what the help shows, and click's default)."""
    v = flag.shown if flag.shown is not None else default
    if isinstance(flag.choices, Mapping):
        return next(word for word, value in flag.choices.items() if value == v)
    if flag.text == "names":
        return ", ".join(v)
    if flag.text == "numbers":
        return ",".join(str(x) for x in v)
    return v


def click_option(flag: Flag, default):
    """The click option of a Flag whose field's default is `default`."""
    decls = [f"{flag.name}/{flag.off}" if flag.off else flag.name, *([flag.short] if flag.short else []), flag.dest]
    kw: dict = {"help": flag.help}
    if flag.switch:
        return click.option(*decls, is_flag=True, **kw)
    kw["default"] = shown_default(flag, default) if flag.show_default else None
    kw["show_default"] = flag.show_default
    if flag.off:
        return click.option(*decls, **kw)
    if flag.path:
        kw["type"] = click.Path()
    elif flag.choices:
        kw["type"] = Choice(list(flag.choices))
    elif flag.text:
        pass  # text, parsed by field_values
    elif flag.low is not None or flag.high is not None:
        whole = isinstance(flag.low, int) and isinstance(flag.high, int) and not isinstance(default, float)
        kw["type"] = click.IntRange(flag.low, flag.high) if whole else FiniteFloatRange(flag.low, flag.high)
    elif isinstance(default, float):
        kw["type"] = FINITE
    return click.option(*decls, **kw)


def options_of(*classes):
    """A decorator adding the click options of every flagged field of `classes`, in order."""
    made = [click_option(flag, default) for cls in classes for _, flag, default in flags_of(cls)]

    def decorate(f):
        for deco in reversed(made):
            f = deco(f)
        return f
    return decorate


def field_option(cls, name: str):
    """The click option of field `name` of `cls`, for a command that takes it beside others of
    its own (`info --crease-angle`: LineOptions'); its value is None when not said."""
    option, = (click_option(flag, default) for field, flag, default in flags_of(cls) if field == name)
    return option


def said(values: dict) -> dict:
    """The values of `values` (a command's parameters) given on the command line."""
    ctx = click.get_current_context()
    return {k: v for k, v in values.items()
            if ctx.get_parameter_source(k) == click.core.ParameterSource.COMMANDLINE}


def field_values(cls, said_values: dict) -> dict:
    """{field: value} of the fields of `cls` whose flags were said, as the field takes them."""
    out = {}
    for name, flag, _ in flags_of(cls):
        if flag.dest in said_values:
            out[name] = field_value(flag, said_values[flag.dest])
    return out


def field_value(flag: Flag, value):
    """A flag's parsed value as its field takes it."""
    if value is None:
        return None
    if flag.text == "names":
        return split_list(value, flag.name)
    if flag.text == "numbers":
        return floats(value, flag.name, flag.count) if value or flag.count else ()
    if isinstance(flag.choices, Mapping):
        return flag.choices[value]
    return not value if flag.invert else value
