"""The strokes as a raster: per line kind, the anti-aliased coverage of its strokes drawn with
round caps and joins at the strokes' widths (per point, linear along each segment, as the SVG
draws them), for compositing without an SVG renderer.

Coverage of a pixel is the area of the pixel square inside the band of width w around the nearest
segment of the stroke (w the width at the nearest point of the segment), as an area-sampling
renderer (cairo, Inkscape) draws it: with d the
distance from the pixel centre to the segment and n the direction from the segment to the centre,
the square projected on n spreads over a trapezoid, and the coverage is the part of it within
w / 2 of the segment. Overlapping segments take the larger coverage (not the sum), so joins and
crossings of one kind do not darken.
"""

from __future__ import annotations

import math

import numpy as np

from strokekit.model import KINDS, N_KINDS, Strokes

_KERNEL = None


def _cdf(x: float, a: float, b: float) -> float:
    """P(X <= x) for X the projection of a uniform point of the unit pixel square on a unit
    direction (nx, ny), a = max(|nx|, |ny|), b = min(...): the sum of two uniform variables."""
    c = 0.5 * (a + b)
    if x <= -c:
        return 0.0
    if x >= c:
        return 1.0
    if b < 1e-9:
        return (x + 0.5 * a) / a
    e = 0.5 * (a - b)
    if x <= -e:
        return (x + c) * (x + c) / (2.0 * a * b)
    if x < e:
        return (x + 0.5 * a) / a
    return 1.0 - (c - x) * (c - x) / (2.0 * a * b)


#: _cdf as _cover calls it: compiled with it by `_kernel`.
_cdf_jit = _cdf


def _cover(points: np.ndarray, seg_a: np.ndarray, seg_b: np.ndarray, radii: np.ndarray, out: np.ndarray) -> None:
    """Max-composite the coverage of segments points[seg_a] -> points[seg_b] into out (H, W), of
    half width radii[seg_a] at the start and radii[seg_b] at the end."""
    H, W = out.shape
    for m in range(len(seg_a)):
        ax, ay = points[seg_a[m], 0], points[seg_a[m], 1]
        bx, by = points[seg_b[m], 0], points[seg_b[m], 1]
        ra, rb = radii[seg_a[m]], radii[seg_b[m]]
        reach = max(ra, rb) + 0.5
        x0 = max(0, int(math.floor(min(ax, bx) - reach)))
        x1 = min(W - 1, int(math.ceil(max(ax, bx) + reach)))
        y0 = max(0, int(math.floor(min(ay, by) - reach)))
        y1 = min(H - 1, int(math.ceil(max(ay, by) + reach)))
        dx, dy = bx - ax, by - ay
        L2 = dx * dx + dy * dy
        for y in range(y0, y1 + 1):
            py = y + 0.5
            for x in range(x0, x1 + 1):
                px = x + 0.5
                t = 0.0
                if L2 > 0.0:
                    t = ((px - ax) * dx + (py - ay) * dy) / L2
                    t = min(1.0, max(0.0, t))
                ex, ey = px - (ax + t * dx), py - (ay + t * dy)
                radius = ra + t * (rb - ra)
                d = math.sqrt(ex * ex + ey * ey)
                if d >= reach + 0.25:  # beyond the projected square's reach (at most sqrt(2) / 2)
                    continue
                if d > 0.0:
                    nx, ny = abs(ex) / d, abs(ey) / d
                elif L2 > 0.0:
                    nx, ny = abs(dy) / math.sqrt(L2), abs(dx) / math.sqrt(L2)
                else:
                    nx, ny = 1.0, 0.0
                a, b = max(nx, ny), min(nx, ny)
                c = _cdf_jit(radius - d, a, b) - _cdf_jit(-radius - d, a, b)
                if c > out[y, x]:
                    out[y, x] = c


def _kernel():
    """_cover compiled by numba (an optional backend: loaded only when a lines raster is asked
    for; compiled once per machine, cached on disk)."""
    global _KERNEL
    if _KERNEL is None:
        import numba

        global _cdf_jit
        _cdf_jit = numba.njit(cache=True)(_cdf)
        _KERNEL = numba.njit(cache=True, nogil=True)(_cover)
    return _KERNEL


def stroke_coverage(strokes: Strokes, width: int, height: int, stroke_width_px) -> dict[str, np.ndarray]:
    """{kind: (height, width) float32 coverage in [0, 1]} of every line kind that has visible
    strokes, in KINDS order; strokes (px) drawn stroke_width_px wide: one width, or (N,) at each
    point (strokekit.style's). Hidden lines (occlusion level >= 1, dashed in the SVG) are not
    drawn."""
    out: dict[str, np.ndarray] = {}
    if len(strokes) == 0:
        return out
    pts = np.ascontiguousarray(strokes.points, np.float64)
    sop = strokes.stroke_of_point
    n = len(pts)
    inner = np.flatnonzero(sop[:-1] == sop[1:]) if n > 1 else np.zeros(0, np.int64)
    lone = strokes.offsets[:-1][np.diff(strokes.offsets) == 1]  # one-point strokes: a dot
    seg_a = np.concatenate([inner, lone]).astype(np.int64)
    seg_b = np.concatenate([inner + 1, lone]).astype(np.int64)
    kind_of_seg = strokes.kind[sop[seg_a]]
    radii = np.ascontiguousarray(np.broadcast_to(0.5 * np.asarray(stroke_width_px, np.float64), (n,)))
    cover = _kernel()
    for k in np.unique(kind_of_seg[kind_of_seg < N_KINDS]):
        img = np.zeros((int(height), int(width)), np.float32)
        sel = kind_of_seg == k
        cover(pts, seg_a[sel], seg_b[sel], radii, img)
        out[KINDS[int(k)]] = img
    return {name: out[name] for name in KINDS if name in out}
