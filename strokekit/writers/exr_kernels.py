"""The EXR writer's compiled loops (numba; `writers.exr` loads them on first use): a scanline
file's chunks, packed from the channel planes and RLE-compressed the way OpenEXR does it.

OpenEXR's RLE and ZIP codecs both first reorder a block's bytes (even bytes, then odd ones) and
replace each byte by its difference from the one before plus 128; RLE then writes runs of 3 to
128 equal bytes as (count - 1, byte) and the rest as (-count, count bytes) (ImfRle.cpp). A block
that would not shrink is stored as it is, as OpenEXR does.

The planes are read a whole pixel at a time (a plane: the flat bytes of a contiguous (H, W)
half or float32 image); a float32 plane may be written as half, converted as numpy converts it.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from strokekit.numba_cache import kernel

MIN_RUN = 3
MAX_RUN = 127
#: A byte repeated over a uint64, and each byte's high bit.
_REPEAT = np.uint64(0x0101010101010101)
_HIGH = np.uint64(0x8080808080808080)


@njit(cache=True)
def _word(pw, i):
    """The 8 bytes from byte i of pw (uint64 words, little-endian) as one uint64."""
    k = i >> 3
    sh = np.uint64(8 * (i & 7))
    if sh == 0:
        return pw[k]
    return (pw[k] >> sh) | (pw[k + 1] << (np.uint64(64) - sh))


@njit(cache=True)
def _half_bits(f):
    """The half float bits numpy's float32 -> float16 cast gives float32 bits f (int64): rounded
    to nearest even, overflow to inf, NaN kept NaN with its payload's high bits."""
    sign = (f >> 16) & 0x8000
    e = f & 0x7F800000
    if e >= 0x47800000:
        if e == 0x7F800000 and f & 0x7FFFFF:
            r = 0x7C00 + ((f & 0x7FFFFF) >> 13)
            return sign + (r + 1 if r == 0x7C00 else r)
        return sign | 0x7C00
    if e <= 0x38000000:  # subnormal half, or zero
        if e < 0x33000000:
            return sign
        sig = (0x800000 + (f & 0x7FFFFF)) >> (113 - (e >> 23))
        if (sig & 0x3FFF) != 0x1000 or f & 0x7FF:
            sig += 0x1000
        return sign + (sig >> 13)
    sig = f & 0x7FFFFF
    if (sig & 0x3FFF) != 0x1000:
        sig += 0x1000
    return sign + (sig >> 13) + ((e - 0x38000000) >> 13)


@njit(cache=True)
def _pack(planes, item, half, sp, width, y0, y1, out):
    """Rows y0..y1 - 1 as the file stores them uncompressed into out: each row's channels in file
    order (plane c: `width` pixels of item[c] bytes a row, or float32 pixels written as half
    where half[c], or a sparse half plane: `_sparse_row`); returns their size."""
    n = 0
    for y in range(y0, y1):
        for c in range(len(planes)):
            rb = width * item[c]
            if sp[0][c] >= 0:
                lo = np.zeros(width, np.uint8)
                hi = np.zeros(width, np.uint8)
                _sparse_row(sp, c, y, width, lo, hi)
                dst = out[n:n + rb]
                for x in range(width):
                    dst[2 * x] = lo[x]
                    dst[2 * x + 1] = hi[x]
            elif half[c]:
                src = planes[c].view(np.uint32)[y * width:(y + 1) * width]
                dst = out[n:n + rb]
                for x in range(width):
                    h = _half_bits(np.int64(src[x]))
                    dst[2 * x] = h & 0xFF
                    dst[2 * x + 1] = h >> 8
            else:
                out[n:n + rb] = planes[c][y * rb:(y + 1) * rb]
            n += rb
    return n


@njit(cache=True)
def _sparse_row(sp, c, y, width, lo, hi):
    """Row y of sparse half plane c into lo, hi (its pixels' low and high bytes, zeroed first):
    sp = (plane's row of vals or -1 by channel, the planes' pixels (P,) flat and ascending, their
    first index by row (H + 1,), vals (K, P) half bits)."""
    k = sp[0][c]
    pix, start, vals = sp[1], sp[2], sp[3]
    lo[:] = 0
    hi[:] = 0
    for j in range(start[y], start[y + 1]):
        x = pix[j] - y * width
        v = vals[k, j]
        lo[x] = v & 0xFF
        hi[x] = v >> 8


@njit(cache=True)
def _reorder(planes, item, half, sp, width, y0, y1, r, r16):
    """The packed rows y0..y1 - 1 (`_pack`) reordered into r: their even bytes, then their odd
    bytes; returns their size. A half pixel gives one byte to each half, a float32 pixel two.
    r16: r viewed as uint16."""
    n = 0
    for c in range(len(planes)):
        n += width * item[c]
    n *= y1 - y0
    h = n // 2  # (n is even: every pixel has 2 or 4 bytes)
    e = 0
    for y in range(y0, y1):
        for c in range(len(planes)):
            # (loops over views from index 0: numba then drops its negative-index checks, and
            # LLVM vectorizes them)
            if sp[0][c] >= 0:
                _sparse_row(sp, c, y, width, r[e:e + width], r[h + e:h + e + width])
                e += width
                continue
            if half[c]:
                src32 = planes[c].view(np.uint32)[y * width:(y + 1) * width]
                lo, hi = r[e:e + width], r[h + e:h + e + width]
                for x in range(width):
                    v = _half_bits(np.int64(src32[x]))
                    lo[x] = v & 0xFF
                    hi[x] = v >> 8
                e += width
                continue
            if item[c] == 2:
                src = planes[c].view(np.uint16)[y * width:(y + 1) * width]
                lo, hi = r[e:e + width], r[h + e:h + e + width]
                for x in range(width):
                    lo[x] = src[x] & 0xFF
                    hi[x] = src[x] >> 8
                e += width
                continue
            src32 = planes[c].view(np.uint32)[y * width:(y + 1) * width]
            if e % 2 == 0 and h % 2 == 0:  # bytes 0, 2 and 1, 3 of a pixel as one uint16 each
                lo16, hi16 = r16[e // 2:e // 2 + width], r16[(h + e) // 2:(h + e) // 2 + width]
                for x in range(width):
                    v = src32[x]
                    lo16[x] = (v & 0xFF) | ((v >> 8) & 0xFF00)
                    hi16[x] = ((v >> 8) & 0xFF) | ((v >> 16) & 0xFF00)
            else:
                lo, hi = r[e:e + 2 * width], r[h + e:h + e + 2 * width]
                for x in range(width):
                    v = src32[x]
                    lo[2 * x] = v & 0xFF
                    lo[2 * x + 1] = (v >> 16) & 0xFF
                    hi[2 * x] = (v >> 8) & 0xFF
                    hi[2 * x + 1] = v >> 24
            e += 2 * width
    return n


@njit(cache=True)
def _predict(r, n, p):
    """p[i] = r[i] - r[i - 1] + 128 (mod 256), p[0] = r[0]: OpenEXR's predictor."""
    p[0] = r[0]
    for i in range(1, n):
        p[i] = (r[i] - r[i - 1] + 128) & 0xFF


@njit(cache=True)
def _stretch_end(p, pw, i, n):
    """The first index past i whose byte differs from p[i] (n if none): 8 bytes at a time over
    the aligned words of pw (p viewed as uint64)."""
    b = p[i]
    j = i + 1
    while j < n and j & 7 != 0:
        if p[j] != b:
            return j
        j += 1
    word = np.uint64(b) * _REPEAT
    while j + 8 <= n and pw[j >> 3] == word:
        j += 8
    while j < n and p[j] == b:
        j += 1
    return j


@njit(cache=True)
def _rle(p, pw, n, out):
    """OpenEXR's run-length code of p[:n] into out (room for n + n // 127 + 2 bytes); returns its
    size. A stretch of equal bytes is found at once (`_stretch_end`) and written as OpenEXR
    writes it: runs of 128 bytes, then one of the rest if it has 3 bytes or more, else the rest
    opens a literal."""
    o = 0
    runs = 0
    while runs < n:
        b = p[runs]
        e = _stretch_end(p, pw, runs, n)
        length = e - runs
        if length >= MIN_RUN:
            while length > MAX_RUN:
                out[o] = MAX_RUN
                out[o + 1] = b
                o += 2
                length -= MAX_RUN + 1
            if length >= MIN_RUN:
                out[o] = length - 1
                out[o + 1] = b
                o += 2
                runs = e
                continue
            if length == 0:
                runs = e
                continue
            runs = e - length
        # a literal: its first `length` bytes are equal, then it runs until 3 equal bytes
        count = length
        rune = runs + length
        while True:
            if rune + 10 <= n and count + 8 <= MAX_RUN:  # 8 bytes at once where no 3 equal start
                w1 = _word(pw, rune + 1)
                x = (_word(pw, rune) ^ w1) | (w1 ^ _word(pw, rune + 2))  # a 0 byte: 3 equal bytes
                if (x - _REPEAT) & ~x & _HIGH == 0:
                    count += 8
                    rune += 8
                    continue
            if (rune < n and ((rune + 1 >= n or p[rune] != p[rune + 1])
                              or (rune + 2 >= n or p[rune + 1] != p[rune + 2])) and count < MAX_RUN):
                count += 1
                rune += 1
                continue
            break
        out[o] = (256 - count) & 0xFF
        o += 1
        out[o:o + count] = p[runs:rune]
        o += count
        runs = rune
    return o


@kernel("(ListType(u1[::1]), i8[::1], b1[::1], i8[::1], i8[::1], i8[::1], u2[:, ::1], i8, i8, i8, i8, u1[::1], "
        "i8[::1])")
def scanline_chunks(planes, item, half, sparse, pix, start, vals, width, height, lines, codec, out, sizes):
    """A scanline image's blocks of `lines` rows, one after another into `out`. Codec 0: chunks
    of the packed rows (`_pack`), each its first row (int32), its data's size (int32) and its
    data; codec 1: the same RLE-compressed (stored packed where that would not shrink it).
    sizes[b] gets block b's data size; returns the bytes written to `out`. Sparse half planes
    (sparse[c] >= 0: planes[c] unused) are zero but at pixels `pix` (`_sparse_row`)."""
    sp = (sparse, pix, start, vals)
    row = 0
    for c in range(item.shape[0]):
        row += width * item[c]
    cap = row * lines
    r16 = np.empty(cap // 2 + 1, np.uint16)
    r = r16.view(np.uint8)
    pw = np.empty(cap // 8 + 1, np.uint64)
    p = pw.view(np.uint8)
    comp = np.empty(cap + cap // MAX_RUN + 2, np.uint8)
    o = 0
    b = 0
    for y0 in range(0, height, lines):
        y1 = min(y0 + lines, height)
        if codec == 1:
            n = _reorder(planes, item, half, sp, width, y0, y1, r, r16)
            _predict(r, n, p)
            size = _rle(p, pw, n, comp)
            if size < n:
                out[o + 8:o + 8 + size] = comp[:size]
            else:
                size = _pack(planes, item, half, sp, width, y0, y1, out[o + 8:])
        else:
            size = _pack(planes, item, half, sp, width, y0, y1, out[o + 8:])
        for k in range(4):
            out[o + k] = (y0 >> (8 * k)) & 0xFF
            out[o + 4 + k] = (size >> (8 * k)) & 0xFF
        sizes[b] = size
        o += 8 + size
        b += 1
    return o
