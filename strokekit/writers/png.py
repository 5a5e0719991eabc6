"""PNG bytes via Pillow, deterministic: no timestamps, no text chunks, fixed compression, so the
same array always gives the same bytes."""

from __future__ import annotations

import io

import numpy as np


def png_bytes(image: np.ndarray) -> bytes:
    """Encode an image as PNG.

    image: (H, W) uint8 (8-bit grey), (H, W) uint16 (16-bit grey), (H, W, 3) uint8 RGB or
    (H, W, 4) uint8 RGBA. Row 0 is the top of the image (BRIEF 1.1)."""
    from PIL import Image

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
    buf = io.BytesIO()
    # No pnginfo and no optimize pass: the output depends on the pixels only.
    img.save(buf, format="PNG", compress_level=6)
    return buf.getvalue()


def read_png(data: bytes) -> np.ndarray:
    """Decode PNG bytes back to an array (uint8, or uint16 for 16-bit grey). For tests and tools."""
    from PIL import Image

    img = Image.open(io.BytesIO(data))
    if img.mode in ("I;16", "I;16B", "I"):
        return np.asarray(img, dtype=np.uint16) if img.mode != "I" else np.asarray(img).astype(np.uint16)
    return np.asarray(img)


def png_files(images: dict[str, np.ndarray]) -> dict[str, bytes]:
    """{file suffix: PNG bytes} of {file suffix: image} (RasterFrame.images), in the same order."""
    return {k: png_bytes(v) for k, v in images.items()}
