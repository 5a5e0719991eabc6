"""PNG bytes via Pillow, deterministic: no timestamps, fixed compression, so the same array
always gives the same bytes.

Colour images (the shade colours, the fill, the lines) carry an sRGB chunk: their values are
sRGB-encoded, with straight (not premultiplied) alpha. Data images (band labels, masks, object
ids, depth) carry none, and a text chunk "colorspace: Non-Color" instead: read them as data
(Blender: Non-Color), never colour-managed."""

from __future__ import annotations

import io

import numpy as np

#: The passes whose PNGs are colour (sRGB); every other pass is data.
COLOUR_PASSES = ("shade", "fill", "lines")


def png_bytes(image: np.ndarray, *, srgb: bool = False, text: dict[str, str] | None = None) -> bytes:
    """Encode an image as PNG.

    image: (H, W) uint8 (8-bit grey), (H, W) uint16 (16-bit grey), (H, W, 3) uint8 RGB or
    (H, W, 4) uint8 RGBA. Row 0 is the top of the image (BRIEF 1.1). srgb: add an sRGB chunk
    (perceptual intent); text: tEXt chunks, in the order given."""
    from PIL import Image, PngImagePlugin

    a = np.ascontiguousarray(image)
    if a.ndim == 2 and a.dtype == np.uint8:
        img = Image.fromarray(a, mode="L")
    elif a.ndim == 2 and a.dtype == np.uint16:
        # "I;16" is Pillow's native 16-bit grey; written as a 16-bit PNG.
        img = Image.frombytes("I;16", (a.shape[1], a.shape[0]), a.astype("<u2").tobytes())
    elif a.ndim == 3 and a.dtype == np.uint8 and a.shape[2] in (3, 4):
        img = Image.fromarray(a, mode="RGB" if a.shape[2] == 3 else "RGBA")
    else:
        raise ValueError(f"cannot write a PNG from an array of shape {a.shape} and dtype {a.dtype}")
    info = PngImagePlugin.PngInfo()
    if srgb:
        info.add(b"sRGB", b"\x00")
    for k, v in (text or {}).items():
        info.add_text(k, v)
    buf = io.BytesIO()
    # No optimize pass: the output depends on the pixels and the chunks given only.
    img.save(buf, format="PNG", compress_level=6, pnginfo=info)
    return buf.getvalue()


def read_png(data: bytes) -> np.ndarray:
    """Decode PNG bytes back to an array (uint8, or uint16 for 16-bit grey). For tests and tools."""
    from PIL import Image

    img = Image.open(io.BytesIO(data))
    if img.mode in ("I;16", "I;16B", "I"):
        return np.asarray(img, dtype=np.uint16) if img.mode != "I" else np.asarray(img).astype(np.uint16)
    return np.asarray(img)


def png_files(images: dict[str, np.ndarray], text: dict[str, dict[str, str]] | None = None) -> dict[str, bytes]:
    """{pass: PNG bytes} of {pass: image} (RasterFrame.images), in the same order: colour passes
    (COLOUR_PASSES) with an sRGB chunk, data passes marked Non-Color; `text` adds chunks per pass
    (e.g. the depth range)."""
    out = {}
    for k, v in images.items():
        srgb = k in COLOUR_PASSES
        chunks = {} if srgb else {"colorspace": "Non-Color"}
        chunks.update((text or {}).get(k, {}))
        out[k] = png_bytes(v, srgb=srgb, text=chunks)
    return out
