"""Compositing passes of a frame from its raster pass and its strokes (`compositing_passes` ->
RasterPasses): float view depth, view-space normals, the shade colours in linear light
premultiplied by coverage, band labels, Cryptomatte mattes of objects and materials, and the
strokes as coverage per line kind.

Depth, normals and labels come from the sample nearest each pixel centre (they must not be
averaged across a silhouette); colours and Cryptomatte coverages from all of a pixel's samples.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from strokekit.cryptomatte import rank_samples
from strokekit.errors import UsageError
from strokekit.model import BACKGROUND_DEPTH, CryptoLayer, RasterPasses, Strokes
from strokekit.raster.bands import RasterFrame, band_ramps, representative, sample_n_dot_l
from strokekit.raster.rays import box_filter
from strokekit.raster.strokes import stroke_coverage

#: The passes an EXR can hold, in the order they are written.
PASSES = ("depth", "normal", "shade", "bands", "crypto", "lines")
#: Cryptomatte ranks written per type: two RGBA layers. The issue asks for at least 3; every
#: layer more adds about a tenth to the EXR's write time (ZIP of float32 channels).
RANKS = 4


@dataclass(frozen=True)
class PassOptions:
    """Which compositing passes to compute (PASSES), and the stroke width of the lines pass (px)."""

    passes: tuple[str, ...] = PASSES
    stroke_width_px: float = 1.5

    def __post_init__(self):
        unknown = [p for p in self.passes if p not in PASSES]
        if unknown or not self.passes:
            raise UsageError(f"unknown or no EXR layer(s) {', '.join(unknown) or '(none)'} "
                             f"(known: {', '.join(PASSES)})", option="passes")
        object.__setattr__(self, "passes", tuple(p for p in PASSES if p in self.passes))


def _pixel_samples(frame: RasterFrame, values: np.ndarray) -> np.ndarray:
    """(H, W, K*K) per-pixel view of a per-sample (HK, WK) array."""
    k = frame.hits.supersample
    H, W = frame.hits.height, frame.hits.width
    return values.reshape(H, k, W, k).transpose(0, 2, 1, 3).reshape(H, W, k * k)


def view_normals(frame: RasterFrame) -> np.ndarray:
    """(H, W, 3) float32 view-space normals (x right, y up, z toward the camera) of the sample
    nearest each pixel centre, turned to face the camera, shaded as the bands are (flat or
    smooth); 0 on background."""
    hits, cam, o = frame.hits, frame.camera, frame.options
    k = hits.supersample
    face = representative(hits.face, k)
    bary = representative(hits.bary, k)
    H, W = face.shape
    sel = np.flatnonzero(face.ravel() >= 0)
    rows, cols = np.divmod(sel, W)
    ax, ay = hits.ray_dir_x[cols * k + k // 2], hits.ray_dir_y[rows * k + k // 2]
    out = np.zeros((H * W, 3), np.float32)
    right, up, fwd = cam.basis
    for c, axis in enumerate((right, up, -fwd)):
        out[sel, c] = sample_n_dot_l(frame.scene, cam, face.ravel()[sel], bary.reshape(-1, 2)[sel], ax, ay,
                                     axis, o.shading, None, o.crease_angle_deg)
    return out.reshape(H, W, 3)


def linear_shade(frame: RasterFrame) -> np.ndarray:
    """(H, W, 4) float32: the ramp colour of each sample's material and band, box-filtered in
    linear light, premultiplied by the covered fraction (alpha), as EXR stores colour."""
    ramps = band_ramps(frame.scene, frame.n_bands, frame.options.gooch)
    table = np.concatenate([np.zeros((1, 3)), ramps.reshape(-1, 3)])  # row 0: background
    idx = np.where(frame.labels_ss > 0, 1 + np.maximum(frame.material_ss, 0) * frame.n_bands
                   + frame.labels_ss.astype(np.int32) - 1, 0)
    rgb = box_filter(table[idx].astype(np.float32), frame.hits.supersample)  # background black: premultiplied
    alpha = 1.0 - frame.sample_coverage[..., 0]
    return np.concatenate([rgb, alpha[..., None]], axis=2).astype(np.float32)


def crypto_layers(frame: RasterFrame) -> tuple[CryptoLayer, ...]:
    """CryptoObject and CryptoMaterial of the frame, ranked from every sample of each pixel
    (coverage = the share of the pixel's samples that see the object or material)."""
    scene = frame.scene
    face = frame.hits.face
    hit = face >= 0
    out = []
    for type_name, table, names in (("CryptoObject", scene.face_object, tuple(scene.objects)),
                                    ("CryptoMaterial", scene.face_material, tuple(m.name for m in scene.materials))):
        idx = np.where(hit, table[np.maximum(face, 0)], -1)
        r = rank_samples(_pixel_samples(frame, idx), names, RANKS)
        out.append(CryptoLayer(type_name, r.ids, r.coverage, names))
    return tuple(out)


def compositing_passes(frame: RasterFrame, strokes: Strokes | None, options: PassOptions) -> RasterPasses:
    """The passes `options` asks for, of one frame (its raster pass, and its strokes for 'lines')."""
    p = options.passes
    H, W = frame.hits.height, frame.hits.width
    depth = normal = shade = bands = None
    if "depth" in p:
        z = representative(frame.hits.depth, frame.hits.supersample)
        depth = np.where(np.isfinite(z), z, BACKGROUND_DEPTH).astype(np.float32)
    if "normal" in p:
        normal = view_normals(frame)
    if "shade" in p:
        shade = linear_shade(frame)
    if "bands" in p:
        bands = frame.labels.astype(np.float32)
    crypto = crypto_layers(frame) if "crypto" in p else ()
    lines = None
    if "lines" in p:
        lines = stroke_coverage(strokes, W, H, options.stroke_width_px) if strokes is not None else {}
    return RasterPasses(width=W, height=H, depth=depth, normal=normal, shade=shade, bands=bands, crypto=crypto,
                        lines=lines)
