"""Compiled loop (numba) of the widths (strokekit.style.widths): the modifiers' width at every
point of a frame's strokes and at even samples along each segment, and the samples the width
drawn linearly between points needs, in one pass. The formulas are strokekit.style.widths' (its
module doc); the numpy `modifier_factor` there is their reference. Imports numpy and numba
only; loaded on first use by `widths.style_kernels()`."""

from __future__ import annotations

import math

import numba
import numpy as np

from strokekit.numba_cache import kernel

#: Modifier codes: the first column of the kernels' modifier table.
ALONG, DEPTH, CURVATURE, CALLIGRAPHY, NOISE = 0, 1, 2, 3, 4

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _mix(x):
    x = (x ^ (x >> np.uint64(30))) * _M1
    x = (x ^ (x >> np.uint64(27))) * _M2
    return x ^ (x >> np.uint64(31))


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _lattice(key, i):
    h = _mix(key + np.uint64(i) * _GOLDEN)
    return np.float64(h >> np.uint64(11)) * (2.0 ** -52) - 1.0


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _noise(x, key):
    f = math.floor(x)
    t = x - f
    t = t * t * (3.0 - 2.0 * t)
    i0 = np.int64(f)
    v0 = _lattice(key, i0)
    v1 = _lattice(key, i0 + 1)
    return v0 + (v1 - v0) * t


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _point_at(P, arc, first, last, s, h):
    """The point at arc length s of the stroke of points first..last (held at its ends), found by
    walking from point h (s is a few px from it: the walk is a step or two)."""
    if s <= arc[first] or last == first:
        return P[first, 0], P[first, 1]
    if s >= arc[last]:
        return P[last, 0], P[last, 1]
    lo = min(max(h, first), last - 1)  # to the last point at or before s: arc[lo] <= s < arc[lo + 1]
    while lo > first and arc[lo] > s:
        lo -= 1
    while lo < last - 1 and arc[lo + 1] <= s:
        lo += 1
    hi = lo + 1
    a = (s - arc[lo]) / (arc[hi] - arc[lo])
    return P[lo, 0] + a * (P[hi, 0] - P[lo, 0]), P[lo, 1] + a * (P[hi, 1] - P[lo, 1])


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _width(k, s, h, px, py, u, z, P, arc, first, last, L, base, mods, m0, m1, ends, keys, period, min_w):
    """The width at arc length s of stroke k, near its point h (position px, py, texture coordinate u, view depth z):
    base times modifiers m0..m1 of the table `mods` in order, at least min_w."""
    f = 1.0
    for r in range(m0, m1):
        code = int(mods[r, 0])
        if code == ALONG:
            c = int(mods[r, 2])
            head, tail, tip = ends[k, 2 * c], ends[k, 2 * c + 1], mods[r, 1]
            grow = 1.0
            if head > 0:
                x = min(max(s / head, 0.0), 1.0)
                grow = x * (2.0 - x)
            fade = 1.0
            if tail > 0:
                x = min(max((L - s) / tail, 0.0), 1.0)
                fade = x * (2.0 - x)
            g = tip + (1 - tip) * min(grow, fade)
        elif code == DEPTH:
            near, far, zn, zf, known = mods[r, 1], mods[r, 2], mods[r, 3], mods[r, 4], mods[r, 5]
            if known == 0.0:
                g = near
            else:
                t = 0.0
                if zf > zn:
                    t = (z - zn) / (zf - zn)
                    t = 0.5 if math.isnan(t) else min(max(t, 0.0), 1.0)  # (an unknown depth: the middle)
                g = near + (far - near) * t
        elif code == CURVATURE:
            flat, curved, radius, span = mods[r, 1], mods[r, 2], mods[r, 3], mods[r, 4]
            a, b = min(span, s), min(span, L - s)
            qx, qy = _point_at(P, arc, first, last, s - a, h)
            c1x, c1y = px - qx, py - qy
            qx, qy = _point_at(P, arc, first, last, s + b, h)
            c2x, c2y = qx - px, qy - py
            ang = math.atan2(abs(c1x * c2y - c1y * c2x), c1x * c2x + c1y * c2y)
            kap = 0.0
            if a >= mods[r, 5] and b >= mods[r, 5] and c1x * c1x + c1y * c1y > 1e-24 and c2x * c2x + c2y * c2y > 1e-24:
                kap = ang / (0.5 * (a + b))
            g = flat + (curved - flat) * min(max(kap * radius, 0.0), 1.0)
        elif code == CALLIGRAPHY:
            # |sin(theta - angle)|, theta the direction of d (y up): |sin theta cos angle - cos theta sin angle|
            thin, span, ca, sa = mods[r, 2], mods[r, 3], mods[r, 4], mods[r, 5]
            a, b = min(span, s), min(span, L - s)
            qx, qy = _point_at(P, arc, first, last, s + b, h)
            ox, oy = _point_at(P, arc, first, last, s - a, h)
            dx, dy = qx - ox, qy - oy
            d2 = dx * dx + dy * dy
            if d2 > 1e-24:
                g = thin + (1 - thin) * min(abs(-dy * ca - dx * sa) / math.sqrt(d2), 1.0)
            else:
                g = 1.0
        else:  # NOISE
            amp, wl = mods[r, 1], mods[r, 2]
            uu = u if math.isfinite(u) else s / period
            g = 1.0 + amp * _noise(uu * period / wl, keys[k, int(mods[r, 3])])
        f = f * g
    return max(base * f, min_w)


@kernel("(f8[:, ::1], f8[::1], f8[::1], f8[::1], i8[::1], i8[::1], f8[::1], f8[::1], f8[:, ::1], i8[::1],"
        " f8[:, ::1], u8[:, ::1], b1, f8, f8, f8, f8)", error_model="numpy")
def fit_widths(P, arc, u, z, offsets, which, length, base, mods, mod_start, ends, keys, persp, period, min_w, tol,
               sample_px):
    """The widths of strokes (points P (N, 2) px grouped by offsets (S + 1,), arc their arc lengths
    from each stroke's start, u, z their texture coordinates and view depths; stroke k drawn by
    set which[k] of base width base[set] and modifiers mods[mod_start[set]:mod_start[set + 1]];
    `length` (S,); ends (S, 2 x along modifiers): each along modifier's head and tail per stroke;
    keys (S, noise modifiers): each noise's hash key per stroke; persp: the depth between two
    points is 1/z linear) at their points and at samples splitting each segment evenly, at most
    sample_px apart; of the samples, those kept that the width drawn linearly between kept ones
    needs to be within tol of the width at every sample (the farthest off first, then each side
    again). Returns (seg (M,), a (M,), w (M,)), the strokes' points in order: each on the segment
    from point seg to seg + 1 at fraction a (0: the point seg itself), and its width."""
    N = P.shape[0]
    S = offsets.shape[0] - 1
    most = 1  # the most samples a segment is split into
    for k in range(S):
        for i in range(offsets[k], offsets[k + 1] - 1):
            d = arc[i + 1] - arc[i]
            if d > sample_px:
                most = max(most, int(math.ceil(d / sample_px)))
    ws = np.empty(most + 1, np.float64)
    keep = np.zeros(most + 1, np.bool_)
    todo = np.empty(2 * most + 2, np.int64)  # (from, to) sample ranges still to look at
    cap = 2 * N + 16
    seg = np.empty(cap, np.int64)
    frac = np.empty(cap, np.float64)
    wid = np.empty(cap, np.float64)
    w_pt = np.empty(N, np.float64)
    m = 0
    for k in range(S):
        first, last = offsets[k], offsets[k + 1] - 1
        if last < first:
            continue
        ls = which[k]
        m0, m1 = mod_start[ls], mod_start[ls + 1]
        L, b = length[k], base[ls]
        for i in range(first, last + 1):
            w_pt[i] = _width(k, arc[i], i, P[i, 0], P[i, 1], u[i], z[i], P, arc, first, last, L, b, mods, m0, m1, ends,
                             keys, period, min_w)
        for i in range(first, last + 1):
            if m + 1 >= cap:
                cap *= 2
                seg, frac, wid = _grow(seg, cap), _grow(frac, cap), _grow(wid, cap)
            seg[m], frac[m], wid[m] = i, 0.0, w_pt[i]
            m += 1
            if i == last or m1 == m0:
                continue
            s0, d = arc[i], arc[i + 1] - arc[i]
            if not d > sample_px:
                continue
            n = int(math.ceil(d / sample_px))
            ws[0], ws[n] = w_pt[i], w_pt[i + 1]
            for j in range(1, n):
                a = j / n
                px = P[i, 0] + a * (P[i + 1, 0] - P[i, 0])
                py = P[i, 1] + a * (P[i + 1, 1] - P[i, 1])
                uu = u[i] + a * (u[i + 1] - u[i])
                if persp:
                    zz = 1.0 / ((1 - a) / z[i] + a / z[i + 1])
                else:
                    zz = z[i] + a * (z[i + 1] - z[i])
                ws[j] = _width(k, s0 + a * d, i, px, py, uu, zz, P, arc, first, last, L, b, mods, m0, m1, ends, keys,
                               period, min_w)
                keep[j] = False
            todo[0], todo[1] = 0, n
            top, added = 2, 0
            while top > 0:
                lo, hi = todo[top - 2], todo[top - 1]
                top -= 2
                if hi - lo < 2:
                    continue
                w0, slope = ws[lo], (ws[hi] - ws[lo]) / (hi - lo)
                far, at = -1.0, -1
                for j in range(lo + 1, hi):
                    off = abs(ws[j] - (w0 + slope * (j - lo)))
                    if off > far:
                        far, at = off, j
                if far > tol:
                    keep[at] = True
                    added += 1
                    todo[top], todo[top + 1], todo[top + 2], todo[top + 3] = lo, at, at, hi
                    top += 4
            if added == 0:
                continue
            while m + added + 1 >= cap:
                cap *= 2
                seg, frac, wid = _grow(seg, cap), _grow(frac, cap), _grow(wid, cap)
            for j in range(1, n):
                if keep[j]:
                    seg[m], frac[m], wid[m] = i, j / n, ws[j]
                    m += 1
    return seg[:m].copy(), frac[:m].copy(), wid[:m].copy()


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _grow(a, cap):
    out = np.empty(cap, a.dtype)
    out[:a.shape[0]] = a
    return out


@kernel("(f8[:, ::1], f8[::1], f8[:, ::1], f8[::1], i8[::1], f8[::1], b1)", error_model="numpy")
def spread(P, u, X, z, seg, frac, persp):
    """The points fit_widths returned (seg, frac): their positions (M, 2), texture coordinates (M,)
    and surface points (M, 3) from the points P, u, X (view depths z) they lie between: position
    and u linear, the surface point as sampling.surface_between (1/z linear on screen, where
    `persp` and both depths are positive)."""
    M = seg.shape[0]
    Po = np.empty((M, 2))
    uo = np.empty(M)
    Xo = np.empty((M, 3))
    for q in range(M):
        i, a = seg[q], frac[q]
        if a == 0.0:
            Po[q, 0], Po[q, 1], uo[q] = P[i, 0], P[i, 1], u[i]
            Xo[q, 0], Xo[q, 1], Xo[q, 2] = X[i, 0], X[i, 1], X[i, 2]
            continue
        j = i + 1
        Po[q, 0] = P[i, 0] + a * (P[j, 0] - P[i, 0])
        Po[q, 1] = P[i, 1] + a * (P[j, 1] - P[i, 1])
        uo[q] = u[i] + a * (u[j] - u[i])
        b = a
        if persp and z[i] > 0 and z[j] > 0:
            den = (1 - a) * z[j] + a * z[i]
            if den > 0:
                b = a * z[i] / den
        for c in range(3):
            Xo[q, c] = X[i, c] * (1 - b) + X[j, c] * b
    return Po, uo, Xo
