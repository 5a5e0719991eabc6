"""Compiled loop (numba) of the filled outlines' path data (strokekit.writers.outline): each
stroke's closed path, walked and written as text in one pass (the same tokens and the same
digits as outline.py's numpy writer, which stays their reference). Imports numpy and numba only;
loaded on first use by `outline.outline_kernels()`."""

from __future__ import annotations

import math

import numba
import numpy as np

from strokekit.numba_cache import kernel

_M, _L, _A = 0, 1, 2


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _number(buf, n, v, scale, decimals):
    """Write "%.{decimals}f" % (np.round(v, decimals) + 0.0) at buf[n:]: the integer
    rint(v 10^decimals) with `decimals` decimals (-0 written as 0). Returns the new end."""
    k = np.int64(np.rint(v * scale))
    if k < 0:
        buf[n] = 45
        n += 1
        k = -k
    u = np.uint64(k)  # (unsigned: plain division by 10, no floor rounding of negatives)
    ten = np.uint64(10)
    nd = 1  # its digits, at least decimals + 1
    p = ten
    while nd < 19 and u >= p:
        nd += 1
        p *= ten
    if nd < decimals + 1:
        nd = decimals + 1
    c = n + nd + (1 if decimals > 0 else 0) - 1
    end = c + 1
    for _ in range(decimals):
        q = u // ten
        buf[c] = np.uint8(48 + (u - q * ten))
        u = q
        c -= 1
    if decimals > 0:
        buf[c] = 46
        c -= 1
    while c >= n:
        q = u // ten
        buf[c] = np.uint8(48 + (u - q * ten))
        u = q
        c -= 1
    return end


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _token(buf, n, first, prev_cmd, cmd, x, y, r, cx, cy, px, py, scale, decimals):
    """One token of a path (after its separator from the one before): M/L x y, A r r 0 0 f x y."""
    if not first:
        if cmd == _A:
            buf[n], buf[n + 1] = 32, 65  # " A"
            n += 2
        elif cmd == _L and prev_cmd == _A:
            buf[n], buf[n + 1] = 32, 76  # " L"
            n += 2
        else:
            buf[n] = 32
            n += 1
    if cmd == _A:
        n = _number(buf, n, r, scale, decimals)
        buf[n] = 32
        n = _number(buf, n + 1, r, scale, decimals)
        cr = (px - cx) * (y - cy) - (py - cy) * (x - cx)
        buf[n], buf[n + 1], buf[n + 2], buf[n + 3], buf[n + 4], buf[n + 5] = 32, 48, 32, 48, 32, 49 if cr > 0 else 48
        buf[n + 6] = 32
        n += 7
    n = _number(buf, n, x, scale, decimals)
    buf[n] = 32
    return _number(buf, n + 1, y, scale, decimals)


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _unit(P, a, b):
    dx, dy = P[b, 0] - P[a, 0], P[b, 1] - P[a, 1]
    ln = math.sqrt(dx * dx + dy * dy)
    return dx / ln, dy / ln


@kernel("(f8[:, ::1], i8[::1], f8[::1], i8[::1], i8, f8, i8)", error_model="numpy")
def outline_text(P, offsets, R, members, decimals, straight, cap):
    """The path data ('M ... Z', ASCII) of the filled outline of each stroke `members` (points P
    (N, 2) px grouped by offsets, radii R (N,)), in one byte buffer of `cap` bytes (enough: the
    caller's bound): (bytes, ends (len(members),), each stroke's end in the bytes). Consecutive
    points that coincide (1e-9 px) are one; a stroke of one point is a disc; joins turning by
    at most `straight` (the cross product of the directions) are drawn straight."""
    buf = np.empty(cap, np.uint8)
    ends = np.empty(members.shape[0], np.int64)
    scale = 10.0 ** decimals
    idx = np.empty(P.shape[0], np.int64)
    TX = np.empty(P.shape[0], np.float64)  # each segment's unit direction, found once
    TY = np.empty(P.shape[0], np.float64)
    n = 0
    for q in range(members.shape[0]):
        s = members[q]
        # the stroke's points, coincident neighbours dropped
        cnt = 0
        for i in range(offsets[s], offsets[s + 1]):
            if i > offsets[s]:
                dx, dy = P[i, 0] - P[i - 1, 0], P[i, 1] - P[i - 1, 1]
                if math.sqrt(dx * dx + dy * dy) <= 1e-9:
                    continue
            idx[cnt] = i
            cnt += 1
        if cnt == 0:
            ends[q] = n
            continue
        buf[n] = 77  # M
        n += 1
        px, py = 0.0, 0.0  # the pen: the start of an arc
        if cnt == 1:
            c = idx[0]
            r = R[c]
            cx, cy = P[c, 0], P[c, 1]
            x, y = cx + r * 1.0, cy + r * 0.0
            n = _token(buf, n, True, _M, _M, x, y, 0.0, 0.0, 0.0, 0.0, 0.0, scale, decimals)
            px, py = x, y
            for vx, vy in ((0.0, 1.0), (-1.0, 0.0), (0.0, -1.0), (1.0, 0.0)):
                x, y = cx + r * vx, cy + r * vy
                n = _token(buf, n, False, _A, _A, x, y, r, cx, cy, px, py, scale, decimals)
                px, py = x, y
            buf[n] = 90  # Z
            n += 1
            ends[q] = n
            continue
        m = cnt - 1
        for k in range(m):
            TX[k], TY[k] = _unit(P, idx[k], idx[k + 1])
        # the left side forward, with the joins at its points
        a0 = idx[0]
        tx, ty = TX[0], TY[0]
        x, y = P[a0, 0] + -ty * R[a0], P[a0, 1] + tx * R[a0]
        n = _token(buf, n, True, _M, _M, x, y, 0.0, 0.0, 0.0, 0.0, 0.0, scale, decimals)
        prev = _M
        for k in range(m):
            a, b = idx[k], idx[k + 1]
            tx, ty = TX[k], TY[k]
            x, y = P[b, 0] + -ty * R[b], P[b, 1] + tx * R[b]
            n = _token(buf, n, False, prev, _L, x, y, 0.0, 0.0, 0.0, 0.0, 0.0, scale, decimals)
            prev = _L
            px, py = x, y
            if k < m - 1:
                n, prev, px, py = _join(buf, n, prev, P, R, TX[k], TY[k], b, TX[k + 1], TY[k + 1], 1.0, px, py,
                                        straight, scale, decimals)
        # the round cap at the end
        b = idx[m]
        tx, ty = TX[m - 1], TY[m - 1]
        r = R[b]
        cx, cy = P[b, 0], P[b, 1]
        x, y = cx + tx * r, cy + ty * r
        n = _token(buf, n, False, prev, _A, x, y, r, cx, cy, px, py, scale, decimals)
        px, py = x, y
        x, y = cx - -ty * r, cy - tx * r
        n = _token(buf, n, False, _A, _A, x, y, r, cx, cy, px, py, scale, decimals)
        prev = _A
        px, py = x, y
        # the right side back
        for k in range(m - 1, -1, -1):
            a = idx[k]
            tx, ty = TX[k], TY[k]
            x, y = P[a, 0] - -ty * R[a], P[a, 1] - tx * R[a]
            n = _token(buf, n, False, prev, _L, x, y, 0.0, 0.0, 0.0, 0.0, 0.0, scale, decimals)
            prev = _L
            px, py = x, y
            if k > 0:
                n, prev, px, py = _join(buf, n, prev, P, R, TX[k - 1], TY[k - 1], a, TX[k], TY[k], -1.0, px, py,
                                        straight, scale, decimals)
        # the round cap at the start
        a = idx[0]
        tx, ty = TX[0], TY[0]
        r = R[a]
        cx, cy = P[a, 0], P[a, 1]
        x, y = cx - tx * r, cy - ty * r
        n = _token(buf, n, False, prev, _A, x, y, r, cx, cy, px, py, scale, decimals)
        px, py = x, y
        x, y = cx + -ty * r, cy + tx * r
        n = _token(buf, n, False, _A, _A, x, y, r, cx, cy, px, py, scale, decimals)
        buf[n] = 90  # Z
        n += 1
        ends[q] = n
    return buf[:n].copy(), ends


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _join(buf, n, prev, P, R, tax, tay, v, tbx, tby, side, px, py, straight, scale, decimals):
    """The join at point v between the segments of directions (tax, tay) into v and (tbx, tby) out
    of it, on the left (side 1, walking forward) or the right (side -1, walking back): the outer
    side an arc (two past 90 degrees), the inner side through the point itself. Returns (end,
    last command, pen x, pen y)."""
    nax, nay = -tay, tax
    nbx, nby = -tby, tbx
    cross = tax * tby - tay * tbx
    dot = tax * tbx + tay * tby
    if abs(cross) <= straight and dot > 0:
        return n, prev, px, py
    outer = cross <= 0 if side > 0 else not cross <= 0
    rv = R[v]
    cx, cy = P[v, 0], P[v, 1]
    ex, ey = (nbx, nby) if side > 0 else (nax, nay)
    x, y = cx + (side * ex) * rv, cy + (side * ey) * rv
    if outer:
        if dot < 0:  # past 90 degrees: the arc in two, through the middle
            mx, my = nax + nbx, nay + nby
            ml = math.sqrt(mx * mx + my * my)
            if ml <= 1e-9:
                hx, hy = tax, tay
            else:
                d = max(ml, 1e-300)
                hx, hy = side * (mx / d), side * (my / d)
            qx, qy = cx + hx * rv, cy + hy * rv
            n = _token(buf, n, False, prev, _A, qx, qy, rv, cx, cy, px, py, scale, decimals)
            prev, px, py = _A, qx, qy
        n = _token(buf, n, False, prev, _A, x, y, rv, cx, cy, px, py, scale, decimals)
        return n, _A, x, y
    n = _token(buf, n, False, prev, _L, cx, cy, 0.0, 0.0, 0.0, 0.0, 0.0, scale, decimals)
    n = _token(buf, n, False, _L, _L, x, y, 0.0, 0.0, 0.0, 0.0, 0.0, scale, decimals)
    return n, _L, x, y
