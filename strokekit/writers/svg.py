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


KIND_COLORS = {
    "silhouette": "#000000", "border": "#1f4e9c", "crease": "#b3261e", "material": "#2e7d32",
    "nonmanifold": "#8e24aa", "smooth_contour": "#000000", "suggestive": "#555555", "intersection": "#e65100",
}

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
        text = _fixed_point_text(v, decimals, sep)
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


def _fixed_point_text(v: np.ndarray, decimals: int, sep: np.ndarray) -> bytes | None:
    """The text of f"%.{decimals}f" % x for each x of np.round(v, decimals) + 0.0 (float64 (M,)),
    each followed by its byte of `sep`; None when a value is not finite or not below 1e15 once
    scaled. np.round is rint(v 10^d) / 10^d, and %.df of that double is the integer
    k = rint(v 10^d) written with d decimals (the double is within 1e-3 units of k 10^-d), -0
    written as 0: so the digits of k, by integer arithmetic, are the text."""
    t = v * (10.0 ** decimals)
    with np.errstate(invalid="ignore"):
        if not (np.abs(t) < 1e15).all():
            return None
    k = np.rint(t).astype(np.int64)
    neg = k < 0
    a = np.abs(k)
    ndig = max(decimals + 1, len(str(int(a.max()))))
    cols = ndig + (decimals > 0) + 2  # sign, digits, point, separator
    # Right-aligned in a (M, cols) byte table; 0xFF fills the left of each number and is deleted
    # from the bytes at the end.
    m = np.empty((len(k), cols), np.uint8)
    m[:, -1] = sep
    m[:, 0] = 255
    c = cols - 2
    for j in range(ndig):
        if j == decimals and decimals > 0:
            m[:, c] = 46  # '.'
            c -= 1
        q = a // 10
        if j <= decimals:
            m[:, c] = a - 10 * q + 48
        else:  # a digit left of the first: 255 where a == 0 (no more digits)
            m[:, c] = _DIGIT_OR_FILL.take(a - 10 * q + 10 * (a == 0))
        a = q
        c -= 1
    if neg.any():  # '-' just left of the first digit
        rows = np.flatnonzero(neg)
        first = np.full(len(rows), cols - 2 - decimals - (decimals > 0))  # column of the ones digit
        a = np.abs(k.take(rows))
        for j in range(decimals + 1, ndig):
            first -= a >= 10 ** j
        m[rows, first - 1] = 45
    return m.tobytes().translate(None, b"\xff")


_DIGIT_OR_FILL = np.array([48, 49, 50, 51, 52, 53, 54, 55, 56, 57, 255], np.uint8)


_POINT_FORMATS: dict[int, dict[int, str]] = {}


def iso_dashes(stroke_width: float) -> tuple[float, float]:
    """ISO 128-20 line type 02 (dashed: hidden outlines and edges): dashes 12 line widths long,
    gaps of 3 (px)."""
    return 12.0 * stroke_width, 3.0 * stroke_width


def dash_path_data(strokes: Strokes, members: list[int], phase: np.ndarray, pattern: tuple[float, ...],
                   decimals: int = 2) -> list[str]:
    """Each member stroke's dashes as the text after "M" of one path, a subpath per dash: the
    pattern (on, off, ...; px) laid along the stroke from `phase` (px into the pattern at its
    start), dash ends interpolated on the polyline, the points between kept (a dash follows
    the curve)."""
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
    P = strokes.points
    inner = np.maximum(i1 - i0, 0)  # stroke points strictly inside the dash
    counts = inner + 2
    off = np.concatenate([[0], np.cumsum(counts)])
    pts = np.empty((int(off[-1]), 2))
    pts[off[:-1]] = P[h0] + t0[:, None] * (P[i0] - P[h0])
    pts[off[1:] - 1] = P[h1] + t1[:, None] * (P[i1] - P[h1])
    r = np.repeat(np.arange(len(m)), inner)
    q = np.arange(int(inner.sum())) - np.repeat(np.cumsum(inner) - inner, inner)
    pts[off[:-1][r] + 1 + q] = P[i0[r] + q]
    text = stroke_path_data(Strokes.build(pts, np.zeros((len(pts), 3)), np.zeros(len(pts)), off,
                                          np.zeros(len(m))), decimals)
    out = [[] for _ in members]
    for owner, t in zip(m.tolist(), text):
        out[owner].append(t)
    return [" M".join(parts) if parts else "" for parts in out]


def svg_document(strokes: Strokes, width: int, height: int, kinds: tuple[str, ...], *, decimals: int = 2,
                 stroke_width: float = 1.5, underlays: list[str] | None = None,
                 dashes: tuple[float, ...] | None = None, dash_paths: bool = False) -> str:
    """The SVG text of one frame. `kinds` lists the layers to write (the kinds, and hidden-<kind>
    for hidden lines: LineOptions.layers), even when empty; hidden layers come first, under the
    visible lines. `underlays` is a list of SVG elements (text) placed under the line layers (e.g.
    `bands_layer`).

    Hidden layers are dashed with `dashes` (px, SVG stroke-dasharray, on the layer; None: the ISO
    128 pattern for the stroke width, (): solid): the dashes are the viewer's, so the path stays
    one continuous line (strokekit diff compares it, and a dash that moves is no change). Each
    hidden path starts its pattern where its texture coordinate says (stroke-dashoffset = u at its
    first point x the period, modulo the pattern): with tracking on, the dashes stay on the
    surface as the stroke grows at either end instead of sliding along it. `dash_paths`: the dashes
    are written as geometry instead (one path per stroke, a subpath per dash, same phase), for
    tools that ignore stroke-dasharray (vpype draws such a path solid)."""
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
    # Per-stroke columns gathered per layer by numpy (a hidden drawing has thousands of strokes).
    data_col = np.array(data, dtype=object)
    ids = strokes.ids
    names = [(N_KINDS + i, "hidden-" + k, k) for i, k in enumerate(KINDS)
             if "hidden-" + k in kinds or N_KINDS + i in by_layer]
    names += [(i, k, k) for i, k in enumerate(KINDS) if k in kinds or i in by_layer]
    pattern = iso_dashes(stroke_width) if dashes is None else tuple(float(x) for x in dashes)
    period = sum(pattern)
    for index, name, kind in names:
        hidden = index >= N_KINDS
        dash = ""
        if hidden and period > 0 and not dash_paths:
            dash = ' stroke-dasharray="' + " ".join(f"{x:g}" for x in pattern) + '"'
        group = (f'<g fill="none" id="layer-{name}" inkscape:groupmode="layer" inkscape:label="{name}" '
                 f'stroke="{KIND_COLORS.get(kind, "#000000")}"{dash} stroke-linecap="round" stroke-linejoin="round" '
                 f'stroke-width="{stroke_width:g}"')
        members = by_layer.get(index, ())
        if not len(members):
            out.append(group + " />")
            continue
        out.append(group + ">")
        if hidden and period > 0 and dash_paths:
            u0 = strokes.u[strokes.offsets[:-1][members]] * strokes.period_px
            phase = np.mod(np.where(np.isfinite(u0), u0, 0.0), period)
            d = dash_path_data(strokes, members, phase, pattern, decimals)
            out += [f'<path d="M{t}" id="s{i}" />' for i, t in zip(ids.take(members).tolist(), d) if t]
        elif dash:
            u0 = strokes.u[strokes.offsets[:-1][members]] * strokes.period_px
            phase = np.round(np.mod(np.where(np.isfinite(u0), u0, 0.0), period), decimals) + 0.0
            template = f'<path d="M%s" id="s%d" stroke-dashoffset="%.{decimals}f" />'
            out.append((template * len(members)) % tuple(
                chain.from_iterable(zip(data_col.take(members).tolist(), ids.take(members).tolist(), phase.tolist()))))
        else:
            out.append(('<path d="M%s" id="s%d" />' * len(members)) % tuple(
                chain.from_iterable(zip(data_col.take(members).tolist(), ids.take(members).tolist()))))
        out.append("</g>")
    out.append("</svg>\n")
    return "".join(out)
