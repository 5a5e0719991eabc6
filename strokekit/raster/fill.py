"""Self-similar volumetric fills (seed 003, Benard et al.'s infinite zoom for solid textures).

Each hit's object-space position P (relative to its object's centre c, object radius R) feeds
4 octaves of one 3D texture. With z the view depth of the hit (seed 003: the camera-space z of
the fragment) expressed in units of the object, z' = z period_px / (f R) (f: focal length in
pixels), k = floor(log2 z') and s = frac(log2 z') (BRIEF 4):

    T_i = 2^(i-1) (P - c) / (R 2^k),   i = 1..4
    a1 = s/2, a2 = 1/2 - s/6, a3 = 1/3 - s/6, a4 = 1/6 - s/6,   h = sum a_i tex(T_i)

Octave i at the end of a zoom cycle is octave i+1 at the start of the next, so the blend is
continuous in z, and octave 1 spans period_px 2^-s output pixels: the marks keep their screen
size under a dolly. T depends on the point and on k only, so nothing slides when the camera
turns. Orthographic cameras use z / f = 1 / f (world size of a pixel), so changing
ortho_height zooms the texture the same way.

Tone map (seed 003 4.2, after Durand et al.): the blended height field h is equalized (its CDF
over the texture) and thresholded by the band's darkness, giving binary marks per band.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from strokekit.raster.rays import RasterHits
from strokekit.scene.load import Scene

#: Hatching planes are perpendicular to this object-space direction.
HATCH_DIR = np.array([0.36, 0.80, 0.48]) / np.linalg.norm([0.36, 0.80, 0.48])


def octave_weights(s: np.ndarray) -> np.ndarray:
    """(..., 4) blend weights of the 4 octaves for zoom-cycle phase s in [0, 1) (seed 003)."""
    s = np.asarray(s, float)
    return np.stack([s / 2, 0.5 - s / 6, 1 / 3 - s / 6, 1 / 6 - s / 6], axis=-1)


def object_frames(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """(O, 3) centres and (O,) radii (world units) of each object's bounding box / sphere: the
    object-space frame the texture is attached to."""
    n = max(len(scene.objects), int(scene.face_object.max(initial=-1)) + 1, 1)
    fo = np.repeat(scene.face_object, 3)
    p = scene.vertices[scene.faces.ravel()]
    lo = np.full((n, 3), np.inf)
    hi = np.full((n, 3), -np.inf)
    np.minimum.at(lo, fo, p)
    np.maximum.at(hi, fo, p)
    ok = np.isfinite(lo[:, 0])
    centre = np.where(ok[:, None], 0.5 * (lo + hi), scene.center)
    r = np.zeros(n)
    np.maximum.at(r, fo, np.linalg.norm(p - centre[fo], axis=1))
    r = np.where(r > 0, r, scene.radius)
    return centre, r


def _hash3(ix: np.ndarray, iy: np.ndarray, iz: np.ndarray) -> np.ndarray:
    """Deterministic lattice hash -> float in [0, 1). Integer arithmetic wraps (uint32)."""
    h = (ix.astype(np.uint32) * np.uint32(0x8DA6B343)) ^ (iy.astype(np.uint32) * np.uint32(0xD8163841)) \
        ^ (iz.astype(np.uint32) * np.uint32(0xCB1AB31F))
    h ^= h >> np.uint32(13)
    h *= np.uint32(0x85EBCA6B)
    h ^= h >> np.uint32(16)
    return h.astype(np.float64) / 4294967296.0


def texture3d(T: np.ndarray, pattern: str) -> np.ndarray:
    """(M,) height field in [0, 1] at texture coordinates T (M, 3); period 1 in texture units.

    hatch: distance to the nearest plane HATCH_DIR.T = integer (0 on the line, 1 half-way);
    dots: distance to the nearest cell centre, normalized; noise: smooth value noise."""
    if pattern == "hatch":
        x = T @ HATCH_DIR
        return np.abs(2.0 * (x - np.floor(x)) - 1.0)
    if pattern == "dots":
        q = T - np.floor(T) - 0.5
        return np.minimum(np.linalg.norm(q, axis=1) / 0.5, 1.0)
    if pattern == "noise":
        i = np.floor(T)
        fr = T - i
        w = fr * fr * (3.0 - 2.0 * fr)  # smoothstep: C1 across cells
        i = i.astype(np.int64)
        out = np.zeros(len(T))
        for dx in (0, 1):
            wx = w[:, 0] if dx else 1 - w[:, 0]
            for dy in (0, 1):
                wy = w[:, 1] if dy else 1 - w[:, 1]
                for dz in (0, 1):
                    wz = w[:, 2] if dz else 1 - w[:, 2]
                    out += wx * wy * wz * _hash3(i[:, 0] + dx, i[:, 1] + dy, i[:, 2] + dz)
        return out
    raise ValueError(f"unknown fill pattern {pattern!r}")


def self_similar_field(points: np.ndarray, obj: np.ndarray, pixel_size: np.ndarray, centres: np.ndarray,
                       radii: np.ndarray, period_px: float, pattern: str) -> np.ndarray:
    """(M,) blended 4-octave texture at world points (M, 3) of objects obj (M,).

    pixel_size (M,): world size of one output pixel at each point (perspective z / f, so this
    is the seed's camera z in units of f; orthographic 1 / f); centres/radii from object_frames.
    The zoom variable is log2(pixel_size * period_px / R): the seed's log2 z with z measured in
    units of the object's size, so s = frac(log2 z) up to that fixed unit."""
    R = radii[obj]
    zl = np.log2(np.maximum(pixel_size * period_px / R, 1e-300))
    k = np.floor(zl)
    s = zl - k
    a = octave_weights(s)
    base = (points - centres[obj]) / (R * np.exp2(k))[:, None]
    h = np.zeros(len(points))
    for i in range(4):
        h += a[:, i] * texture3d(base * (2.0 ** i), pattern)
    return h


@lru_cache(maxsize=None)
def _equalizer(pattern: str) -> tuple[np.ndarray, np.ndarray]:
    """Quantiles of the blended field over random points and zoom phases: (levels, values) so
    that np.interp(h, values, levels) is h's CDF. Fixed seed: deterministic."""
    rng = np.random.default_rng(12345)
    n = 1 << 16
    T = rng.uniform(-64, 64, size=(n, 3))
    s = rng.uniform(0, 1, size=n)
    a = octave_weights(s)
    h = sum(a[:, i] * texture3d(T * (2.0 ** i), pattern) for i in range(4))
    levels = np.linspace(0, 1, 257)
    return levels, np.quantile(h, levels)


def tone_map(h: np.ndarray, darkness: np.ndarray, pattern: str) -> np.ndarray:
    """Binary marks: True (ink) where the equalized height is below the wanted darkness in [0, 1],
    so about a `darkness` fraction of the surface is inked."""
    levels, values = _equalizer(pattern)
    return np.interp(h, values, levels) < darkness


def band_darkness(labels: np.ndarray, n_bands: int) -> np.ndarray:
    """Ink fraction per band label 1..N: 1 - L / (N + 1), so no band is solid black or blank."""
    return 1.0 - labels.astype(np.float64) / (n_bands + 1)


def fill_field(scene: Scene, hits: RasterHits, period_px: float, pattern: str) -> np.ndarray:
    """(HK, WK) float height field of the self-similar texture, NaN on background."""
    face = hits.face.ravel()
    sel = np.flatnonzero(face >= 0)
    centres, radii = object_frames(scene)
    pts = hits.position.reshape(-1, 3)[sel]
    obj = scene.face_object[face[sel]]
    f = hits.camera.focal_px
    if hits.camera.is_ortho:
        pixel_size = np.full(len(sel), 1.0 / f)
    else:
        pixel_size = hits.depth.ravel()[sel].astype(np.float64) / f
    h = self_similar_field(pts, obj, pixel_size, centres, radii, period_px, pattern)
    out = np.full(face.shape, np.nan)
    out[sel] = h
    return out.reshape(hits.shape)


def fill_ink(scene: Scene, hits: RasterHits, labels_ss: np.ndarray, n_bands: int, pattern: str,
             period_px: float) -> np.ndarray:
    """(HK, WK) bool: ink per supersample, from the band tone of each sample (seed 003 4.2)."""
    h = fill_field(scene, hits, period_px, pattern)
    hit = labels_ss > 0
    ink = np.zeros(hits.shape, bool)
    ink[hit] = tone_map(h[hit], band_darkness(labels_ss[hit], n_bands), pattern)
    return ink


def surface_points(scene: Scene, face: np.ndarray, bary: np.ndarray) -> np.ndarray:
    """(M, 3) world points of M hits on faces (M,) (>= 0) at barycentrics (M, 2) (open3d's u, v:
    P = (1 - u - v) A + u B + v C)."""
    tri = scene.faces[face]
    A = scene.vertices[tri[:, 0]]
    u = bary[:, 0:1].astype(np.float64)
    v = bary[:, 1:2].astype(np.float64)
    return A + u * (scene.vertices[tri[:, 1]] - A) + v * (scene.vertices[tri[:, 2]] - A)


def equalized_field(scene: Scene, camera, face: np.ndarray, bary: np.ndarray, depth: np.ndarray, period_px: float,
                    pattern: str) -> np.ndarray:
    """(M,) the blended texture at M hits (faces (M,) >= 0, barycentrics (M, 2), view depths
    (M,)), equalized to [0, 1] by its CDF (`tone_map`: ink where it is below a band's darkness)."""
    centres, radii = object_frames(scene)
    f = camera.focal_px
    pixel_size = np.full(len(face), 1.0 / f) if camera.is_ortho else depth.astype(np.float64) / f
    h = self_similar_field(surface_points(scene, face, bary), scene.face_object[face], pixel_size, centres, radii,
                           period_px, pattern)
    levels, values = _equalizer(pattern)
    return np.interp(h, values, levels)


def _soft_ink(e: np.ndarray, obj: np.ndarray, dark: np.ndarray) -> np.ndarray:
    """Ink share of each sample cell of grids (..., rows, cols): e the equalized field (NaN:
    background), obj the object of each sample, dark the darkness of its band. The threshold
    e < dark is smoothed over the change of e across one cell, |grad e| estimated as the hypot
    of the larger one-sided differences to the neighbour samples of the same object along rows
    and along columns (a shader's fwidth): a cell the mark's edge crosses gets about the share of
    it the mark covers instead of all or nothing. A cell with no neighbour of its object is
    thresholded as it is. (Measured against 8 x 8 binary samples box-filtered, on a hatched
    sphere: with 2 x 2 samples a pixel, mean error 6.9 grey levels, against 11.7 for the 2 x 2
    binary marks strokekit wrote before; at 1 sample a pixel the differences alias the finest
    octave, 14.4, which is why the fill samples 2 x 2.)"""
    ok = np.isfinite(e)
    w2 = np.zeros(e.shape)
    for axis in (-1, -2):
        n = e.shape[axis]
        if n < 2:
            continue
        a = [slice(None)] * e.ndim
        b = [slice(None)] * e.ndim
        a[axis], b[axis] = slice(1, None), slice(None, -1)
        a, b = tuple(a), tuple(b)
        d = np.abs(e[a] - e[b])
        d[~(ok[a] & ok[b] & (obj[a] == obj[b]))] = 0.0
        g = np.zeros(e.shape)
        g[a] = d
        g[b] = np.maximum(g[b], d)
        w2 += g * g
    w = np.sqrt(w2)
    with np.errstate(divide="ignore", invalid="ignore"):
        soft = np.where(w > 1e-9, np.clip(0.5 + (dark - e) / w, 0.0, 1.0), (e < dark).astype(np.float64))
    soft[~ok] = 0.0
    return soft


#: Samples a pixel side the fill draws at least (see _soft_ink).
FILL_SUPERSAMPLE = 2


def fill_coverage(scene: Scene, camera, face: np.ndarray, bary: np.ndarray, depth: np.ndarray, labels: np.ndarray,
                  n_bands: int, pattern: str, period_px: float, mixed=None) -> np.ndarray:
    """(H, W) float64 share of each output pixel inked by the fill (seed 003 marks per band),
    anti-aliased: from a K x K grid of samples a pixel (face (HK, WK) int32, bary (HK, WK, 2),
    depth (HK, WK), labels (HK, WK) uint8; K >= FILL_SUPERSAMPLE), every sample cell gets its ink
    share (`_soft_ink`), a pixel the mean of its cells; the mixed pixels of the raster pass
    (`bands.MixedPixels`: band, material or object edges, R x R samples) the mean of their own
    samples' shares, like the bands."""
    H, W = camera.height, camera.width
    K = face.shape[0] // H
    hit = labels > 0
    e = np.full(face.shape, np.nan)
    sel = np.flatnonzero(hit)
    e.reshape(-1)[sel] = equalized_field(scene, camera, face.reshape(-1)[sel], bary.reshape(-1, 2)[sel],
                                         depth.reshape(-1)[sel], period_px, pattern)
    obj = np.where(face >= 0, np.take(scene.face_object, face, mode="wrap"), -1)
    soft = _soft_ink(e, obj, band_darkness(labels, n_bands))
    ink = soft.reshape(H, K, W, K).mean(axis=(1, 3)) if K > 1 else soft
    if mixed is not None and len(mixed.pixels) and mixed.samples > K * K:
        P, S = mixed.face.shape
        side = int(round(np.sqrt(S)))
        mf, ml = mixed.face.reshape(-1), mixed.labels.reshape(-1)
        es = np.full(P * S, np.nan)
        on = np.flatnonzero(ml > 0)
        es[on] = equalized_field(scene, camera, mf[on], mixed.bary.reshape(-1, 2)[on], mixed.depth.reshape(-1)[on],
                                 period_px, pattern)
        obj_s = np.where(mf >= 0, np.take(scene.face_object, mf, mode="wrap"), -1)
        soft_s = _soft_ink(es.reshape(P, side, side), obj_s.reshape(P, side, side),
                           band_darkness(mixed.labels, n_bands).reshape(P, side, side))
        ink.reshape(-1)[mixed.pixels] = soft_s.reshape(P, S).mean(axis=1)
    return ink
