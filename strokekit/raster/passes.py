"""Compositing passes of a frame from its raster pass and its strokes (`compositing_passes` ->
RasterPasses): float view depth, view-space normals, the shade colours in linear light
premultiplied by coverage, band labels, Cryptomatte mattes of objects and materials, and the
strokes as coverage per line kind.

Depth, normals and labels come from each pixel's representative sample, the one nearest its
centre (they must not be averaged across a silhouette); colours and Cryptomatte coverages from
all the samples of the mixed pixels (the R x R samples at band, material and object edges).
"""

from __future__ import annotations

import numpy as np

from strokekit.cryptomatte import id_table, name_bits
from strokekit.model import BACKGROUND_DEPTH, CryptoLayer, RasterPasses, Strokes
from strokekit.raster.bands import RasterFrame, representative
from strokekit.raster.hits import compiled
from strokekit.raster.options import PassOptions
from strokekit.raster.strokes import stroke_coverage

#: Cryptomatte ranks written per type: two RGBA layers. The issue asks for at least 3; every
#: layer more adds about a tenth to the EXR's write time (ZIP of float32 channels).
RANKS = 4


def view_normals(frame: RasterFrame) -> np.ndarray:
    """(H, W, 3) float32 view-space unit normals (x right, y up, z toward the camera) of each
    pixel's representative sample: the face normal (flat shading) or the corner normals split at
    the raster options' smooth_angle_deg interpolated (smooth: the bands' normals), turned to
    face the camera; 0 on background. A view
    of three contiguous (H, W) planes, the EXR's channels."""
    hits, cam, scene = frame.hits, frame.camera, frame.scene
    H, W = frame.height, frame.width
    if frame.options.shading == "smooth":
        sn = scene.split_normals(frame.options.smooth_angle_deg)
        corner, normals = np.ascontiguousarray(sn.corner, np.int64), np.ascontiguousarray(sn.normals, np.float64)
    else:
        corner, normals = np.zeros((0, 3), np.int64), np.zeros((0, 3))
    right, up, fwd = (np.ascontiguousarray(v, np.float64) for v in cam.basis)
    ortho_dir = np.ascontiguousarray(cam.ray_dir, np.float64) if cam.is_ortho else np.zeros(0)
    out = np.empty((3, H * W), np.float32)
    compiled().view_normals(np.ascontiguousarray(hits.face, np.int32), np.ascontiguousarray(hits.bary, np.float32),
                            frame.K, corner, normals, np.ascontiguousarray(scene.face_normals, np.float64),
                            right, up, fwd, np.ascontiguousarray(hits.ray_dir_x, np.float64),
                            np.ascontiguousarray(hits.ray_dir_y, np.float64), ortho_dir, out)
    return out.reshape(3, H, W).transpose(1, 2, 0)


def linear_shade(frame: RasterFrame) -> np.ndarray:
    """(H, W, 4) float32: the ramp colour of each pixel's material and band in linear light,
    premultiplied by the covered share A (EXR's convention); mixed pixels the mean over their
    samples (background samples count black). A view of four contiguous (H, W) planes."""
    lin = frame._key_colours()
    N1 = frame.n_bands + 1
    table = np.zeros((4, len(lin)), np.float32)
    table[:3] = lin.T
    table[3] = np.arange(len(lin)) % N1 != 0
    key = np.ascontiguousarray(representative(frame.keys_ss, frame.K), np.int32).reshape(-1)
    out = np.empty((4, frame.height * frame.width), np.float32)
    compiled().table_planes(key, table, out)
    m = frame.mixed
    if m is not None:
        n, rgb = frame._mixed_sums(lin)
        covered = n[:, 1:].sum(axis=1)
        out[:3, m.pixels] = (rgb / m.samples).T
        out[3, m.pixels] = covered / m.samples
    return out.reshape(4, frame.height, frame.width).transpose(1, 2, 0)


def crypto_layers(frame: RasterFrame) -> tuple[CryptoLayer, ...]:
    """CryptoObject and CryptoMaterial of the frame: a uniform pixel has its representative
    sample's object (material) at coverage 1, a mixed pixel the ranked shares of its R x R
    samples (cryptomatte.ranked_matte's matte, compiled)."""
    scene = frame.scene
    H, W = frame.height, frame.width
    face = np.ascontiguousarray(representative(frame.hits.face, frame.K), np.int32).reshape(-1)
    m = frame.mixed
    out = []
    for type_name, table, names in (("CryptoObject", scene.face_object, tuple(scene.objects)),
                                    ("CryptoMaterial", scene.face_material, tuple(m_.name for m_ in scene.materials))):
        # Rank-major planes: each rank's ids and coverages are contiguous (H, W) images, the
        # EXR's channels as they are written; the (H, W, R) arrays handed out are views of them.
        ids = np.zeros((RANKS, H * W), np.float32)
        cov = np.zeros((RANKS, H * W), np.float32)
        if names:
            compiled().crypto_rank0(face, np.ascontiguousarray(table, np.int32), name_bits(names), ids[0], cov[0])
        if m is not None and len(m.pixels):
            slot_of, uniq = id_table(names)
            face_slot = slot_of[table] if len(names) else np.zeros(len(table), np.int64)
            slots = np.where(m.face >= 0, face_slot[np.maximum(m.face, 0)], -1).astype(np.int32)
            e_ids = np.zeros((RANKS, len(m.pixels)), np.float32)
            e_cov = np.zeros((RANKS, len(m.pixels)), np.float32)
            compiled().crypto_ranks(slots, uniq.view(np.float32), e_ids, e_cov)
            for r in range(RANKS):  # one rank at a time: numpy's fast 1-D scatter
                # (the ranks a pixel does not fill stay 0 untouched: writing zeros over the planes
                # of the upper ranks, mostly empty, would fault in all their memory)
                at = np.flatnonzero(e_cov[r] > 0) if r else slice(None)
                ids[r][m.pixels[at]] = e_ids[r, at]
                cov[r][m.pixels[at]] = e_cov[r, at]
        out.append(CryptoLayer(type_name, ids.reshape(RANKS, H, W).transpose(1, 2, 0),
                               cov.reshape(RANKS, H, W).transpose(1, 2, 0), names))
    return tuple(out)


def compositing_passes(frame: RasterFrame, strokes: Strokes | None, options: PassOptions,
                       lines_coverage: dict | None = None) -> RasterPasses:
    """The passes `options` asks for, of one frame (its raster pass, and its strokes for 'lines');
    `lines_coverage`: the
    strokes' coverage at options.stroke_width_px when the caller has it (stroke_coverage)."""
    p = options.passes
    H, W = frame.height, frame.width
    depth = normal = shade = bands = None
    if "depth" in p:
        z = representative(frame.hits.depth, frame.K)
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
        if lines_coverage is not None:
            lines = lines_coverage
        else:
            lines = stroke_coverage(strokes, W, H, options.stroke_width_px) if strokes is not None else {}
    return RasterPasses(width=W, height=H, depth=depth, normal=normal, shade=shade, bands=bands, crypto=crypto,
                        lines=lines)
