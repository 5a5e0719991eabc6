"""The EXR writer's compiled loops (numba; `writers.exr` loads them on first use): a scanline
file's chunks, packed from the channel planes and RLE-compressed the way OpenEXR does it, or
prepared for ZIP's deflate.

OpenEXR's RLE and ZIP codecs both first reorder a block's bytes (even bytes, then odd ones) and
replace each byte by its difference from the one before plus 128; RLE then writes runs of 3 to
128 equal bytes as (count - 1, byte) and the rest as (-count, count bytes) (ImfRle.cpp). A block
that would not shrink is stored as it is, as OpenEXR does.

The planes are read a whole pixel at a time (a plane: the flat bytes of a contiguous (H, W)
half or float32 image).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from strokekit.numba_cache import kernel

MIN_RUN = 3
MAX_RUN = 127
#: A byte repeated over a uint64.
_REPEAT = np.uint64(0x0101010101010101)


@njit(cache=True)
def _pack(planes, item, width, y0, y1, out):
    """Rows y0..y1 - 1 as the file stores them uncompressed into out: each row's channels in file
    order (plane c: `width` pixels of item[c] bytes a row); returns their size."""
    n = 0
    for y in range(y0, y1):
        for c in range(len(planes)):
            rb = width * item[c]
            out[n:n + rb] = planes[c][y * rb:(y + 1) * rb]
            n += rb
    return n


@njit(cache=True)
def _reorder(planes, item, width, y0, y1, r, r16):
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
            if item[c] == 2:
                a16 = planes[c].view(np.uint16)
                s = y * width
                for x in range(width):
                    v = a16[s + x]
                    r[e + x] = v & 0xFF
                    r[h + e + x] = v >> 8
                e += width
                continue
            a32 = planes[c].view(np.uint32)
            s = y * width
            if e % 2 == 0 and h % 2 == 0:  # bytes 0, 2 and 1, 3 of a pixel as one uint16 each
                lo, hi = e // 2, (h + e) // 2
                for x in range(width):
                    v = a32[s + x]
                    r16[lo + x] = (v & 0xFF) | ((v >> 8) & 0xFF00)
                    r16[hi + x] = ((v >> 8) & 0xFF) | ((v >> 16) & 0xFF00)
            else:
                for x in range(width):
                    v = a32[s + x]
                    r[e + 2 * x] = v & 0xFF
                    r[e + 2 * x + 1] = (v >> 16) & 0xFF
                    r[h + e + 2 * x] = (v >> 8) & 0xFF
                    r[h + e + 2 * x + 1] = v >> 24
            e += 2 * width
    return n


@njit(cache=True)
def _predict(r, n, p):
    """p[i] = r[i] - r[i - 1] + 128 (mod 256), p[0] = r[0]: OpenEXR's predictor."""
    p[0] = r[0]
    for i in range(1, n):
        p[i] = (r[i] - r[i - 1] + 128) & 0xFF


@njit(cache=True)
def _rle(p, pw, n, out):
    """OpenEXR's run-length code of p[:n] into out (room for n + n // 127 + 2 bytes); returns its
    size. pw: p viewed as uint64, to pass over a run 8 bytes at a time."""
    o = 0
    runs = 0
    rune = 1
    while runs < n:
        count = 0
        b = p[runs]
        word = np.uint64(b) * _REPEAT
        while rune < n and count < MAX_RUN:
            if rune & 7 == 0 and rune + 8 <= n and count + 8 <= MAX_RUN and pw[rune >> 3] == word:
                rune += 8
                count += 8
            elif p[rune] == b:
                rune += 1
                count += 1
            else:
                break
        if count >= MIN_RUN - 1:
            out[o] = count
            out[o + 1] = b
            o += 2
            runs = rune
        else:
            count += 1
            while (rune < n and ((rune + 1 >= n or p[rune] != p[rune + 1])
                                 or (rune + 2 >= n or p[rune + 1] != p[rune + 2])) and count < MAX_RUN):
                count += 1
                rune += 1
            out[o] = (256 - count) & 0xFF
            o += 1
            out[o:o + rune - runs] = p[runs:rune]
            o += rune - runs
            runs = rune
        rune += 1
    return o


@kernel("(ListType(u1[::1]), i8[::1], i8, i8, i8, i8, u1[::1], i8[::1])")
def scanline_chunks(planes, item, width, height, lines, codec, out, sizes):
    """A scanline image's blocks of `lines` rows, one after another into `out`. Codec 0: chunks
    of the packed rows (`_pack`), each its first row (int32), its data's size (int32) and its
    data; codec 1: the same RLE-compressed (stored packed where that would not shrink it);
    codec 2: the blocks reordered and predicted only, no chunk heads (the caller deflates them).
    sizes[b] gets block b's data size; returns the bytes written to `out`."""
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
        if codec == 2:
            n = _reorder(planes, item, width, y0, y1, r, r16)
            _predict(r, n, out[o:o + n])
            sizes[b] = n
            o += n
            b += 1
            continue
        if codec == 1:
            n = _reorder(planes, item, width, y0, y1, r, r16)
            _predict(r, n, p)
            size = _rle(p, pw, n, comp)
            if size < n:
                out[o + 8:o + 8 + size] = comp[:size]
            else:
                size = _pack(planes, item, width, y0, y1, out[o + 8:])
        else:
            size = _pack(planes, item, width, y0, y1, out[o + 8:])
        for k in range(4):
            out[o + k] = (y0 >> (8 * k)) & 0xFF
            out[o + 4 + k] = (size >> (8 * k)) & 0xFF
        sizes[b] = size
        o += 8 + size
        b += 1
    return o
