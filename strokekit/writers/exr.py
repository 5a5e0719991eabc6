"""One multilayer OpenEXR per frame (`exr_bytes`), written with the OpenEXR Python bindings.

Single part, scanline, ZIP compression (readers built on OpenEXR < 3.3, Blender 3.4 among them,
cannot read ZSTD or HTJ2K). Channels, each only when the run computed it, all (H, W):

- `Z` float32: view depth in scene units; background 1e10 (model.BACKGROUND_DEPTH), as Blender
  writes it. Blender reads it as its Depth pass.
- `N.X N.Y N.Z` half: view-space unit normal (x right, y up, z toward the camera; 0 on background).
- `R G B A` half: the shade colours, linear, premultiplied by A (EXR's convention); A is the
  covered fraction. Blender reads them as Combined.
- `bands.V` half: the band label (0 background, 1..N), from the sample nearest the pixel centre.
- `CryptoObjectNN.R/G/B/A`, `CryptoMaterialNN.R/G/B/A` float32: Cryptomatte rank pairs (id,
  coverage), ids as float32 bit patterns, with the manifest and conversion in the header.
- `lines_<kind>.R/G/B/A` half: that kind's strokes in their SVG colour (linear), premultiplied by
  their coverage; `lines.R/G/B/A` all kinds over each other in the SVG's layer order.

The header holds only what the bindings write plus the Cryptomatte strings: no date or host, so
the same passes give the same bytes.
"""

from __future__ import annotations

import os
import tempfile

import numpy as np
import OpenEXR

from strokekit.colour import srgb_decode
from strokekit.cryptomatte import header_attributes, layer_names
from strokekit.model import RasterPasses
from strokekit.writers.svg import KIND_COLORS


def _rgb(hex_colour: str) -> np.ndarray:
    return srgb_decode(np.array([int(hex_colour[i:i + 2], 16) for i in (1, 3, 5)], float) / 255.0)


def lines_rgba(lines: dict[str, np.ndarray]) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """({kind: (H, W, 4) premultiplied linear RGBA of its coverage in its SVG colour}, their
    composite (H, W, 4), each kind over the ones before it in KINDS order)."""
    per_kind = {}
    total = None
    for kind, cov in lines.items():
        a = cov.astype(np.float32)
        rgba = np.concatenate([a[..., None] * _rgb(KIND_COLORS.get(kind, "#000000")).astype(np.float32),
                               a[..., None]], axis=2)
        per_kind[kind] = rgba
        total = rgba.copy() if total is None else rgba + total * (1.0 - a[..., None])
    return per_kind, total


def exr_channels(passes: RasterPasses) -> tuple[dict[str, np.ndarray], dict[str, str]]:
    """(channels by full name, header string attributes) of one frame's EXR."""
    ch: dict[str, np.ndarray] = {}
    hdr: dict[str, str] = {}
    half = np.float16
    if passes.depth is not None:
        ch["Z"] = passes.depth.astype(np.float32)
    if passes.normal is not None:
        for i, c in enumerate("XYZ"):
            ch[f"N.{c}"] = passes.normal[..., i].astype(half)
    if passes.shade is not None:
        for i, c in enumerate("RGBA"):
            ch[c] = passes.shade[..., i].astype(half)
    if passes.bands is not None:
        ch["bands.V"] = passes.bands.astype(half)
    for layer in passes.crypto:
        R = layer.ids.shape[2]
        for i, name in enumerate(layer_names(layer.type_name, R)):
            for j, (idc, covc) in enumerate((("R", "G"), ("B", "A"))):
                k = 2 * i + j
                ids = layer.ids[..., k] if k < R else np.zeros(layer.ids.shape[:2], np.float32)
                cov = layer.coverage[..., k] if k < R else np.zeros(layer.ids.shape[:2], np.float32)
                ch[f"{name}.{idc}"] = ids.astype(np.float32)
                ch[f"{name}.{covc}"] = cov.astype(np.float32)
        hdr.update(header_attributes(layer.type_name, layer.names))
    if passes.lines is not None:
        per_kind, total = lines_rgba(passes.lines)
        if total is None:
            total = np.zeros((passes.height, passes.width, 4), np.float32)
        for kind, rgba in per_kind.items():
            for i, c in enumerate("RGBA"):
                ch[f"lines_{kind}.{c}"] = rgba[..., i].astype(half)
        for i, c in enumerate("RGBA"):
            ch[f"lines.{c}"] = total[..., i].astype(half)
    return {k: np.ascontiguousarray(v) for k, v in ch.items()}, hdr


def exr_bytes(passes: RasterPasses) -> bytes:
    """The EXR file of one frame's passes (bytes: the caller writes them atomically)."""
    channels, attrs = exr_channels(passes)
    if not channels:
        raise ValueError("no EXR layer to write")
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage, **attrs}
    # The bindings write to a path only: a private temporary file, read back.
    with tempfile.TemporaryDirectory(prefix="strokekit-exr-") as d:
        path = os.path.join(d, "frame.exr")
        with OpenEXR.File(header, channels) as f:
            f.write(path)
        with open(path, "rb") as fh:
            return fh.read()


def read_exr(path) -> tuple[dict[str, np.ndarray], dict]:
    """(channels by full name, header) of a single-part EXR (for tests and checks)."""
    with OpenEXR.File(os.fspath(path), separate_channels=True) as f:
        return {name: np.array(c.pixels) for name, c in f.channels().items()}, dict(f.header())
