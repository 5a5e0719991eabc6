"""SVG drawings read back as stroke geometry by kind (`read_svg`): what `strokekit diff` compares
and what the tests check drawings with.

Layers are `<g inkscape:groupmode="layer" inkscape:label="KIND">` or `<g id="layer-KIND">`, as
strokekit.writers.svg writes them. Paths may use M/m, L/l, H/h, V/v and Z/z commands (as other
tools write them); `<polyline>`, `<polygon>`, `<line>` and `transform` attributes are read too.
Curves are refused with a clear error. A path with a `data-centreline` attribute (the filled
outline strokekit writes for a stroke whose width varies) is read as that centreline.
"""

from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np

from strokekit.errors import InputError
from strokekit.writers.svg import CENTRELINE

#: Kind name for paths that are not inside any layer.
NO_LAYER = "(no layer)"

_SVG_NS = "http://www.w3.org/2000/svg"
_INK_NS = "http://www.inkscape.org/namespaces/inkscape"
# Elements whose content is not drawn where it stands.
_NOT_DRAWN = {"defs", "clipPath", "mask", "symbol", "pattern", "marker", "metadata", "title", "desc", "style",
              "script", "linearGradient", "radialGradient", "filter", "namedview"}


@dataclass(frozen=True, eq=False)
class Polylines:
    """The strokes of one layer: points (N, 2) in px (SVG user units), offsets (P+1,) so that
    polyline p is points[offsets[p]:offsets[p+1]] (at least one point each), ids (P,) the `id`
    attribute of the element each polyline came from (None when absent; a path with several
    subpaths gives several polylines with the same id)."""

    points: np.ndarray
    offsets: np.ndarray
    ids: tuple

    def __len__(self) -> int:
        return len(self.offsets) - 1

    @cached_property
    def segment_lengths(self) -> np.ndarray:
        """(N-1,) length of the segment from each point to the next (0 across polyline ends)."""
        if len(self.points) < 2:
            return np.zeros(0)
        d = np.linalg.norm(np.diff(self.points, axis=0), axis=1)
        d[self.offsets[1:-1] - 1] = 0.0
        return d

    @property
    def length(self) -> float:
        """Total length in px."""
        return float(self.segment_lengths.sum())

    @staticmethod
    def from_list(polys: list[np.ndarray], ids: list) -> "Polylines":
        if not polys:
            return Polylines(np.zeros((0, 2)), np.zeros(1, np.int64), ())
        counts = [len(p) for p in polys]
        return Polylines(np.concatenate(polys).astype(float) + 0.0, np.r_[0, np.cumsum(counts)].astype(np.int64),
                         tuple(ids))


@dataclass(frozen=True, eq=False)
class SvgDrawing:
    """Stroke geometry of one SVG file by kind. viewbox (x, y, w, h) in px or None when the file
    has neither a viewBox nor a width/height."""

    path: str
    viewbox: tuple[float, float, float, float] | None
    layers: dict[str, Polylines]
    #: kind -> the (stroke, stroke-width, fill) styles its drawn elements have (inherited from
    #: their groups, `style=` over attributes); reported, never part of the comparison.
    styles: dict[str, frozenset] = field(default_factory=dict)


def _local(tag) -> str:
    return tag.rsplit("}", 1)[-1] if isinstance(tag, str) else ""


_NUM = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_NUM_RE = re.compile(_NUM)
_PATH_TOKEN = re.compile(rf"([MmLlHhVvZzCcSsQqTtAa])|({_NUM})|([\s,]+)|(.)", re.S)
# strokekit's own writer: 'M x y x y ...' (implicit line-to after M) -> parsed with numpy at once.
_FAST_PATH = re.compile(r"^\s*M[\s\d.,eE+-]*$")
_CURVES = set("CcSsQqTtAa")


def parse_path_data(d: str) -> list[np.ndarray]:
    """The polylines (one (n, 2) array per subpath) of SVG path data made of M/m, L/l, H/h, V/v
    and Z/z commands. Raises ValueError naming the problem (curves, missing numbers, junk)."""
    if _FAST_PATH.match(d):
        try:
            nums = np.array(d.strip()[1:].replace(",", " ").split(), dtype=float)
        except ValueError:
            nums = None  # e.g. '1-2' without a separator: the tokenizer below splits it
        if nums is not None:
            if len(nums) % 2:
                raise ValueError("odd count of coordinates after M")
            return [nums.reshape(-1, 2)] if len(nums) else []
    toks: list = []
    for m in _PATH_TOKEN.finditer(d):
        if m.group(1):
            toks.append(m.group(1))
        elif m.group(2):
            toks.append(float(m.group(2)))
        elif m.group(4):
            raise ValueError(f"unexpected character {m.group(4)!r}")
    subpaths: list[list[tuple[float, float]]] = []
    cur: list[tuple[float, float]] | None = None
    x = y = 0.0
    start = (0.0, 0.0)
    cmd = None
    i, n = 0, len(toks)
    while i < n:
        t = toks[i]
        if isinstance(t, str):
            cmd = t
            i += 1
            if cmd in _CURVES:
                raise ValueError(f"curve command {cmd!r} is not supported (only M, L, H, V, Z)")
            if cmd in "Zz":
                if cur is not None:
                    if cur[-1] != start:
                        cur.append(start)
                    subpaths.append(cur)
                    cur = None
                x, y = start
                continue
            if cmd not in "Mm" and cur is None and not subpaths:
                raise ValueError("path data must start with M")
        elif cmd is None:
            raise ValueError("path data must start with M")
        elif cmd in "Zz":
            raise ValueError("numbers after Z")
        need = 1 if cmd in "HhVv" else 2
        args = toks[i:i + need]
        if len(args) < need or any(isinstance(a, str) for a in args):
            raise ValueError(f"command {cmd!r} expects {need} numbers")
        i += need
        rel = cmd.islower()
        if cmd in "Mm":
            if cur:
                subpaths.append(cur)
            x, y = (x + args[0], y + args[1]) if rel else (args[0], args[1])
            cur = [(x, y)]
            start = (x, y)
            cmd = "l" if rel else "L"  # further pairs are implicit line-tos
            continue
        if cmd in "Ll":
            x, y = (x + args[0], y + args[1]) if rel else (args[0], args[1])
        elif cmd in "Hh":
            x = x + args[0] if rel else args[0]
        else:  # V v
            y = y + args[0] if rel else args[0]
        if cur is None:  # drawing on after Z starts a new subpath at the closing point
            cur = [start]
        cur.append((x, y))
    if cur:
        subpaths.append(cur)
    return [np.array(s, dtype=float) for s in subpaths]


def _numbers(text: str, what: str) -> list[float]:
    rest = _NUM_RE.sub(" ", text)
    if rest.replace(",", " ").strip():
        raise ValueError(f"unparsable {what} {text[:60]!r}")
    return [float(v) for v in _NUM_RE.findall(text)]


_TRANSFORM = re.compile(r"\s*(matrix|translate|scale|rotate|skewX|skewY)\s*\(([^)]*)\)\s*,?")


def parse_transform(text: str | None) -> np.ndarray:
    """3x3 affine matrix of an SVG transform attribute (identity for None)."""
    m = np.eye(3)
    if not text:
        return m
    pos = 0
    for t in _TRANSFORM.finditer(text):
        if t.start() != pos:
            break
        pos = t.end()
        name, v = t.group(1), _numbers(t.group(2), "transform")
        if name == "matrix" and len(v) == 6:
            step = np.array([[v[0], v[2], v[4]], [v[1], v[3], v[5]], [0, 0, 1]])
        elif name == "translate" and len(v) in (1, 2):
            step = np.array([[1, 0, v[0]], [0, 1, v[1] if len(v) == 2 else 0.0], [0, 0, 1]])
        elif name == "scale" and len(v) in (1, 2):
            step = np.diag([v[0], v[1] if len(v) == 2 else v[0], 1.0])
        elif name == "rotate" and len(v) in (1, 3):
            a = math.radians(v[0])
            c, s = math.cos(a), math.sin(a)
            step = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
            if len(v) == 3:
                step = (np.array([[1, 0, v[1]], [0, 1, v[2]], [0, 0, 1]]) @ step
                        @ np.array([[1, 0, -v[1]], [0, 1, -v[2]], [0, 0, 1]]))
        elif name == "skewX" and len(v) == 1:
            step = np.array([[1, math.tan(math.radians(v[0])), 0], [0, 1, 0], [0, 0, 1]])
        elif name == "skewY" and len(v) == 1:
            step = np.array([[1, 0, 0], [math.tan(math.radians(v[0])), 1, 0], [0, 0, 1]])
        else:
            raise ValueError(f"unparsable transform {text[:60]!r}")
        m = m @ step
    if text[pos:].strip():
        raise ValueError(f"unparsable transform {text[:60]!r}")
    return m


def _hidden(el) -> bool:
    style = el.get("style", "")
    return el.get("display") == "none" or re.search(r"display\s*:\s*none", style) is not None


def _layer_name(el) -> str | None:
    """The kind a <g> stands for, or None when it is not a layer."""
    gid = el.get("id") or ""
    label = el.get(f"{{{_INK_NS}}}label")
    if el.get(f"{{{_INK_NS}}}groupmode") == "layer" or gid.startswith("layer-"):
        return label or (gid[len("layer-"):] if gid.startswith("layer-") else gid) or NO_LAYER
    return None


#: The presentation properties kept per element (SvgDrawing.styles): reported, never compared.
STYLE_KEYS = ("stroke", "stroke-width", "fill")


def _own_style(el, inherited: tuple) -> tuple:
    """(stroke, stroke-width, fill) of element `el` given its parent's: presentation attributes,
    then `style=` declarations over them. Numbers in a normal form ('4px', '4.0' -> '4')."""
    own = {k: el.get(k) for k in STYLE_KEYS if el.get(k) is not None}
    for decl in (el.get("style") or "").split(";"):
        k, _, v = decl.partition(":")
        if k.strip() in STYLE_KEYS:
            own[k.strip()] = v
    out = list(inherited)
    for i, k in enumerate(STYLE_KEYS):
        if k in own:
            v = own[k].strip().lower()
            n = _length_attr(v) if k == "stroke-width" else None
            out[i] = format(n, "g") if n is not None else v
    return tuple(out)


def _length_attr(v: str | None) -> float | None:
    if not v:
        return None
    m = _NUM_RE.match(v.strip())
    return float(m.group(0)) if m else None


def read_svg(path: str | Path) -> SvgDrawing:
    """The stroke geometry of an SVG file by kind (layer). Raises InputError for a missing file,
    a file that is not SVG, or path data that cannot be read (naming the element)."""
    p = Path(path)
    if not p.exists():
        raise InputError("no such file", path=p)
    if p.is_dir():
        raise InputError("is a folder, expected an SVG file", path=p)
    try:
        root = ET.parse(p).getroot()
    except ET.ParseError as e:
        raise InputError(f"not an SVG file (XML error: {e})", path=p) from None
    except OSError as e:
        raise InputError(f"cannot read: {e.strerror or e}", path=p) from None
    if _local(root.tag) != "svg":
        raise InputError(f"not an SVG file (root element is <{_local(root.tag)}>)", path=p)

    viewbox = None
    if root.get("viewBox"):
        try:
            vb = _numbers(root.get("viewBox"), "viewBox")
        except ValueError:
            vb = []
        if len(vb) != 4 or vb[2] <= 0 or vb[3] <= 0:
            raise InputError(f"bad viewBox {root.get('viewBox')!r}", path=p)
        viewbox = tuple(vb)
    else:
        w, h = _length_attr(root.get("width")), _length_attr(root.get("height"))
        if w and h and w > 0 and h > 0:
            viewbox = (0.0, 0.0, w, h)

    polys: dict[str, list[np.ndarray]] = {}
    ids: dict[str, list] = {}
    styles: dict[str, set] = {}

    def add(kind: str, arrays: list[np.ndarray], eid, m: np.ndarray, style: tuple):
        if arrays:
            styles.setdefault(kind, set()).add(style)
        for a in arrays:
            if len(a) == 0:
                continue
            if not np.all(np.isfinite(a)):
                raise InputError(f"non-finite coordinate in <{eid or 'element'}>", path=p)
            if not np.array_equal(m, np.eye(3)):
                a = a @ m[:2, :2].T + m[:2, 2]
            polys.setdefault(kind, []).append(a)
            ids.setdefault(kind, []).append(eid)

    def walk(el, kind: str, m: np.ndarray, style: tuple):
        for ch in el:
            name = _local(ch.tag)
            if name in _NOT_DRAWN or _hidden(ch):
                continue
            eid = ch.get("id")
            st = _own_style(ch, style)
            try:
                cm = m @ parse_transform(ch.get("transform")) if ch.get("transform") else m
                if name in ("g", "svg", "a", "switch"):
                    layer = _layer_name(ch) if name == "g" else None
                    if layer is not None:
                        polys.setdefault(layer, [])  # an empty layer is still a kind of the file
                        ids.setdefault(layer, [])
                    walk(ch, layer if layer is not None else kind, cm, st)
                elif name == "path":  # (a filled outline of strokekit's gives its centreline)
                    add(kind, parse_path_data(ch.get(CENTRELINE) or ch.get("d", "")), eid, cm, st)
                elif name in ("polyline", "polygon"):
                    v = _numbers(ch.get("points", ""), "points")
                    if len(v) % 2:
                        raise ValueError("odd count of coordinates in points")
                    a = np.array(v, float).reshape(-1, 2)
                    if name == "polygon" and len(a) > 1:
                        a = np.vstack([a, a[:1]])
                    add(kind, [a], eid, cm, st)
                elif name == "line":
                    v = [float(ch.get(k, "0")) for k in ("x1", "y1", "x2", "y2")]
                    add(kind, [np.array(v).reshape(2, 2)], eid, cm, st)
            except ValueError as e:
                what = f"<{name} id={eid!r}>" if eid else f"<{name}>"
                raise InputError(f"unreadable {what}: {e}", path=p) from None

    # SVG's initial values: stroke none, stroke-width 1, fill black.
    walk(root, NO_LAYER, parse_transform(root.get("transform")) if root.get("transform") else np.eye(3),
         _own_style(root, ("none", "1", "black")))
    layers = {k: Polylines.from_list(polys[k], ids[k]) for k in polys}
    return SvgDrawing(str(p), viewbox, layers, {k: frozenset(v) for k, v in styles.items()})
