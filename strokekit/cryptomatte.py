"""Cryptomatte ids, manifests and ranked mattes (Psyop Cryptomatte specification 1.1.0, 2015).

What a compositor needs to pick an object or material by name:

* ids: MurmurHash3_x86_32 (seed 0) of the UTF-8 name, stored as the float32 with the same bits,
  except that the exponent is clamped to [1, 254] so that no id is a denormal, 0, inf or NaN;
* per pixel, the (id, coverage) pairs of every object seen by the pixel's samples, ranked by coverage
  (highest first), two pairs per RGBA layer: ``{type}00.R/G`` = rank 0 id/coverage, ``.B/A`` = rank 1,
  ``{type}01`` ranks 2 and 3, ...; unused ranks hold id 0.0 and coverage 0.0;
* header attributes ``cryptomatte/<key>/name|hash|conversion|manifest`` where ``<key>`` is the first
  7 hex digits of the hash of the type name and the manifest maps names to 8-hex-digit id bits.

Background samples (index -1) have no id: they only count in the pixel's total weight, so the
coverages of all ranks of a pixel sum to its covered fraction (its alpha).

Everything here is deterministic: same names and samples give the same arrays and strings.
"""

from __future__ import annotations

import json
import struct
from dataclasses import dataclass
from typing import Iterable, Mapping, Sequence

import numpy as np

try:  # mmh3 (PyPI, C extension with wheels) is the fast path; the pure function is the fallback
    import mmh3 as _mmh3
except ImportError:  # pragma: no cover - exercised through murmur3_32_py in the tests
    _mmh3 = None

HASH_NAME = "MurmurHash3_32"
CONVERSION = "uint32_to_float32"
DEFAULT_RANKS = 6  # the specification's suggested default: 3 layers, 00 01 02


def _as_bytes(name: str | bytes) -> bytes:
    return name if isinstance(name, bytes) else name.encode("utf-8")


def murmur3_32_py(data: bytes, seed: int = 0) -> int:
    """MurmurHash3_x86_32 in pure Python, unsigned 32-bit result (reference for mmh3)."""
    c1, c2, mask = 0xCC9E2D51, 0x1B873593, 0xFFFFFFFF
    h = seed & mask
    n = len(data)
    nblocks = n // 4
    for i in range(nblocks):
        k = int.from_bytes(data[4 * i:4 * i + 4], "little")
        k = (k * c1) & mask
        k = ((k << 15) | (k >> 17)) & mask
        k = (k * c2) & mask
        h ^= k
        h = ((h << 13) | (h >> 19)) & mask
        h = (h * 5 + 0xE6546B64) & mask
    tail = data[4 * nblocks:]
    k = 0
    if len(tail) >= 3:
        k ^= tail[2] << 16
    if len(tail) >= 2:
        k ^= tail[1] << 8
    if len(tail) >= 1:
        k ^= tail[0]
        k = (k * c1) & mask
        k = ((k << 15) | (k >> 17)) & mask
        k = (k * c2) & mask
        h ^= k
    h ^= n
    h ^= h >> 16
    h = (h * 0x85EBCA6B) & mask
    h ^= h >> 13
    h = (h * 0xC2B2AE35) & mask
    h ^= h >> 16
    return h


def murmur3_32(name: str | bytes) -> int:
    """MurmurHash3_x86_32, seed 0, of the UTF-8 bytes of ``name``, as an unsigned int."""
    data = _as_bytes(name)
    if _mmh3 is not None:
        return _mmh3.hash(data, 0, signed=False)
    return murmur3_32_py(data)


def hash_to_float_bits(h: int) -> int:
    """The uint32_to_float32 conversion: the hash's bits with the exponent clamped to [1, 254]."""
    h &= 0xFFFFFFFF
    exponent = min(max((h >> 23) & 0xFF, 1), 254)
    return (h & 0x807FFFFF) | (exponent << 23)


def bits_to_float(bits: int) -> float:
    """The float32 with these bits, as a Python float (exactly representable in float32)."""
    return struct.unpack("<f", struct.pack("<I", bits & 0xFFFFFFFF))[0]


def name_to_bits(name: str | bytes) -> int:
    """The id of ``name`` as its float32 bit pattern (what the manifest's hex digits spell)."""
    return hash_to_float_bits(murmur3_32(name))


def name_to_id(name: str | bytes) -> float:
    """The id of ``name`` as stored in the R or B channel of a rank layer (a float32 value)."""
    return bits_to_float(name_to_bits(name))


def name_to_hex(name: str | bytes) -> str:
    """The manifest value for ``name``: 8 lower-case hex digits of the id's float32 bits."""
    return f"{name_to_bits(name):08x}"


def layer_key(type_name: str) -> str:
    """The 7-character metadata key of a Cryptomatte type (first 7 hex digits of its hash)."""
    return f"{murmur3_32(type_name):08x}"[:7]


def manifest_json(names: Iterable[str]) -> str:
    """The manifest, ``{"name": "hex8", ...}``: keys sorted, compact, ASCII-safe, deterministic.

    Duplicate names are written once. Names that collide on one id keep their own entries (their
    mattes merge, as the specification says overlapping names do).
    """
    entries = {str(n): name_to_hex(n) for n in names}
    return json.dumps(dict(sorted(entries.items())), separators=(",", ":"), ensure_ascii=True)


def header_attributes(type_name: str, names: Iterable[str], manifest: bool = True) -> dict[str, str]:
    """The EXR header attributes (all strings) that declare one Cryptomatte type.

    ``type_name`` is the channel prefix, e.g. ``"CryptoObject"`` for ``CryptoObject00.R`` ...
    Blender only reads *string* attributes of the first part of a file into image metadata.
    """
    key = f"cryptomatte/{layer_key(type_name)}/"
    attrs = {key + "name": type_name, key + "hash": HASH_NAME, key + "conversion": CONVERSION}
    if manifest:
        attrs[key + "manifest"] = manifest_json(names)
    return attrs


def layer_names(type_name: str, ranks: int = DEFAULT_RANKS) -> list[str]:
    """``["CryptoObject00", "CryptoObject01", ...]``: ceil(ranks / 2) RGBA layers."""
    return [f"{type_name}{i:02d}" for i in range((ranks + 1) // 2)]


@dataclass(frozen=True)
class RankedMatte:
    """Ranked Cryptomatte data of one frame for one type.

    ids:      (H, W, R) float32, id of rank r at each pixel (0.0 where unused)
    coverage: (H, W, R) float32, coverage of that id, descending along the last axis (0.0 where unused)
    """

    ids: np.ndarray
    coverage: np.ndarray

    @property
    def ranks(self) -> int:
        return self.ids.shape[-1]

    def channels(self, type_name: str) -> dict[str, np.ndarray]:
        """EXR channel arrays ``{type}NN.R/G/B/A`` (float32, (H, W)); R and B ids, G and A coverage.

        An odd rank count is padded with an empty rank so that every layer is complete RGBA.
        """
        out: dict[str, np.ndarray] = {}
        h, w, r = self.ids.shape
        for i, layer in enumerate(layer_names(type_name, r)):
            for j, (idc, covc) in enumerate((("R", "G"), ("B", "A"))):
                k = 2 * i + j
                if k < r:
                    out[f"{layer}.{idc}"] = np.ascontiguousarray(self.ids[:, :, k], dtype=np.float32)
                    out[f"{layer}.{covc}"] = np.ascontiguousarray(self.coverage[:, :, k], dtype=np.float32)
                else:
                    out[f"{layer}.{idc}"] = np.zeros((h, w), np.float32)
                    out[f"{layer}.{covc}"] = np.zeros((h, w), np.float32)
        return out

    def matte(self, name_or_id: str | float) -> np.ndarray:
        """The (H, W) float32 matte of one name (sum of its coverage over the ranks), as a decoder sees it."""
        fid = np.float32(name_to_id(name_or_id) if isinstance(name_or_id, (str, bytes)) else name_or_id)
        hit = self.ids.view(np.uint32) == fid.view(np.uint32)
        return np.where(hit, self.coverage, 0).sum(axis=-1, dtype=np.float64).astype(np.float32)


def _id_table(names: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
    """Per object index: slot into the table of distinct id bits, and the sorted distinct id bits."""
    bits = np.array([name_to_bits(n) for n in names], dtype=np.uint32)
    uniq, slot = np.unique(bits, return_inverse=True)  # ascending bits: the tie order
    return slot.astype(np.int64).reshape(-1), uniq


def _top_ranks(slot: np.ndarray, weight: np.ndarray, total: np.ndarray, uniq: np.ndarray, ranks: int):
    """slot, weight: (N, M) candidates (slot -1 = none); total: (N,). Best ``ranks`` per row.

    Order: weight descending, then id bits ascending as uint32 (deterministic ties).
    """
    n = slot.shape[0]
    w = np.where(slot >= 0, weight, -1.0)
    tie = np.where(slot >= 0, slot, np.iinfo(np.int64).max)
    order = np.lexsort((tie, -w), axis=-1)[:, :ranks]
    s = np.take_along_axis(slot, order, axis=-1)
    wk = np.take_along_axis(w, order, axis=-1)
    ids = np.zeros((n, ranks), np.float32)
    cov = np.zeros((n, ranks), np.float32)
    k = s.shape[1]
    valid = (s >= 0) & (wk > 0)
    if len(uniq):
        ids[:, :k] = np.where(valid, uniq[np.clip(s, 0, None)].view(np.float32), np.float32(0))
    cov[:, :k] = np.where(valid, wk / np.where(total > 0, total, 1.0)[:, None], 0.0)
    return ids, cov


def rank_samples(samples: np.ndarray, names: Sequence[str], ranks: int = DEFAULT_RANKS,
                 weights: np.ndarray | None = None, rows_per_chunk: int = 64) -> RankedMatte:
    """Rank the ids seen by each pixel's samples.

    samples: (H, W, S) integer object indices into ``names``, -1 = background (no object).
    weights: optional (S,) or (H, W, S) filter weights of the samples (default: all 1, a box filter).
    Coverage of an id = its samples' weight / all samples' weight (background included), so the
    ranks of a pixel sum to its covered fraction when no more than ``ranks`` ids meet in it.
    Names whose ids collide are merged (as the specification says).
    """
    samples = np.asarray(samples)
    if samples.ndim != 3:
        raise ValueError(f"samples must be (H, W, S), got shape {samples.shape}")
    if ranks < 1:
        raise ValueError("ranks must be >= 1")
    h, w, s = samples.shape
    if samples.size and (samples.max(initial=-1) >= len(names) or samples.min(initial=0) < -1):
        raise ValueError("sample index out of range of names (or below -1)")
    slot_of, uniq = _id_table(names)
    if weights is None:
        wts = None
    else:
        wts = np.broadcast_to(np.asarray(weights, dtype=np.float64), (h, w, s))
    flat = samples.reshape(-1, s)
    ids = np.zeros((h * w, ranks), np.float32)
    cov = np.zeros((h * w, ranks), np.float32)
    # fast path: pixels whose samples all see one object (or all background): rank 0, coverage 1
    uniform = (flat == flat[:, :1]).all(axis=1)
    first = flat[uniform, 0].astype(np.int64)
    hit = first >= 0
    if hit.any():
        rows = np.flatnonzero(uniform)[hit]
        ids[rows, 0] = uniq[slot_of[first[hit]]].view(np.float32)
        cov[rows, 0] = 1.0
    mixed = np.flatnonzero(~uniform)
    wflat = None if wts is None else wts.reshape(-1, s)
    step = max(1, rows_per_chunk * w)
    for c0 in range(0, len(mixed), step):
        rows = mixed[c0:c0 + step]
        blk = flat[rows].astype(np.int64)
        sl = np.where(blk >= 0, slot_of[np.clip(blk, 0, None)], -1)
        wt = np.ones(sl.shape) if wflat is None else wflat[rows]
        total = wt.sum(axis=1)
        order = np.argsort(sl, axis=1, kind="stable")
        sl = np.take_along_axis(sl, order, axis=1)
        wt = np.take_along_axis(wt, order, axis=1)
        csum = np.cumsum(wt, axis=1)
        # runs of equal slot: one candidate per run, at its last sample, carrying the run's weight
        start = np.ones_like(sl, dtype=bool)
        start[:, 1:] = sl[:, 1:] != sl[:, :-1]
        last = np.ones_like(sl, dtype=bool)
        last[:, :-1] = start[:, 1:]
        run_start = np.maximum.accumulate(np.where(start, np.arange(s)[None, :], 0), axis=1)
        before = np.take_along_axis(csum - wt, run_start, axis=1)  # weight before the run
        run_w = np.where(last, csum - before, 0.0)
        cand = np.where(last, sl, -1)
        ids[rows], cov[rows] = _top_ranks(cand, run_w, total, uniq, ranks)
    ids = ids.reshape(h, w, ranks)
    cov = cov.reshape(h, w, ranks)
    return RankedMatte(ids, cov)


def id_table(names: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
    """(slot of each name's id in the ascending table of distinct ids (N,) int64, that table
    (U,) uint32): the ranking's tie order."""
    return _id_table(names)


def name_bits(names: Sequence[str]) -> np.ndarray:
    """(N,) float32: the Cryptomatte id of each name, as the float32 its bits make (colliding
    names share one id)."""
    slot_of, uniq = _id_table(names)
    return uniq[slot_of].view(np.float32)


def ranked_matte(base: np.ndarray, names: Sequence[str], ranks: int = DEFAULT_RANKS,
                 edge_pixels: np.ndarray | None = None, edge_samples: np.ndarray | None = None,
                 table: np.ndarray | None = None) -> RankedMatte:
    """The ranked matte of a raster pass sampled once per pixel and R x R times on edge pixels.

    base: (H, W) integer index into `names` of each pixel's one sample (-1: background), or into
    `table` when given (e.g. face indices, with table the face's object: index into `names`);
    edge_pixels (P,) flat pixel indices whose (P, S) `edge_samples` (indices into `names`)
    replace their base sample. A pixel of one sample has its id at coverage 1 (or nothing, on
    background)."""
    base = np.asarray(base)
    h, w = base.shape
    flat = base.reshape(-1)
    slot_of, uniq = _id_table(names)
    # Rank-major planes: each rank's ids and coverages are contiguous (H, W) images, the EXR's
    # channels as they are written; the (H, W, R) arrays handed out are views of them.
    ids = np.zeros((ranks, h * w), np.float32)
    cov = np.zeros((ranks, h * w), np.float32)
    if len(names):
        by_name = uniq[slot_of]
        bits = np.append(by_name if table is None else by_name[table], np.uint32(0)).view(np.float32)
        np.take(bits, flat, out=ids[0])  # (index -1: the last entry, no id)
    np.greater_equal(flat, 0, out=cov[0], casting="unsafe")
    if edge_pixels is not None and len(edge_pixels):
        edge = rank_samples(np.asarray(edge_samples)[None], names, ranks)
        for r in range(ranks):  # one rank at a time: numpy's fast 1-D scatter
            ids[r][edge_pixels] = edge.ids[0, :, r]
            cov[r][edge_pixels] = edge.coverage[0, :, r]
    return RankedMatte(ids.reshape(ranks, h, w).transpose(1, 2, 0), cov.reshape(ranks, h, w).transpose(1, 2, 0))


def rank_coverage(coverage: Mapping[str, np.ndarray], ranks: int = DEFAULT_RANKS) -> RankedMatte:
    """Rank per-name coverage maps: ``{name: (H, W) coverage in [0, 1]}`` (already normalised).

    Names whose ids collide are summed. Iteration order of the mapping does not matter.
    """
    if not coverage:
        raise ValueError("coverage is empty: give the frame size with at least one name")
    names = sorted(coverage)
    slot_of, uniq = _id_table(names)
    shape = np.shape(coverage[names[0]])
    acc = np.zeros(shape + (len(uniq),), np.float64)
    for n, sl in zip(names, slot_of):
        a = np.asarray(coverage[n], dtype=np.float64)
        if a.shape != shape:
            raise ValueError(f"coverage of {n!r} has shape {a.shape}, expected {shape}")
        acc[..., sl] += a
    flat = acc.reshape(-1, len(uniq))
    cand = np.broadcast_to(np.arange(len(uniq)), flat.shape)
    cand = np.where(flat > 0, cand, -1)
    ids, cov = _top_ranks(cand, flat, np.ones(flat.shape[0]), uniq, ranks)
    return RankedMatte(ids.reshape(shape + (ranks,)), cov.reshape(shape + (ranks,)))
