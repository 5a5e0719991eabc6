"""Style files (TOML, `--style FILE.toml`): `read_style` makes a Style, and every problem is one
InputError naming the file, the line and the key (an unknown key, a value of the wrong type or
range, a line set that selects nothing).

    width = 1.5                      # the sets' default width, px (--stroke-width)
    dashes = [6, 3]                  # the hidden strokes' default dashes (--dashes)

    [[lineset]]
    name = "outline"
    kinds = ["silhouette", "border"]
    visibility = "visible"           # visible, hidden or any; or occlusion = [1, 2]
    objects = ["vase"]               # materials = ["brass"]
    color = "#1a1a1a"
    width = 2.0
    dashes = "solid"                 # or [on, off, ...] px, or "iso"
    thickness = [{ by = "depth", near = 3.0, far = 0.5 }, { by = "along", head = 8, tail = 12 }]

TOML has no positions in its parsed values: a key's line is found again in the text (the n-th
[[lineset]] header, the key's assignment after it, the n-th inline table of its thickness
array or the n-th [[lineset.thickness]] header)."""

from __future__ import annotations

import re
from dataclasses import fields
from pathlib import Path

from strokekit.errors import InputError, UsageError
from strokekit.kinds import MAX_OCCLUSION
from strokekit.style.linesets import MODIFIERS, VISIBILITY, LineSet, Style

try:  # Python 3.11 reads TOML itself; 3.10 with tomli (the same parser, a dependency there)
    import tomllib
except ModuleNotFoundError:  # pragma: no cover
    import tomli as tomllib

_TOP_KEYS = ("width", "dashes", "lineset")
_SET_KEYS = ("name", "kinds", "visibility", "occlusion", "objects", "materials", "color", "width", "dashes",
             "thickness")


class _Problem(Exception):
    """A problem at a key path: ("lineset", i, key) or ("lineset", i, "thickness", j, key)."""

    def __init__(self, where: tuple, message: str):
        super().__init__(message)
        self.where = where


def read_style(path: str | Path) -> Style:
    """The Style of a TOML style file (module doc). InputError (exit 1) for a missing or
    unreadable file, a TOML syntax error, or a key that is unknown, of the wrong type or out of
    range: 'FILE: line N: key 'K' (lineset 2 'name'): problem'."""
    p = Path(path)
    if not p.is_file():
        raise InputError("no such style file" if not p.exists() else "is a folder, expected a style file (.toml)", p)
    try:
        text = p.read_bytes().decode("utf-8")
    except (OSError, UnicodeDecodeError) as e:
        raise InputError(f"cannot read the style file: {getattr(e, 'strerror', None) or e}", p) from None
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise InputError(f"not a TOML style file: {e}", p) from None
    try:
        return _style(doc, str(p))
    except _Problem as e:
        raise InputError(_located(text, e.where, str(e), doc), p) from None


def style_error(style: Style, e: UsageError) -> InputError:
    """The InputError of a UsageError raised about a style's set (option "lineset.<i>" or
    "lineset.<i>.<key>"): naming the style file and the key's line when the style came from one."""
    parts = (e.option or "").split(".")
    where = ("lineset", int(parts[1]), *(parts[2:3] or ["kinds"])) if parts[0] == "lineset" and len(parts) > 1 else ()
    text = doc = None
    if style.source is not None:
        try:
            text = Path(style.source).read_text("utf-8")
            doc = tomllib.loads(text)
        except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
            pass
    if doc is not None and len(where) == 3 and where[2] == "occlusion":  # written as visibility = ...
        try:
            if "visibility" in doc["lineset"][where[1]]:
                where = (*where[:2], "visibility")
        except (KeyError, IndexError, TypeError):
            pass
    msg = _located(text, where, str(e), doc) if text is not None and where else str(e)
    return InputError(msg, style.source)


def check_scene_names(style: Style, scene) -> None:
    """UsageError (option "lineset.<i>.objects" / ".materials") for a set naming an object or
    material the scene does not have: it would select nothing."""
    have = {"objects": tuple(scene.objects), "materials": tuple(m.name for m in scene.materials)}
    for i, s in enumerate(style.sets):
        for key in ("objects", "materials"):
            names = getattr(s, key)
            missing = [n for n in names or () if n not in have[key]]
            if missing:
                raise UsageError(f"line set {s.name!r} names {key[:-1]}(s) {', '.join(map(repr, missing))} the scene "
                                 f"does not have (its {key}: {', '.join(have[key])})", option=f"lineset.{i}.{key}")


def check_style_names(style: Style, scene) -> None:
    """An InputError (style_error's: the file, the key's line) for a line set naming an object or
    material `scene` does not have (it would select nothing): checked once the scene is loaded,
    before any frame."""
    try:
        check_scene_names(style, scene)
    except UsageError as e:
        raise style_error(style, e) from None


# --- the document -------------------------------------------------------------------------------------

def _style(doc: dict, source: str) -> Style:
    for key in doc:
        if key not in _TOP_KEYS:
            raise _Problem((key,), f"unknown key (known at the top: {', '.join(_TOP_KEYS)})")
    top: dict = {}
    if "width" in doc:
        top["width"] = _num(doc["width"], ("width",))
    if "dashes" in doc:
        top["dashes"] = _dashes(doc["dashes"], ("dashes",))
    sets = doc.get("lineset", [])
    if not isinstance(sets, list) or not all(isinstance(s, dict) for s in sets):
        raise _Problem(("lineset",), "must be tables: write each line set as [[lineset]]")
    made = tuple(_line_set(s, i) for i, s in enumerate(sets))
    try:
        return Style(**top, sets=made, source=source)
    except UsageError as e:
        if e.option == "name":  # two sets named alike: the second one's name
            names = [s.name for s in made]
            i = next(i for i, n in enumerate(names) if n in names[:i])
            raise _Problem(("lineset", i, "name"), str(e)) from None
        raise _Problem((e.option or "width",), _without_key(str(e), e.option)) from None


def _line_set(d: dict, i: int) -> LineSet:
    where = ("lineset", i)
    for key in d:
        if key not in _SET_KEYS:
            raise _Problem((*where, key), f"unknown key (known in a line set: {', '.join(_SET_KEYS)})")
    kw: dict = {"name": d.get("name", f"lineset{i + 1}")}
    if not isinstance(kw["name"], str):
        raise _Problem((*where, "name"), f"must be a string, got {_shown(kw['name'])}")
    for key in ("kinds", "objects", "materials"):
        if key in d:
            kw[key] = _names(d[key], (*where, key))
    if "visibility" in d and "occlusion" in d:
        raise _Problem((*where, "occlusion"), "give visibility or occlusion, not both")
    if "visibility" in d:
        v = d["visibility"]
        if v not in VISIBILITY:
            raise _Problem((*where, "visibility"), f"must be one of {', '.join(VISIBILITY)}, got {_shown(v)}")
        kw["occlusion"] = VISIBILITY[v]
    if "occlusion" in d:
        kw["occlusion"] = _levels(d["occlusion"], (*where, "occlusion"))
    if "color" in d:
        if not isinstance(d["color"], str):
            raise _Problem((*where, "color"), f"must be a string #rrggbb, got {_shown(d['color'])}")
        kw["color"] = d["color"]
    if "width" in d:
        kw["width"] = _num(d["width"], (*where, "width"))
    if "dashes" in d:
        kw["dashes"] = _dashes(d["dashes"], (*where, "dashes"))
    if "thickness" in d:
        mods = d["thickness"]
        if not isinstance(mods, list) or not all(isinstance(m, dict) for m in mods):
            raise _Problem((*where, "thickness"), "must be a list of tables, e.g. [{ by = \"depth\", near = 2 }]")
        kw["thickness"] = tuple(_modifier(m, (*where, "thickness", j)) for j, m in enumerate(mods))
    try:
        return LineSet(**kw)
    except UsageError as e:
        raise _Problem((*where, e.option or "name"), _without_key(str(e), e.option)) from None


def _modifier(d: dict, where: tuple):
    by = d.get("by")
    if by is None:
        raise _Problem((*where, "by"), f"missing: say which modifier ({', '.join(MODIFIERS)})")
    if by not in MODIFIERS:
        raise _Problem((*where, "by"), f"unknown modifier {by!r} (known: {', '.join(MODIFIERS)})")
    cls = MODIFIERS[by]
    names = [f.name for f in fields(cls)]
    kw = {}
    for key, v in d.items():
        if key == "by":
            continue
        if key not in names:
            raise _Problem((*where, key), f"unknown key for {by} (known: by, {', '.join(names)})")
        want = next(f for f in fields(cls) if f.name == key).default
        if isinstance(want, str):
            if not isinstance(v, str):
                raise _Problem((*where, key), f"must be a string, got {_shown(v)}")
        elif isinstance(want, int) and not isinstance(want, bool) and not isinstance(want, float):
            if isinstance(v, bool) or not isinstance(v, int):
                raise _Problem((*where, key), f"must be a whole number, got {_shown(v)}")
        else:
            v = _num(v, (*where, key))
        kw[key] = v
    try:
        return cls(**kw)
    except UsageError as e:
        raise _Problem((*where, e.option or "by"), _without_key(str(e), e.option)) from None


def _num(v, where: tuple) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise _Problem(where, f"must be a number, got {_shown(v)}")
    return float(v)


def _names(v, where: tuple) -> tuple[str, ...]:
    if isinstance(v, str):
        v = [v]
    if not isinstance(v, list) or not all(isinstance(x, str) for x in v):
        raise _Problem(where, f"must be a list of names, got {_shown(v)}")
    if not v:
        raise _Problem(where, "is empty: the line set selects nothing")
    return tuple(v)


def _levels(v, where: tuple) -> tuple[int, int]:
    if isinstance(v, int) and not isinstance(v, bool):
        v = [v, v]
    if not (isinstance(v, list) and len(v) == 2 and all(isinstance(x, int) and not isinstance(x, bool) for x in v)):
        raise _Problem(where, f"must be a level or [lo, hi] (whole numbers 0-{MAX_OCCLUSION}), got {_shown(v)}")
    return v[0], v[1]


def _dashes(v, where: tuple) -> tuple[float, ...] | None:
    if v == "solid":
        return ()
    if v == "iso":
        return None
    if not isinstance(v, list) or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v):
        raise _Problem(where, f"must be [dash, gap, ...] in px, \"solid\" or \"iso\", got {_shown(v)}")
    return tuple(float(x) for x in v)


def _shown(v) -> str:
    kind = {bool: "a boolean", str: "a string", int: "a number", float: "a number", list: "a list",
            dict: "a table"}.get(type(v), type(v).__name__)
    text = repr(v) if not isinstance(v, (list, dict)) else str(v)
    return f"{kind} {text[:40]}"


def _without_key(message: str, key: str | None) -> str:
    """A field's message without its leading name (the location names the key)."""
    return message[len(key) + 1:] if key and message.startswith(key + " ") else message


# --- where a key is written ---------------------------------------------------------------------------

_HEADER = re.compile(r"^\s*\[\[?\s*([A-Za-z0-9_.\"' -]+?)\s*\]\]?\s*(#.*)?$")


def _located(text: str, where: tuple, message: str, doc: dict | None) -> str:
    """'line N: key 'K' (lineset i 'name', thickness j 'by'): message' for a key path."""
    line = _line_of(text, where)
    key = where[-1] if where and isinstance(where[-1], str) else None
    context = []
    if len(where) >= 2 and where[0] == "lineset":
        i = where[1]
        name = None
        if doc is not None:
            sets = doc.get("lineset")
            if isinstance(sets, list) and i < len(sets) and isinstance(sets[i], dict):
                name = sets[i].get("name")
        context.append(f"lineset {i + 1}" + (f" {name!r}" if isinstance(name, str) else ""))
        if len(where) >= 4 and where[2] == "thickness":
            j = where[3]
            by = None
            if doc is not None:
                try:
                    by = doc["lineset"][i]["thickness"][j].get("by")
                except (KeyError, IndexError, TypeError, AttributeError):
                    by = None
            context.append(f"thickness {j + 1}" + (f" {by!r}" if isinstance(by, str) else ""))
    head = f"line {line}: " if line else ""
    what = f"key {key!r}" if key else "the file"
    return f"{head}{what}{' (' + ', '.join(context) + ')' if context else ''}: {message}"


def _line_of(text: str, where: tuple) -> int | None:
    """The 1-based line where the key path is written (its table's header when the key is not)."""
    lines = text.splitlines()
    headers = [(n, m.group(1).replace(" ", "")) for n, ln in enumerate(lines) if (m := _HEADER.match(ln))]

    def key_line(key: str, start: int, stop: int) -> int | None:
        pat = re.compile(rf"^\s*(?:{re.escape(key)}|\"{re.escape(key)}\"|'{re.escape(key)}')\s*=")
        for n in range(start, stop):
            if pat.match(lines[n]):
                return n
        return None

    def section(name: str, k: int, after: int = -1) -> tuple[int, int] | None:
        """Line range of the k-th [[name]] header after line `after`, to the next header of
        that name or of a parent table."""
        found = [n for n, h in headers if h == name and n > after]
        if k >= len(found):
            return None
        start = found[k]
        parent = name.split(".")[0]
        nxt = [n for n, h in headers if n > start and (h == name or h == parent or "." not in h)]
        return start, (nxt[0] if nxt else len(lines))

    if not where:
        return None
    if where[0] != "lineset" or len(where) == 1:
        stop = headers[0][0] if headers else len(lines)
        n = key_line(str(where[0]), 0, stop)
        if n is None and where[0] == "lineset" and headers:
            n = headers[0][0]
        return n + 1 if n is not None else None
    sec = section("lineset", where[1])
    if sec is None:
        return None
    start, stop = sec
    if len(where) == 2:
        return start + 1
    key = where[2]
    if key != "thickness" or len(where) < 4:
        n = key_line(str(key), start + 1, stop)
        return (n if n is not None else start) + 1
    j, sub = where[3], where[4] if len(where) > 4 else None
    n = key_line("thickness", start + 1, stop)
    if n is not None:  # thickness = [{...}, {...}]: the j-th inline table
        return _inline_table_line(lines, n, j, sub) + 1
    sub_sec = section("lineset.thickness", j, start)
    if sub_sec is None or sub_sec[0] >= stop:
        return start + 1
    m = key_line(str(sub), sub_sec[0] + 1, sub_sec[1]) if sub else None
    return (m if m is not None else sub_sec[0]) + 1


def _inline_table_line(lines: list[str], first: int, j: int, key: str | None) -> int:
    """The line of `key` in the j-th inline table of the array assigned on line `first` (or the
    table's opening brace, or the assignment)."""
    text = "\n".join(lines[first:])
    start = text.index("=") + 1
    depth, count, in_str, table_at = 0, -1, None, None
    k = start
    while k < len(text):
        c = text[k]
        if in_str:
            if c == "\\" and in_str == '"':
                k += 2
                continue
            if c == in_str:
                in_str = None
        elif c in "\"'":
            in_str = c
        elif c == "#":
            nl = text.find("\n", k)
            k = len(text) if nl < 0 else nl
            continue
        elif c in "[{":
            depth += 1
            if c == "{" and depth == 2:
                count += 1
                if count == j:
                    table_at = k
        elif c in "]}":
            depth -= 1
            if c == "}" and depth == 1 and table_at is not None:
                if key is not None:
                    m = re.search(rf"(?<![A-Za-z0-9_]){re.escape(key)}\s*=", text[table_at:k])
                    if m:
                        return first + text.count("\n", 0, table_at + m.start())
                return first + text.count("\n", 0, table_at)
            if depth == 0:
                break
        k += 1
    return first
