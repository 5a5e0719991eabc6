"""Numbers as text at fixed decimals, for many numbers at once (the SVG's coordinates)."""

from __future__ import annotations

import numpy as np


def fixed_point_text(v: np.ndarray, decimals: int, sep: np.ndarray) -> bytes | None:
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
