"""SVG per BRIEF 1.3: one Inkscape layer per line kind, one <path> per stroke with id s<stroke id>,
fixed decimals, no timestamps: the same strokes give the same bytes.

The document is assembled as text, by this module alone (the band polygons' layer too): an
element tree per stroke costs several times more for the same bytes.
"""

from __future__ import annotations

from itertools import chain

import numpy as np

from strokekit.colour import srgb_encode
from strokekit.model import KINDS, N_KINDS, BandRegion, Strokes
from strokekit.sampling import locate
from strokekit.style.linesets import KIND_COLORS, Style
from strokekit.style.widths import StyledStrokes, apply_style
from strokekit.writers.options import SVG_LINES
from strokekit.writers.outline import outline_path_data
from strokekit.writers.text import fixed_point_text


def _ring_path(coords: np.ndarray, decimals: int) -> str:
    r = np.round(np.asarray(coords)[:-1], decimals) + 0.0
    fmt = f"%.{decimals}f"
    return "M" + " ".join(fmt % v for v in r.ravel()) + "Z"


def bands_layer(regions: list[BandRegion], *, decimals: int = 2) -> str:
    """The Inkscape layer 'bands' (id 'layer-bands') to place under the line layers
    (svg_document(..., underlays=...)): one <path> per (material, band) region, id
    'b<material>-<band>', filled with the ramp colour, holes by the even-odd rule, and outlined
    1 px wide in the same colour: two regions that share an edge each cover only part of the
    pixels along it when a viewer anti-aliases them, and the background showed through as a
    light seam (Inkscape); the outline makes each region overlap its neighbours by half a pixel."""
    head = ('<g fill-rule="evenodd" id="layer-bands" inkscape:groupmode="layer" inkscape:label="bands" '
            'stroke-linejoin="round" stroke-width="1"')
    paths = []
    for r in regions:
        d = " ".join(_ring_path(ring, decimals) for ring in r.rings)
        rgb = np.round(srgb_encode(r.colour) * 255).astype(int)
        colour = "#%02x%02x%02x" % tuple(rgb)
        paths.append(f'<path d="{d}" fill="{colour}" id="b{r.material}-{r.band}" stroke="{colour}" />')
    return head + (">" + "".join(paths) + "</g>" if paths else " />")


_HEAD = ('<svg baseProfile="full" height="{h}px" version="1.1" viewBox="0 0 {w} {h}" width="{w}px" '
         'xmlns="http://www.w3.org/2000/svg" xmlns:ev="http://www.w3.org/2001/xml-events" '
         'xmlns:inkscape="http://www.inkscape.org/namespaces/inkscape" '
         'xmlns:sodipodi="http://sodipodi.sourceforge.net/DTD/sodipodi-0.dtd" '
         'xmlns:xlink="http://www.w3.org/1999/xlink"><defs />')


def point_strings(points: np.ndarray, decimals: int = 2) -> list[str]:
    """'x y' for each (n, 2) pixel point at fixed decimals (-0.00 written as 0.00)."""
    r = (np.round(points, decimals) + 0.0).tolist()  # + 0.0 turns -0.0 into 0.0
    fmt = f"%.{decimals}f %.{decimals}f"
    return [fmt % (x, y) for x, y in r]


def path_data(points: np.ndarray, decimals: int = 2) -> str:
    """'M x y x y ...' for (n, 2) pixel points (implicit line-to after M)."""
    return "M" + " ".join(point_strings(points, decimals))


def stroke_path_data(strokes: Strokes, decimals: int = 2) -> list[str]:
    """Each stroke's points as 'x y x y ...' (the text after "M" of its path). The same strings as
    joining point_strings per stroke, written by numpy digit arithmetic on all points at once
    (no per-number Python formatting); frames with numbers beyond its range go through one
    %-operation over all points."""
    counts = np.diff(strokes.offsets).tolist()
    if not counts:
        return []
    v = np.asarray(strokes.points).ravel()
    if 0 <= decimals <= 9 and v.dtype == np.float64 and strokes.offsets[0] == 0 \
            and len(v) == 2 * strokes.offsets[-1] and min(counts) > 0:
        sep = np.full(len(v), 32, np.uint8)  # ' ' between numbers, NUL after each stroke's last
        sep[2 * strokes.offsets[1:] - 1] = 0
        text = fixed_point_text(v, decimals, sep)
        if text is not None:
            return text[:-1].decode("ascii").split("\0")
    r = (np.round(strokes.points, decimals) + 0.0).ravel().tolist()  # + 0.0 turns -0.0 into 0.0
    # Strokes separated by NUL, which the formatted numbers never contain; one template per
    # point count.
    formats = _POINT_FORMATS.setdefault(decimals, {})
    for n in set(counts).difference(formats):
        formats[n] = " ".join([f"%.{decimals}f %.{decimals}f"] * n)
    template = "\0".join([formats[n] for n in counts])
    if len(formats) > 4096:  # a frame with unusually many distinct lengths: do not keep them all
        # A new cache rather than clearing this one: another thread may be reading it.
        _POINT_FORMATS[decimals] = {}
    return (template % tuple(r)).split("\0")


_POINT_FORMATS: dict[int, dict[int, str]] = {}


def iso_dashes(stroke_width: float) -> tuple[float, float]:
    """ISO 128-20 line type 02 (dashed: hidden outlines and edges): dashes 12 line widths long,
    gaps of 3 (px)."""
    return 12.0 * stroke_width, 3.0 * stroke_width


def dash_pieces(strokes: Strokes, members: np.ndarray, phase: np.ndarray, pattern: tuple[float, ...],
                values: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
    """The dashes of the member strokes as polylines: the pattern (on, off, ...; px) laid along
    each stroke from `phase` (px into the pattern at its start), dash ends interpolated on the
    polyline, the points between kept (a dash follows the curve). Returns the dashes' points
    (M, 2), offsets, the member (index into `members`) each dash belongs to and, for per-point
    `values` (N,) of the strokes (their widths), those values at the dashes' points."""
    period = sum(pattern)
    on = np.cumsum(pattern)[0::2] - np.asarray(pattern[0::2])  # where each dash starts in the pattern
    on_len = np.asarray(pattern[0::2])
    L = strokes.lengths[members]
    n_rep = np.ceil((L + phase) / period).astype(np.int64) + 1
    m = np.repeat(np.arange(len(members)), n_rep * len(on))
    k = np.repeat(np.arange(n_rep.sum()) - np.repeat(np.cumsum(n_rep) - n_rep, n_rep), len(on))
    j = np.tile(np.arange(len(on)), int(n_rep.sum()))
    a = k * period + on[j] - phase[m]
    b = a + on_len[j]
    a, b = np.maximum(a, 0.0), np.minimum(b, L[m])
    keep = b > a
    m, a, b = m[keep], a[keep], b[keep]
    st = np.asarray(members, np.int64)[m]
    h0, i0, t0 = locate(strokes, st, a)  # segment h0 -> i0 holds the dash's start
    h1, i1, t1 = locate(strokes, st, b, side="left")  # and h1 -> i1 its end
    P = strokes.points if values is None else np.column_stack([strokes.points, values])
    inner = np.maximum(i1 - i0, 0)  # stroke points strictly inside the dash
    counts = inner + 2
    off = np.concatenate([[0], np.cumsum(counts)])
    pts = np.empty((int(off[-1]), P.shape[1]))
    pts[off[:-1]] = P[h0] + t0[:, None] * (P[i0] - P[h0])
    pts[off[1:] - 1] = P[h1] + t1[:, None] * (P[i1] - P[h1])
    r = np.repeat(np.arange(len(m)), inner)
    q = np.arange(int(inner.sum())) - np.repeat(np.cumsum(inner) - inner, inner)
    pts[off[:-1][r] + 1 + q] = P[i0[r] + q]
    if values is None:
        return pts, off, m, None
    return np.ascontiguousarray(pts[:, :2]), off, m, pts[:, 2]


def _by_member(m: np.ndarray, n: int, texts: list[str], sep: str) -> list[str]:
    """The texts of the dashes joined per member (m: each dash's member), "" for none."""
    out: list[list[str]] = [[] for _ in range(n)]
    for owner, t in zip(m.tolist(), texts):
        out[owner].append(t)
    return [sep.join(parts) if parts else "" for parts in out]


def dash_path_data(strokes: Strokes, members: list[int], phase: np.ndarray, pattern: tuple[float, ...],
                   decimals: int = 2) -> list[str]:
    """Each member stroke's dashes (dash_pieces) as the text after "M" of one path, a subpath
    per dash."""
    pts, off, m, _ = dash_pieces(strokes, np.asarray(members, np.int64), phase, pattern)
    text = stroke_path_data(Strokes.build(pts, np.zeros((len(pts), 3)), np.zeros(len(pts)), off,
                                          np.zeros(len(m))), decimals)
    return _by_member(m, len(members), text, " M")


#: The attribute of an outline path holding its centreline (the stroke's points: what strokekit
#: diff compares, metrics.svg_reader).
CENTRELINE = "data-centreline"

def _width_text(w: float) -> str:
    """A stroke-width as written (px, at most 4 decimals)."""
    return format(round(float(w), 4) + 0.0, "g")


def svg_document(strokes: Strokes, width: int, height: int, kinds: tuple[str, ...], *, decimals: int = 2,
                 stroke_width: float = 1.5, underlays: list[str] | None = None,
                 dashes: tuple[float, ...] | None = None, dash_paths: bool = False,
                 styled: StyledStrokes | None = None, lines: str = "outline") -> str:
    """The SVG text of one frame. `kinds` lists the layers to write (the kinds, and hidden-<kind>
    for hidden lines: LineOptions.layers), even when empty; hidden layers come first, under the
    visible lines. `underlays` is a list of SVG elements (text) placed under the line layers (e.g.
    `bands_layer`).

    `styled`: the strokes in their style (strokekit.style.apply_style; `strokes` is then not
    used); None: the default style at `stroke_width`, hidden lines dashed with `dashes`. A layer
    whose strokes belong to one line set carries that set's colour, width and dashes; a layer of
    several sets holds a group per set (id <layer>--<set>, not an Inkscape layer). A stroke of
    one width is its centreline path (stroke-width on the path where it is not the group's); a
    stroke whose width varies is a filled outline (writers.outline) with its centreline in a
    `data-centreline` attribute (what strokekit diff compares). lines "centreline": every
    stroke as its centreline at its mean width (for plotters).

    Dashes (a set's, or for hidden strokes by default the ISO 128 pattern of the set's width): on
    a centreline, the viewer's stroke-dasharray on its group, so the path stays one continuous
    line (strokekit diff compares it, and a dash that moves is no change); each path starts its
    pattern where its texture coordinate says (stroke-dashoffset = u at its first point x the
    period, modulo the pattern): with tracking on, the dashes stay on the surface as the stroke
    grows at either end instead of sliding along it. `dash_paths`: the dashes are written as
    geometry instead (one path per stroke, a subpath per dash, same phase), for tools that ignore
    stroke-dasharray (vpype draws such a path solid). An outline's dashes are always geometry
    (one outline per dash)."""
    if lines not in SVG_LINES:
        raise ValueError(f"lines must be one of {', '.join(SVG_LINES)}, got {lines!r}")
    if styled is None:
        styled = apply_style(strokes, tuple(kinds), Style(width=stroke_width, dashes=dashes))
    strokes = styled.strokes
    out = [_HEAD.format(w=int(width), h=int(height))]
    out += underlays or []
    data = stroke_path_data(strokes, decimals)
    # Strokes by layer (a hidden layer holds every level of its kind), in stroke order within each.
    code = strokes.kind
    lay = code if not len(code) or code.max() < N_KINDS else np.where(code < N_KINDS, code, N_KINDS + code % N_KINDS)
    order = np.argsort(lay, kind="stable")
    lay_sorted = lay[order]
    present = np.unique(lay_sorted).tolist()
    bounds = np.searchsorted(lay_sorted, present).tolist() + [len(order)]
    by_layer = {k: order[a:b] for k, a, b in zip(present, bounds[:-1], bounds[1:])}
    writer = _Paths(styled, data, decimals, dash_paths, lines)
    names = [(N_KINDS + i, "hidden-" + k, k) for i, k in enumerate(KINDS)
             if "hidden-" + k in kinds or N_KINDS + i in by_layer]
    names += [(i, k, k) for i, k in enumerate(KINDS) if k in kinds or i in by_layer]
    for index, name, kind in names:
        hidden = index >= N_KINDS
        members = by_layer.get(index, np.zeros(0, np.int64))
        sets_here = np.unique(styled.lineset[members]).tolist() if len(members) else []
        head = f'<g fill="none" id="layer-{name}" inkscape:groupmode="layer" inkscape:label="{name}" '
        if len(sets_here) <= 1:
            k = sets_here[0] if sets_here else None
            colour, w, pattern = writer.look(k, kind, hidden)
            out.append(head + f'stroke="{colour}"{_dash_attr(pattern, dash_paths)} stroke-linecap="round" '
                       f'stroke-linejoin="round" stroke-width="{w:g}"')
            if not len(members):
                out.append(" />")
                continue
            out.append(">")
            out += writer.paths(members, k, hidden, colour, w, pattern)
            out.append("</g>")
            continue
        out.append(head + 'stroke-linecap="round" stroke-linejoin="round">')
        set_of = styled.lineset[members]
        for k in sets_here:
            colour, w, pattern = writer.look(k, kind, hidden)
            sname = styled.sets[k].name
            out.append(f'<g id="{name}--{sname}" inkscape:label="{sname}" stroke="{colour}"'
                       f'{_dash_attr(pattern, dash_paths)} stroke-width="{w:g}">')
            out += writer.paths(members[set_of == k], k, hidden, colour, w, pattern)
            out.append("</g>")
        out.append("</g>")
    out.append("</svg>\n")
    return "".join(out)


def _dash_attr(pattern: tuple[float, ...], dash_paths: bool) -> str:
    if sum(pattern) > 0 and not dash_paths:
        return ' stroke-dasharray="' + " ".join(f"{x:g}" for x in pattern) + '"'
    return ""


class _Paths:
    """The <path> elements of one frame's strokes, set by set (svg_document)."""

    def __init__(self, styled: StyledStrokes, data: list[str], decimals: int, dash_paths: bool, lines: str):
        self.styled, self.decimals, self.dash_paths, self.lines = styled, decimals, dash_paths, lines
        self.data_col = np.array(data, dtype=object)
        st = styled.strokes
        self.ids = st.ids
        self.outline = ~styled.constant if lines == "outline" else np.zeros(len(st), bool)

    def look(self, k: int | None, kind: str, hidden: bool) -> tuple[str, float, tuple[float, ...]]:
        """(colour, width, dashes) of set k's strokes in a layer of `kind` (k None: an empty
        layer, drawn as the default style would)."""
        st = self.styled
        if k is None:
            w = st.style.width
            d = st.style.dashes if st.style.dashes is not None else iso_dashes(w)
            return KIND_COLORS.get(kind, "#000000"), w, (d if hidden else ())
        return st.color(k, kind), st.set_width(k), st.dashes(k, hidden)

    def phase(self, members: np.ndarray, period: float) -> np.ndarray:
        st = self.styled.strokes
        u0 = st.u[st.offsets[:-1][members]] * st.period_px
        return np.mod(np.where(np.isfinite(u0), u0, 0.0), period)

    def paths(self, members: np.ndarray, k: int | None, hidden: bool, colour: str, w: float,
              pattern: tuple[float, ...]) -> list[str]:
        """The paths of set k's `members` (stroke indices, in order) in a group of this colour,
        width and dash pattern."""
        members = np.asarray(members, np.int64)
        ids = self.ids.take(members)
        period = sum(pattern)
        outline = self.outline[members]
        widths = self.styled.mean_width[members] if self.lines == "centreline" else \
            self.styled.width[self.styled.strokes.offsets[:-1][members]]
        # (an outline's width is its geometry: only centrelines get a stroke-width)
        own = [_width_text(x) if not o else "" for x, o in zip(widths.tolist(), outline.tolist())]
        same_width = [t == f"{w:g}" for t in own]
        if not outline.any() and all(same_width):  # the plain drawing: one % operation a group
            return self._plain(members, ids, period, pattern)
        texts: list[str] = [""] * len(members)
        line = np.flatnonzero(~outline)
        if len(line):
            plain = self._plain(members[line], ids[line], period, pattern, one_each=True)
            for q, t in zip(line.tolist(), plain):
                wt = "" if same_width[q] else f' stroke-width="{own[q]}"'
                texts[q] = t.replace(" />", wt + " />", 1) if wt else t
        ol = np.flatnonzero(outline)
        if len(ol):
            for q, t in zip(ol.tolist(), self._outlines(members[ol], period, pattern)):
                if t:
                    texts[q] = (f'<path d="{t}" id="s{int(ids[q])}" fill="{colour}" stroke="none" '
                                f'{CENTRELINE}="M{self.data_col[members[q]]}" />')
        return [t for t in texts if t]

    def _plain(self, members, ids, period, pattern, one_each: bool = False) -> list[str]:
        """Centreline paths (dashed as the pattern says), as one text (or one per stroke)."""
        data = self.data_col.take(members).tolist()
        ids = ids.tolist()
        st = self.styled.strokes
        if period > 0 and self.dash_paths:
            d = dash_path_data(st, members, self.phase(members, period), pattern, self.decimals)
            out = [f'<path d="M{t}" id="s{i}" />' if t else "" for i, t in zip(ids, d)]
            return out if one_each else ["".join(out)]
        if period > 0:
            phase = (np.round(self.phase(members, period), self.decimals) + 0.0).tolist()
            template = f'<path d="M%s" id="s%d" stroke-dashoffset="%.{self.decimals}f" />'
            cols = list(zip(data, ids, phase))
        else:
            template = '<path d="M%s" id="s%d" />'
            cols = list(zip(data, ids))
        if one_each:
            return [template % c for c in cols]
        return [(template * len(cols)) % tuple(chain.from_iterable(cols))]

    def _outlines(self, members: np.ndarray, period: float, pattern: tuple[float, ...]) -> list[str]:
        """The filled outlines' path data of the members (their dashes', each dash one outline)."""
        st, w = self.styled.strokes, self.styled.width
        if period > 0:
            pts, off, m, wd = dash_pieces(st, members, self.phase(members, period), pattern, w)
            return _by_member(m, len(members), outline_path_data(pts, off, 0.5 * wd, self.decimals), " ")
        return outline_path_data(st.points, st.offsets, 0.5 * w, self.decimals, members=members)
