"""PNG bytes, deterministic (no timestamps, fixed filter and compression: the same array and
chunks always give the same bytes), written for speed.

Colour images (the shade colours, the fill, the lines) carry an sRGB chunk: their values are
sRGB-encoded, with straight (not premultiplied) alpha. Data images (band labels, masks, object
ids, depth) carry none, and a text chunk "colorspace: Non-Color" instead: read them as data
(Blender: Non-Color), never colour-managed.

Every row is filtered with PNG's Up filter (the difference to the row above: flat regions and
straight edges become runs of zeros) and the rows are deflated by zlib at level 1, with the RLE
strategy for 8-bit images (runs are what an image of flat bands, masks and ids is made of) and
the default strategy for 16-bit depth: files within a fifth of Pillow's level 6 at a fraction of
its time (docs/measurements.md, "Raster pass", has the sizes and times).
"""

from __future__ import annotations

import io
import struct
import zlib
from concurrent.futures import ThreadPoolExecutor

import numpy as np

_SIGNATURE = b"\x89PNG\r\n\x1a\n"
#: zlib level and strategy of 8-bit and 16-bit images (see the module docstring).
LEVEL = 1
STRATEGY_8BIT = zlib.Z_RLE
STRATEGY_16BIT = zlib.Z_DEFAULT_STRATEGY


#: The passes whose PNGs are colour (sRGB); every other pass is data.
COLOUR_PASSES = ("shade", "fill", "lines")


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)


def png_bytes(image: np.ndarray, *, srgb: bool = False, text: dict[str, str] | None = None) -> bytes:
    """Encode an image as PNG.

    image: (H, W) uint8 (8-bit grey), (H, W) uint16 (16-bit grey), (H, W, 3) uint8 RGB or
    (H, W, 4) uint8 RGBA. Row 0 is the top of the image (BRIEF 1.1). srgb: add an sRGB chunk
    (perceptual intent); text: tEXt chunks (Latin-1), in the order given."""
    a = np.asarray(image)
    if a.ndim == 2 and a.dtype == np.uint8:
        colour, depth = 0, 8
    elif a.ndim == 2 and a.dtype == np.uint16:
        colour, depth = 0, 16
        a = a.astype(">u2")  # PNG samples are big-endian
    elif a.ndim == 3 and a.dtype == np.uint8 and a.shape[2] in (3, 4):
        colour, depth = (2 if a.shape[2] == 3 else 6), 8
    else:
        raise ValueError(f"cannot write a PNG from an array of shape {a.shape} and dtype {a.dtype}")
    H, W = a.shape[:2]
    if H == 0 or W == 0:
        raise ValueError(f"cannot write an empty PNG ({W} x {H})")
    rows = np.ascontiguousarray(a).view(np.uint8).reshape(H, -1)
    # Up filter: filter byte 2, then each byte minus the byte above it (mod 256); the first row's
    # "above" is zero.
    filtered = np.empty((H, rows.shape[1] + 1), np.uint8)
    filtered[:, 0] = 2
    filtered[0, 1:] = rows[0]
    np.subtract(rows[1:], rows[:-1], out=filtered[1:, 1:])
    z = zlib.compressobj(LEVEL, zlib.DEFLATED, 15, 9, STRATEGY_16BIT if depth == 16 else STRATEGY_8BIT)
    idat = z.compress(filtered.data) + z.flush()
    ihdr = struct.pack(">IIBBBBB", W, H, depth, colour, 0, 0, 0)
    extra = _chunk(b"sRGB", b"\x00") if srgb else b""
    extra += b"".join(_chunk(b"tEXt", k.encode("latin-1") + b"\0" + v.encode("latin-1"))
                      for k, v in (text or {}).items())
    return _SIGNATURE + _chunk(b"IHDR", ihdr) + extra + _chunk(b"IDAT", idat) + _chunk(b"IEND", b"")


def read_png(data: bytes) -> np.ndarray:
    """Decode PNG bytes back to an array (uint8, or uint16 for 16-bit grey). For tests and tools."""
    from PIL import Image

    img = Image.open(io.BytesIO(data))
    if img.mode in ("I;16", "I;16B", "I"):
        return np.asarray(img, dtype=np.uint16) if img.mode != "I" else np.asarray(img).astype(np.uint16)
    return np.asarray(img)


def png_files(images: dict[str, np.ndarray], text: dict[str, dict[str, str]] | None = None,
              threads: int = 1) -> dict[str, bytes]:
    """{pass: PNG bytes} of {pass: image} (RasterFrame.images), in the same order: colour passes
    (COLOUR_PASSES) with an sRGB chunk, data passes marked Non-Color; `text` adds chunks per pass
    (e.g. the depth range). `threads` > 1 encodes that many images at once (zlib lets go of
    Python's lock; each image's bytes are its own)."""
    def encode(k: str) -> bytes:
        srgb = k in COLOUR_PASSES
        chunks = {} if srgb else {"colorspace": "Non-Color"}
        chunks.update((text or {}).get(k, {}))
        return png_bytes(images[k], srgb=srgb, text=chunks)

    names = list(images)
    if threads > 1 and len(names) > 1:
        with ThreadPoolExecutor(min(threads, len(names))) as pool:
            return dict(zip(names, pool.map(encode, names)))
    return {k: encode(k) for k in names}
