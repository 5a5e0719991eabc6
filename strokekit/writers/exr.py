"""One multilayer OpenEXR per frame (`exr_bytes`).

Single part, scanline, with a lossless compression that readers built on OpenEXR < 3.3 read
(Blender 3.4 among them: not ZSTD or HTJ2K). ZIP by default, as Blender writes; RLE is written by
strokekit's own compiled writer (`compiled_exr`: the bytes OpenEXR writes, in a fraction of its time),
the others (ZIP, ZIPS, PIZ, none) by the OpenEXR Python bindings (`openexr_file`). Channels, each only when the run computed it, all
(H, W):

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

With `--exr-float full` every channel is float32. The header holds only what the bindings write,
the Cryptomatte strings and `strokekit/layers` (what each layer holds, its pixel type): no date or
host, so the same passes give the same bytes.
"""

from __future__ import annotations

import io
import json
import os
import struct
import threading
from typing import NamedTuple

import numpy as np
import OpenEXR

from strokekit.colour import srgb_decode
from strokekit.cryptomatte import header_attributes, layer_names
from strokekit.model import RasterPasses
from strokekit.numba_cache import KernelGroup, LazyKernels
from strokekit.writers.svg import KIND_COLORS


def _rgb(hex_colour: str) -> np.ndarray:
    return srgb_decode(np.array([int(hex_colour[i:i + 2], 16) for i in (1, 3, 5)], float) / 255.0)


def lines_sparse(lines: dict[str, np.ndarray]) -> tuple[np.ndarray, dict[str, np.ndarray], np.ndarray]:
    """The lines pass on the pixels any stroke covers (few in a frame): (flat pixel indices (P,),
    {kind: (P, 4) premultiplied linear RGBA of its coverage in its SVG colour}, their composite
    (P, 4), each kind over the ones before it in KINDS order)."""
    flat = {kind: np.asarray(cov, np.float32).reshape(-1) for kind, cov in lines.items()}
    covered = np.zeros(0 if not flat else next(iter(flat.values())).size, bool)
    for a in flat.values():
        covered |= a != 0
    pix = np.flatnonzero(covered)  # (one pass over a mask: a fifth of a flatnonzero per kind)
    per_kind = {}
    total = np.zeros((len(pix), 4), np.float32)
    for kind, a in flat.items():
        a = a[pix, None]
        rgba = np.concatenate([a * _rgb(KIND_COLORS.get(kind, "#000000")).astype(np.float32), a], axis=1)
        per_kind[kind] = rgba
        total = rgba + total * (1.0 - a)
    return pix, per_kind, total


def _half_planes(pix: np.ndarray, values: np.ndarray, shape: tuple, dtype=np.float16) -> list[np.ndarray]:
    """`shape` (H, W) images of `dtype`, zero but at flat pixels `pix`, where they take the columns
    of `values`."""
    out = []
    for c in range(values.shape[1]):
        plane = np.zeros(shape[0] * shape[1], dtype)
        plane[pix] = values[:, c]
        out.append(plane.reshape(shape))
    return out


def exr_channels(passes: RasterPasses, precision: str = "half") -> tuple[dict[str, np.ndarray], dict[str, str]]:
    """(channels by full name, header string attributes) of one frame's EXR. `precision` "half":
    the channels Blender writes in half float are half (see the module); "full": every one float32."""
    sources, hdr = channel_sources(passes, precision)
    return {k: a.astype(t, copy=False) for k, (a, t) in sources.items()}, hdr


class SparsePlane(NamedTuple):
    """An (H, W) half plane zero but at flat pixels `pix` (ascending), where it holds `values`."""

    pix: np.ndarray
    values: np.ndarray
    shape: tuple[int, int]


def channel_sources(passes: RasterPasses, precision: str = "half", sparse: bool = False) -> tuple[
        dict[str, tuple[np.ndarray | SparsePlane, type]], dict[str, str]]:
    """exr_channels before its casts: (by channel name, (its contiguous (H, W) plane, float32 or
    half, and the pixel type the file holds it in), header string attributes). The compiled
    writer casts float32 planes to half as it writes them; with `sparse`, the half lines layers
    are SparsePlanes (nearly all zero: the writer fills their rows)."""
    src: dict[str, tuple[np.ndarray, type]] = {}
    hdr: dict[str, str] = {}
    half = np.float16 if precision == "half" else np.float32

    def plane(a):
        return np.ascontiguousarray(a, np.float32)  # (the passes' planes are contiguous: no copy)

    if passes.depth is not None:
        src["Z"] = plane(passes.depth), np.float32
    if passes.normal is not None:
        for i, c in enumerate("XYZ"):
            src[f"N.{c}"] = plane(passes.normal[..., i]), half
    if passes.shade is not None:
        for i, c in enumerate("RGBA"):
            src[c] = plane(passes.shade[..., i]), half
    if passes.bands is not None:
        src["bands.V"] = plane(passes.bands), half
    for layer in passes.crypto:
        R = layer.ids.shape[2]
        for i, name in enumerate(layer_names(layer.type_name, R)):
            for j, (idc, covc) in enumerate((("R", "G"), ("B", "A"))):
                k = 2 * i + j
                ids = layer.ids[..., k] if k < R else np.zeros(layer.ids.shape[:2], np.float32)
                cov = layer.coverage[..., k] if k < R else np.zeros(layer.ids.shape[:2], np.float32)
                src[f"{name}.{idc}"] = plane(ids), np.float32  # (rank planes: contiguous)
                src[f"{name}.{covc}"] = plane(cov), np.float32
        hdr.update(header_attributes(layer.type_name, layer.names))
    if passes.lines is not None:
        # Built from the covered pixels only: the lines layers are nearly all zero.
        shape = (passes.height, passes.width)
        pix, per_kind, total = lines_sparse(passes.lines)
        for name, rgba in [*((f"lines_{k}", v) for k, v in per_kind.items()), ("lines", total)]:
            if sparse and half is np.float16:
                for c, col in zip("RGBA", rgba.T):
                    src[f"{name}.{c}"] = SparsePlane(pix, col.astype(np.float16), shape), half
                continue
            for c, p in zip("RGBA", _half_planes(pix, rgba, shape, half)):
                src[f"{name}.{c}"] = p, half
    hdr[CONTENTS_KEY] = contents({k: t for k, (_, t) in src.items()})
    return src, hdr


#: The header attribute that says what the file holds (`contents`).
CONTENTS_KEY = "strokekit/layers"
#: What each layer holds, by the name its channels start with (LAYER.X, or the bare R G B A).
MEANINGS = {
    "Z": "view depth in scene units; background 1e10",
    "N": "view-space unit normal: x right, y up, z toward the camera; 0 on background",
    "RGBA": "shade colours, linear, premultiplied by A (the covered share of the pixel)",
    "bands": "band label of the sample nearest the pixel centre: 0 background, 1..N",
    "Crypto": "Cryptomatte ranks (id as float32 bits, coverage); manifest in the cryptomatte/ keys",
    "lines": "strokes in their SVG colour, linear, premultiplied by their coverage",
}


def contents(channels: dict[str, type]) -> str:
    """The `strokekit/layers` attribute: a JSON object, for each layer of `channels` (pixel type
    by channel name, in the file's order), its channels' pixel type (half or float: one for a
    layer's channels) and what it holds."""
    layers: dict[str, dict] = {}
    for name, t in channels.items():
        layer = name.rsplit(".", 1)[0] if "." in name else ("RGBA" if name in "RGBA" else name)
        kind = "Crypto" if layer.startswith("Crypto") else ("lines" if layer.startswith("lines") else layer)
        layers.setdefault(layer, {"type": "half" if np.dtype(t) == np.float16 else "float", "holds": MEANINGS[kind]})
    return json.dumps(layers, separators=(",", ":"), ensure_ascii=True)


_pool_lock = threading.Lock()


def _encode_threads() -> int:
    """Threads OpenEXR compresses a frame's blocks with: the cores this process may use. The
    bytes do not depend on it (blocks are written in scanline order); a run's other processes
    encode their own frames meanwhile, so this only shortens a frame's wall time. OpenEXR's
    thread pool is one per process: it is raised to that count once, never lowered."""
    try:
        n = len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        n = os.cpu_count() or 1
    n = max(1, min(n, 8))
    with _pool_lock:  # (two threads of one process may encode at once)
        if OpenEXR.global_thread_count() < n:  # the pool the file's threads come from (0 by default)
            OpenEXR.set_global_thread_count(n)
    return n


#: The compiled writer's kernels: loaded on first use, warmed before a run's frames (run.kernels).
EXR_WRITER = LazyKernels("strokekit.writers.exr_kernels")
EXR_KERNELS = KernelGroup("EXR writer", (EXR_WRITER,), compile_seconds=4)

#: PassOptions.codec -> OpenEXR's compression.
COMPRESSION = {"zip": OpenEXR.ZIP_COMPRESSION, "zips": OpenEXR.ZIPS_COMPRESSION, "piz": OpenEXR.PIZ_COMPRESSION,
               "rle": OpenEXR.RLE_COMPRESSION, "none": OpenEXR.NO_COMPRESSION}
#: The codecs the compiled writer encodes (`compiled_exr`): the code of each in the file's
#: compression attribute and for `exr_kernels.scanline_chunks`.
COMPILED = {"none": 0, "rle": 1}
#: Those that runs write with it: RLE. OpenEXR's uncompressed file is quicker (a 122 MB frame:
#: the compiled writer's buffer and its copy cost more than OpenEXR's copy), as are the others.
WRITTEN_COMPILED = ("rle",)


def exr_bytes(passes: RasterPasses, codec: str = "zip", precision: str = "half") -> bytes:
    """The EXR file of one frame's passes (bytes: the caller writes them atomically), compressed
    with `codec` (a key of COMPRESSION), its float types by `precision` (exr_channels). RLE is
    written by strokekit's compiled writer (the bytes OpenEXR writes, about 4 times faster), the
    others by OpenEXR."""
    if codec in WRITTEN_COMPILED:
        sources, attrs = channel_sources(passes, precision, sparse=True)
        if not sources:
            raise ValueError("no EXR layer to write")
        return _compiled_exr(sources, attrs, codec)
    channels, attrs = exr_channels(passes, precision)
    if not channels:
        raise ValueError("no EXR layer to write")
    return openexr_file(channels, attrs, codec, _encode_threads())


def openexr_file(channels: dict[str, np.ndarray], attrs: dict[str, str], codec: str, threads: int = 0) -> bytes:
    """The single-part scanline file OpenEXR's Python bindings write of `channels` with string
    attributes `attrs`, compressed with `codec` (a key of COMPRESSION), on `threads` threads."""
    header = {"compression": COMPRESSION[codec], "type": OpenEXR.scanlineimage, **attrs}
    out = io.BytesIO()
    with OpenEXR.File(header, dict(channels), num_threads=threads) as f:
        f.write(out)
    return out.getvalue()


def compiled_exr(channels: dict[str, np.ndarray], attrs: dict[str, str], codec: str) -> bytes:
    """A single-part scanline EXR of `channels` (contiguous (H, W) half or float32 planes), one
    scanline a block, RLE-compressed or not (`codec`, a key of COMPILED), with OpenEXR's header:
    the attributes its Python bindings write for such a file, and `attrs` as strings."""
    return _compiled_exr({k: (a, a.dtype.type) for k, a in channels.items()}, attrs, codec)


def _compiled_exr(sources: dict[str, tuple[np.ndarray, type]], attrs: dict[str, str], codec: str) -> bytes:
    """compiled_exr of channel_sources' planes (a float32 plane held as half: cast as written)."""
    from numba.typed import List

    EXR_KERNELS.ensure()
    names = sorted(sources)  # the file's channel order (OpenEXR's: by name, bytewise)
    H, W = sources[names[0]][0].shape
    sparse = [sources[n][0] for n in names if isinstance(sources[n][0], SparsePlane)]
    pix = sparse[0].pix if sparse else np.zeros(0, np.int64)
    if any(s.pix is not pix and not np.array_equal(s.pix, pix) for s in sparse):
        raise ValueError("the sparse planes of one file share their pixels")
    row = np.full(len(names), -1, np.int64)  # each sparse plane's row of vals
    none = np.zeros(0, np.uint8)
    planes, k = List(), 0
    for i, n in enumerate(names):
        if isinstance(sources[n][0], SparsePlane):
            row[i], k = k, k + 1
            planes.append(none)
        else:
            planes.append(np.ascontiguousarray(sources[n][0]).reshape(-1).view(np.uint8))
    vals = np.ascontiguousarray(np.array([s.values for s in sparse], np.float16).reshape(len(sparse), len(pix))
                                .view(np.uint16))
    start = np.searchsorted(pix, np.arange(H + 1) * W).astype(np.int64)
    item = np.array([np.dtype(sources[n][1]).itemsize for n in names], np.int64)
    half = np.array([row[i] < 0 and sources[n][0].dtype == np.float32 and item[i] == 2 for i, n in enumerate(names)],
                    bool)
    out = np.empty(int(item.sum()) * W * H + 8 * H, np.uint8)  # room for every row stored as it is
    sizes = np.zeros(H, np.int64)
    n = EXR_WRITER.kernels().scanline_chunks(planes, item, half, row, np.ascontiguousarray(pix, np.int64), start,
                                             vals, W, H, 1, COMPILED[codec], out, sizes)
    head = _header(names, {k: t for k, (_, t) in sources.items()}, COMPILED[codec], W, H, attrs)
    table = len(head) + 8 * H + np.concatenate([[0], np.cumsum(sizes + 8)[:-1]])
    return b"".join((head, table.astype("<u8").tobytes(), out[:n].data))


#: OpenEXR's pixel type codes.
_PIXEL_TYPE = {np.dtype(np.float16): 1, np.dtype(np.float32): 2}


def _header(names: list[str], types: dict[str, type], compression: int, W: int, H: int,
            attrs: dict[str, str]) -> bytes:
    """The magic number, version and header of a single-part scanline file of channels `names`
    (pixel types `types`), attributes sorted by name as OpenEXR writes them."""
    def attribute(name: str, kind: str, value: bytes) -> bytes:
        return name.encode() + b"\0" + kind.encode() + b"\0" + struct.pack("<i", len(value)) + value

    chlist = b"".join(n.encode() + b"\0" + struct.pack("<iB3xii", _PIXEL_TYPE[np.dtype(types[n])], 0, 1, 1)
                      for n in names) + b"\0"
    box = struct.pack("<4i", 0, 0, W - 1, H - 1)
    a = {"channels": ("chlist", chlist), "compression": ("compression", bytes([compression])),
         "dataWindow": ("box2i", box), "displayWindow": ("box2i", box), "lineOrder": ("lineOrder", b"\0"),
         "pixelAspectRatio": ("float", struct.pack("<f", 1.0)), "screenWindowCenter": ("v2f", struct.pack("<2f", 0, 0)),
         "screenWindowWidth": ("float", struct.pack("<f", 1.0)), "type": ("string", b"scanlineimage"),
         **{k: ("string", v.encode()) for k, v in attrs.items()}}
    long_names = any(len(k) > 31 for k in (*a, *names))  # the version's flag for names of 32 to 255 bytes
    version = 2 | (0x400 if long_names else 0)
    return (b"\x76\x2f\x31\x01" + struct.pack("<i", version) + b"".join(attribute(k, *a[k]) for k in sorted(a))
            + b"\0")


def read_exr(path) -> tuple[dict[str, np.ndarray], dict]:
    """(channels by full name, header) of a single-part EXR (for tests and checks)."""
    with OpenEXR.File(os.fspath(path), separate_channels=True) as f:
        return {name: np.array(c.pixels) for name, c in f.channels().items()}, dict(f.header())
