"""SVG per BRIEF 1.3: one Inkscape layer per line kind, one <path> per stroke with id s<stroke id>,
fixed decimals, no timestamps: the same strokes give the same bytes."""

from __future__ import annotations

import numpy as np
import svgwrite
from svgwrite.extensions import Inkscape

from ..model import KINDS, Strokes

KIND_COLORS = {
    "silhouette": "#000000", "border": "#1f4e9c", "crease": "#b3261e", "material": "#2e7d32",
    "nonmanifold": "#8e24aa", "smooth_contour": "#000000", "suggestive": "#555555", "intersection": "#e65100",
}


def path_data(points: np.ndarray, decimals: int = 2) -> str:
    """'M x y x y ...' for (n, 2) pixel points at fixed decimals (implicit line-to after M)."""
    r = np.round(points, decimals) + 0.0  # + 0.0 turns -0.0 into 0.0
    fmt = f"%.{decimals}f"
    return "M" + " ".join(fmt % v for v in r.ravel())


def svg_document(strokes: Strokes, width: int, height: int, kinds: tuple[str, ...], *, decimals: int = 2,
                 stroke_width: float = 1.5, underlays: list | None = None) -> str:
    """The SVG text of one frame. `kinds` lists the layers to write (in KINDS order), even when empty.
    `underlays` is a list of svgwrite elements placed under the line layers (e.g. band polygons)."""
    dwg = svgwrite.Drawing(size=(f"{width}px", f"{height}px"), viewBox=f"0 0 {width} {height}", debug=False)
    ink = Inkscape(dwg)
    for el in underlays or []:
        dwg.add(el)
    by_kind: dict[int, list[int]] = {}
    for s, k in enumerate(strokes.kind):
        by_kind.setdefault(int(k), []).append(s)
    layer_order = [k for k in KINDS if k in kinds or KINDS.index(k) in by_kind]
    for name in layer_order:
        k = KINDS.index(name)
        layer = ink.layer(label=name, id=f"layer-{name}")
        layer.attribs.update({"fill": "none", "stroke": KIND_COLORS.get(name, "#000000"),
                              "stroke-width": f"{stroke_width:g}", "stroke-linecap": "round",
                              "stroke-linejoin": "round"})
        for s in by_kind.get(k, []):
            sl = strokes.stroke(s)
            layer.add(dwg.path(d=path_data(strokes.points[sl], decimals), id=f"s{int(strokes.ids[s])}"))
        dwg.add(layer)
    return dwg.tostring() + "\n"
