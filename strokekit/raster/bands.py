"""Toon bands (seed 002, seed 001 section 6, seed 000 section 2.1.1): quantized Lambert shading
from the raster pass, per-material 1D ramps, anti-aliased band masks and band polygons.

Labels: 0 is background, 1..N are bands from darkest to brightest. With N bands and no explicit
thresholds the band of a sample is floor(max(0, n.l) N) (seed 002: floor(diffuse * levels)),
with n.l = 1 put in the top band. Lighting is two-sided: the normal is turned to face the viewer,
so open meshes and inconsistent windings (common in glTF) are lit from the side we see.

How a frame is sampled (`render_raster`): the z-buffer (`raster.hits`, numba kernels) gives the
first surface at K x K samples per pixel (K = supersample; 1 by default), and each sample gets
its label. Pixels whose samples, or the nearest samples of their neighbours, carry different
labels, materials or objects, and pixels a face thinner than the sample spacing crosses, are
resampled R x R (R = edge_supersample; 4 by default): the "mixed" pixels. Every other pixel is
uniform: one label, one colour, one id. Images are built from the representative sample of each
pixel plus the mixed pixels' samples, never from a supersampled image of colours.

Entry points: `render_raster(scene, camera, occluder, options) -> RasterFrame`,
`RasterFrame.images() -> {suffix: image}` and `band_regions(frame) -> [BandRegion]`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np

from strokekit.camera.view import Camera
from strokekit.colour import srgb_encode
from strokekit.model import BandRegion
from strokekit.raster.fill import FILL_SUPERSAMPLE, fill_coverage
from strokekit.raster.hits import RayHits, ZBufferHits, compiled, ensure_kernels
from strokekit.raster.options import RasterOptions
from strokekit.raster.rays import RasterHits
from strokekit.scene.load import Scene
from strokekit.scene.occluder import Occluder
from strokekit.scene.tables import corner_gram, min_interpolated_norm

#: The ramp's darkest shade, as a fraction of the base colour (seed 000 Fig 2.7: shades are the
#: base colour darkened).
RAMP_DARKEST = 0.45


# --- shading --------------------------------------------------------------------------------------

def light_direction(camera: Camera, options: RasterOptions) -> np.ndarray:
    """(3,) unit world vector toward the light."""
    l = np.asarray(options.light, float)
    if options.light_space == "camera":
        right, up, fwd = camera.basis
        l = l[0] * right + l[1] * up - l[2] * fwd
    return l / np.linalg.norm(l)


def back_facing(scene: Scene, camera: Camera) -> np.ndarray:
    """(F,) bool: we see the back of the face (its winding normal points away from the viewer).
    One answer per face: its corners lie in its plane, so n.(P - eye) is one number over it
    (perspective), and a parallel camera's rays share one direction (camera.ray_dir: fwd but for
    the oblique projections)."""
    nf = scene.face_normals
    if camera.is_ortho:
        return nf @ camera.ray_dir > 0
    return scene.face_offsets - nf @ camera.eye_array > 0


def corner_shading(scene: Scene, smooth_angle_deg: float = 30.0, vnormals: np.ndarray | None = None
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(corner (F, 3) node of each face corner, normals (N, 3) unit node normals, gram (F, 3)
    n_a.n_b, n_b.n_c, n_c.n_a of each face's corner normals) for smooth shading.

    The nodes and normals are `scene.split_normals(smooth_angle_deg)` (angle-weighted, Blender's
    auto smooth rule): corners share a normal only across edges flatter than the angle, so a
    face next to a sharp edge keeps its own normal there.
    With `vnormals` (V, 3) those vertex normals are interpolated instead, unsplit."""
    if vnormals is not None:
        return scene.faces, np.asarray(vnormals, float), corner_gram(scene.faces, np.asarray(vnormals, float))
    sn = scene.split_normals(smooth_angle_deg)
    return sn.corner, sn.normals, sn.corner_gram


def quantize_bands(ndl: np.ndarray, bands: int, thresholds: tuple[float, ...] = ()) -> np.ndarray:
    """uint8 labels, same shape as ndl: 0 where ndl is NaN (background), else 1..N.

    Without thresholds: 1 + floor(max(0, n.l) N), n.l = 1 kept in band N (seed 002)."""
    x = np.asarray(ndl)
    bg = np.isnan(x)
    if bg.any():
        x = np.where(bg, 0.0, x)
    if thresholds:
        lab = np.searchsorted(np.asarray(thresholds, x.dtype), x, side="right") + 1
    else:
        # Negative n.l (and NaN) fall below 0 after the product; clipping puts them in band 1.
        lab = np.clip(np.floor(x * bands), 0, bands - 1) + 1
    lab = lab.astype(np.uint8)
    lab[bg] = 0
    return lab


def band_ramps(scene: Scene, bands: int, gooch: bool = False) -> np.ndarray:
    """(materials, N, 3) float linear RGB in [0, 1]: per material a 1D ramp from darker shades of its
    base colour (band 1) up to the base colour (band N) (seed 000 Fig 2.7/2.8). With `gooch`,
    the ramp goes from a cool (blue) to a warm (yellow) tone mixed with the base colour
    (Gooch et al. 1998 constants)."""
    mats = scene.materials or ()
    base = np.array([m.base_color[:3] for m in mats], float).reshape(-1, 3)
    if len(base) == 0:
        base = np.array([[0.8, 0.8, 0.8]])
    t = np.linspace(0.0, 1.0, bands) if bands > 1 else np.ones(1)
    if gooch:
        cool = np.array([0.0, 0.0, 0.55]) + 0.25 * base
        warm = np.array([0.3, 0.3, 0.0]) + 0.5 * base
        ramp = (1 - t)[None, :, None] * cool[:, None, :] + t[None, :, None] * warm[:, None, :]
    else:
        k = RAMP_DARKEST + (1 - RAMP_DARKEST) * t
        ramp = base[:, None, :] * k[None, :, None]
    return np.clip(ramp, 0.0, 1.0)




# --- per-face tables of a frame -------------------------------------------------------------------

#: Label table entry of a face whose samples are not all in one band: interpolate per sample.
_PER_SAMPLE = 255
_NO_COEF = np.zeros((0, 7))
_NO_REGION = np.zeros(0, np.int32)


@dataclass(frozen=True, eq=False)
class FaceShading:
    """What a frame's samples need of their faces, computed once per frame (F faces).

    label (F + 1,) uint8: the band label of every sample on the face when they all have one
    (flat shading, and smooth faces whose whole range of n.l falls in one band), _PER_SAMPLE where
    it is found per sample; entry F is 0, the label of face -1 (background), so label[face] labels
    a face array directly. lo, hi (F,) uint8: the lowest and highest label a sample on the face
    can get; back (F,) bool: we see its back. coef (F, 7) float64 for smooth shading: the corner
    normals' n.l (a, b, c), their pairwise dot products (ab, bc, ca) and the two-sided sign.
    region (F,) int32: the face's (material, object) pair as an index; key = label + (N + 1)
    region tells samples of another band, material or object apart (0: background)."""

    label: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    back: np.ndarray
    coef: np.ndarray | None
    region: np.ndarray | None
    region_material: np.ndarray
    region_object: np.ndarray
    bands: int
    thresholds: tuple

    def labels(self, face: np.ndarray, bary: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(labels uint8, keys int32) of samples on faces `face` (any shape, -1 background) at
        barycentrics `bary` (face.shape + (2,)): compiled (`raster.compiled.label_samples`)."""
        lab = np.empty(face.shape, np.uint8)
        key = np.empty(face.shape, np.int32)
        compiled().label_samples(np.ascontiguousarray(face).reshape(-1), np.ascontiguousarray(bary).reshape(-1, 2),
                                 self.label, self.coef if self.coef is not None else _NO_COEF, self.bands,
                                 np.asarray(self.thresholds, np.float64),
                                 self.region if self.region is not None else _NO_REGION,
                                 lab.reshape(-1), key.reshape(-1))
        return lab, key

    @property
    def n_regions(self) -> int:
        return len(self.region_material)


def face_shading(scene: Scene, camera: Camera, options: RasterOptions, light: np.ndarray,
                 vnormals: np.ndarray | None = None) -> FaceShading:
    """The frame's FaceShading. Band ranges: flat shading has one n.l per face; smooth shading's
    interpolated numerator (wa la + wb lb + wc lc) is linear, so its extremes are corner values,
    and the renormalization divides it by |n| in [sqrt(min n_i.n_j), 1] (|sum w_i n_i|^2 = sum
    w_i w_j n_i.n_j >= min n_i.n_j). Two-sided lighting flips the sign on the back side, which is
    the same over a whole face (`back_facing`)."""
    back = back_facing(scene, camera)
    sign = np.where(back, -1.0, 1.0)
    N, th = int(options.bands), options.thresholds
    coef = None
    if options.shading == "flat":
        lo = hi = quantize_bands(sign * (scene.face_normals @ light), N, th)
    else:
        corner, normals, gram = corner_shading(scene, options.smooth_angle_deg, vnormals)
        nl = normals @ light
        la, lb, lc = (np.take(nl, corner[:, k]) for k in range(3))
        lmin, lmax = np.minimum(np.minimum(la, lb), lc), np.maximum(np.maximum(la, lb), lc)
        root = _min_norm(scene, options.smooth_angle_deg, vnormals)
        LO = np.where(lmin >= 0, lmin, lmin / root)
        HI = np.where(lmax >= 0, lmax / root, lmax)
        lo = quantize_bands(np.where(back, -HI, LO), N, th)
        hi = quantize_bands(np.where(back, -LO, HI), N, th)
        coef = np.column_stack([la, lb, lc, gram, sign])
    label = np.zeros(len(lo) + 1, np.uint8)
    label[:-1] = np.where(lo == hi, lo, _PER_SAMPLE)
    region, rmat, robj = scene.regions
    return FaceShading(label=label, lo=lo, hi=hi, back=back, coef=coef, region=region, region_material=rmat,
                       region_object=robj, bands=N, thresholds=th)


def _min_norm(scene: Scene, smooth_angle_deg: float, vnormals: np.ndarray | None) -> np.ndarray:
    """(F,) a lower bound of |w_a n_a + w_b n_b + w_c n_c| over each face (weights >= 0 summing
    to 1) for smooth shading's corner normals (`tables.min_interpolated_norm`)."""
    if vnormals is None:
        return scene.split_normals(smooth_angle_deg).min_corner_norm
    return min_interpolated_norm(corner_shading(scene, smooth_angle_deg, vnormals)[2])


#: Relative depth slack of the thin-triangle occlusion test (float32 depths, curvature between
#: samples).
THIN_DEPTH_SLACK = 1e-3


# --- a frame's samples -> output images -----------------------------------------------------------

def representative(img: np.ndarray, k: int) -> np.ndarray:
    """The sample nearest each output pixel's centre (for ids and depth, which must not be
    averaged, and for the uniform pixels): index (k//2, k//2) of each k x k block."""
    return img[k // 2::k, k // 2::k] if k > 1 else img


def _block_samples(img: np.ndarray, k: int, pixels: np.ndarray) -> np.ndarray:
    """(P, k*k, ...) the samples of output pixels `pixels` (flat indices) in a (H*k, W*k, ...)
    grid, row-major inside each pixel."""
    HK, WK = img.shape[:2]
    py, px = np.divmod(pixels, WK // k)
    sub = np.arange(k)
    rows = (py[:, None] * k + np.repeat(sub, k)[None, :])
    cols = (px[:, None] * k + np.tile(sub, k)[None, :])
    return img.reshape(HK * WK, *img.shape[2:])[rows * WK + cols]


@dataclass(frozen=True, eq=False)
class MixedPixels:
    """The pixels whose samples may disagree, with their own samples: pixels (P,) flat indices
    py * W + px, increasing; S samples each (R x R edge resampling, or the K x K samples of the
    grid), sample b * side + a at (px + (a + 0.5) / side, py + (b + 0.5) / side); face (P, S)
    int32, bary (P, S, 2) float32, depth (P, S) float32, labels (P, S) uint8, keys (P, S) int32."""

    pixels: np.ndarray
    face: np.ndarray
    bary: np.ndarray
    depth: np.ndarray
    labels: np.ndarray
    keys: np.ndarray

    @property
    def samples(self) -> int:
        return int(self.face.shape[1])

    @cached_property
    def counts(self) -> np.ndarray:
        """(P, n_labels) int64 samples of each label (n_labels: max label + 1)."""
        n = int(self.labels.max(initial=0)) + 1
        counts = np.empty((len(self.labels), n), np.int64)
        compiled().label_counts(np.ascontiguousarray(self.labels), counts)
        return counts

    def coverage(self, n_labels: int) -> np.ndarray:
        """(P, n_labels) float32 share of each label."""
        c = np.zeros((len(self.pixels), n_labels), np.float32)
        k = min(n_labels, self.counts.shape[1])
        c[:, :k] = self.counts[:, :k] / np.float32(self.samples)
        return c


@dataclass(frozen=True, eq=False)
class RasterFrame:
    """One frame's raster products: the K x K sample grid (hits, labels_ss, keys_ss) and the
    mixed pixels (or None); everything at output resolution is derived on demand, from the
    representative sample of each uniform pixel and the samples of the mixed ones."""

    scene: Scene
    camera: Camera
    options: RasterOptions
    hits: RasterHits
    labels_ss: np.ndarray
    light: np.ndarray
    shading: FaceShading
    keys_ss: np.ndarray
    mixed: MixedPixels | None = None
    source: object = None  # the frame's raster.hits sample source (more samples on demand: the fill)

    @property
    def n_bands(self) -> int:
        return int(self.options.bands)

    @property
    def K(self) -> int:
        return int(self.hits.supersample)

    @property
    def width(self) -> int:
        return int(self.camera.width)

    @property
    def height(self) -> int:
        return int(self.camera.height)

    @property
    def edge_coverage(self) -> tuple | None:
        """(pixel flat indices (P,), coverages (P, N+1)) of the R x R resampled pixels, or None."""
        if self.mixed is None or int(self.options.edge_supersample) <= self.K:
            return None
        return self.mixed.pixels, self.mixed.coverage(self.n_bands + 1)

    @cached_property
    def rep_labels(self) -> np.ndarray:
        """(H, W) uint8 label of each pixel's representative sample."""
        return representative(self.labels_ss, self.K)

    @cached_property
    def coverage(self) -> np.ndarray:
        """(H, W, N+1) float32: the share of background (0) and of each band in every pixel."""
        n = self.n_bands + 1
        cov = np.zeros((self.height * self.width, n), np.float32)
        cov[np.arange(cov.shape[0]), self.rep_labels.reshape(-1)] = 1.0
        if self.mixed is not None:
            cov[self.mixed.pixels] = self.mixed.coverage(n)
        return cov.reshape(self.height, self.width, n)

    @cached_property
    def labels(self) -> np.ndarray:
        """(H, W) uint8: the label covering most of each output pixel (ties: the lower label)."""
        lab = self.rep_labels.copy()
        if self.mixed is not None:
            lab.reshape(-1)[self.mixed.pixels] = np.argmax(self.mixed.counts, axis=1)
        return lab

    def mask(self, band: int) -> np.ndarray:
        """(H, W) uint8 anti-aliased mask of band 1..N (0 for background), 255 = fully covered."""
        m = np.where(self.rep_labels == band, np.uint8(255), np.uint8(0))
        if self.mixed is not None:
            c = self.mixed.counts
            share = c[:, band] if band < c.shape[1] else np.zeros(len(c))
            m.reshape(-1)[self.mixed.pixels] = np.round(share * (255.0 / self.mixed.samples)).astype(np.uint8)
        return m

    def _key_colours(self) -> np.ndarray:
        """(keys, 3) float64 linear ramp colour of every sample key (row 0 and every label 0:
        black): key = label + (N + 1) region."""
        sh, N = self.shading, self.n_bands
        ramps = band_ramps(self.scene, N, self.options.gooch)
        mat = np.minimum(np.maximum(sh.region_material, 0), len(ramps) - 1)
        table = np.zeros((sh.n_regions, N + 1, 3))
        table[:, 1:] = ramps[mat]
        return table.reshape(-1, 3)

    def shade_image(self) -> np.ndarray:
        """(H, W, 4) uint8 RGBA: the ramp colour of each pixel's material and band; mixed pixels
        the mean colour of their covered samples (in linear light) with alpha = covered share
        (straight, not premultiplied, alpha in the PNG). sRGB-encoded (the scene's colours are
        linear: a base colour 0.4 is written as 170, not 102)."""
        lin = self._key_colours()
        table = np.zeros((len(lin), 4), np.uint8)
        table[:, :3] = np.round(np.clip(srgb_encode(lin), 0, 1) * 255.0)
        table[:, 3] = 255
        table[::self.n_bands + 1] = 0  # label 0: background
        # One 4-byte gather a pixel.
        out = table.view(np.uint32)[:, 0][representative(self.keys_ss, self.K)]
        out = out.view(np.uint8).reshape(self.height, self.width, 4)
        m = self.mixed
        if m is not None:
            n, rgb = self._mixed_sums(lin)
            covered = n[:, 1:].sum(axis=1)
            px = np.concatenate([srgb_encode(rgb / np.maximum(covered, 1)[:, None]), (covered / m.samples)[:, None]],
                                axis=1)
            out.reshape(-1, 4)[m.pixels] = np.round(np.clip(px, 0, 1) * 255.0).astype(np.uint8)
        return out

    def _mixed_sums(self, lin: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        m = self.mixed
        counts = np.empty((len(m.pixels), self.n_bands + 1), np.int32)
        rgb = np.empty((len(m.pixels), 3))
        compiled().mixed_sums(m.labels, m.keys, lin, self.n_bands + 1, counts, rgb)
        return counts, rgb

    def objectid_image(self) -> np.ndarray:
        """(H, W) uint8 (uint16 past 254 objects): 0 background, object index + 1, of each pixel's
        representative sample (ids are not averaged)."""
        f = representative(self.hits.face, self.K)
        table = np.zeros(len(self.scene.faces) + 1, np.uint16 if len(self.scene.objects) >= 255 else np.uint8)
        table[:-1] = self.scene.face_object + 1
        return table[f]

    def depth_range(self) -> tuple[float, float]:
        """(z_near, z_far) world units mapped to 0 and 65534 in the depth PNG: the scene's bounding
        sphere along the view axis, so the mapping only moves with the camera."""
        _, _, fwd = self.camera.basis
        zc = float((self.scene.center - np.asarray(self.camera.eye)) @ fwd)
        zn = max(zc - self.scene.radius, self.camera.near_distance(self.scene.radius))
        return zn, max(zc + self.scene.radius, zn * (1 + 1e-9) + 1e-300)

    def depth_image(self) -> np.ndarray:
        """(H, W) uint16 linear view depth: 0 at z_near, 65534 at z_far (see depth_range), 65535
        background (of each pixel's representative sample)."""
        z = representative(self.hits.depth, self.K)
        zn, zf = self.depth_range()
        with np.errstate(invalid="ignore"):
            q = np.clip(np.round((z - zn) * np.float32(65534.0 / (zf - zn))), 0, 65534)
        return np.where(np.isfinite(z), q, 65535).astype(np.uint16)

    def fill_image(self) -> np.ndarray:
        """(H, W) uint8 grey: seed 003 marks per band (0 ink, 255 paper), anti-aliased (see
        raster.fill.fill_coverage): at least FILL_SUPERSAMPLE x FILL_SUPERSAMPLE samples a pixel
        (a grid of its own when the frame's is coarser), the mixed pixels' R x R samples."""
        o = self.options
        h = self.hits
        if self.K >= FILL_SUPERSAMPLE or self.source is None:
            face, bary, depth, labels = h.face, h.bary, h.depth, self.labels_ss
        else:
            face, bary, depth = self.source.grid(FILL_SUPERSAMPLE, own=True)
            labels, _ = self.shading.labels(face, bary)
        ink = fill_coverage(self.scene, self.camera, face, bary, depth, labels, self.n_bands, o.fill_pattern,
                            o.fill_period_px, self.mixed)
        return np.round(255.0 * (1.0 - ink)).astype(np.uint8)

    def images(self, timings: dict | None = None) -> dict[str, np.ndarray]:
        """{file suffix: image} of what the options ask: 'bands' always, then 'shade',
        'mask1'..'maskN', 'objectid', 'depth', 'fill' (uint8 or uint16 arrays, see each method);
        writers.png.png_files encodes them."""
        o = self.options
        out = {"bands": self.labels}
        if o.shade:
            out["shade"] = self.shade_image()
        if o.masks:
            for b in range(1, self.n_bands + 1):
                out[f"mask{b}"] = self.mask(b)
        if o.objectid:
            out["objectid"] = self.objectid_image()
        if o.depth:
            out["depth"] = self.depth_image()
        if o.fill:
            out["fill"] = self.fill_image()
        return out

    # --- vector bands ----------------------------------------------------------------------
    def region_keys(self) -> tuple[np.ndarray, dict[int, tuple[int, int]]]:
        """(H, W) int32 region key per output pixel (0 background) and {key: (material, band)}.
        A region is one band of one material; its material is the highest material index
        among the pixel's samples (deterministic)."""
        lab = self.labels.astype(np.int32)
        fm = np.zeros(len(self.scene.faces) + 1, np.int64)
        fm[:-1] = self.scene.face_material
        mat = fm[representative(self.hits.face, self.K)]
        if self.mixed is not None:
            mat.reshape(-1)[self.mixed.pixels] = fm[self.mixed.face].max(axis=1)
        key = np.where(lab > 0, mat * self.n_bands + lab, 0)
        keys = np.unique(key[key > 0])
        return key, {int(q): (int((q - 1) // self.n_bands), int((q - 1) % self.n_bands + 1)) for q in keys}

    def band_polygons(self, tolerance_px: float = 0.5) -> dict[int, object]:
        """{region key: shapely (Multi)Polygon with holes} in output pixel coordinates, traced from
        the label image (unions of pixel squares) and simplified within `tolerance_px`."""
        key, _ = self.region_keys()
        return label_polygons(key, tolerance_px)


def band_regions(frame: RasterFrame, tolerance_px: float = 0.5) -> list[BandRegion]:
    """The frame's band regions, in region-key order, traced from its label image and simplified
    within `tolerance_px` (see label_polygons); regions with no polygon left are dropped."""
    key, meaning = frame.region_keys()
    polys = label_polygons(key, tolerance_px)
    ramps = band_ramps(frame.scene, frame.n_bands, frame.options.gooch)
    out = []
    for q in sorted(polys):
        mat, band = meaning[q]
        rings = []
        for p in getattr(polys[q], "geoms", [polys[q]]):
            if p.is_empty or p.geom_type != "Polygon":
                continue
            rings.append(np.asarray(p.exterior.coords))
            rings.extend(np.asarray(h.coords) for h in p.interiors)
        if rings:
            out.append(BandRegion(mat, band, rings, ramps[min(mat, len(ramps) - 1), band - 1]))
    return out


def label_polygons(key: np.ndarray, tolerance_px: float = 0.5) -> dict[int, object]:
    """{label: shapely geometry} for every non-zero label of an (H, W) integer image.

    Pixel (i, j) is the square [i, i+1] x [j, j+1]. Runs of equal labels along rows are merged
    with identical runs of the rows below into rectangles, and the rectangles of one label are
    unioned: few shapes even on large images, and holes come out of the union."""
    import shapely

    H, W = key.shape
    brk = np.ones((H, W + 1), bool)
    brk[:, 1:W] = key[:, 1:] != key[:, :-1]
    r, c = np.nonzero(brk)  # run boundaries, row-major
    # Consecutive boundaries in one row delimit runs; the last boundary of a row (c == W) ends it.
    same_row = r[1:] == r[:-1]
    r0, x0, x1 = r[:-1][same_row], c[:-1][same_row], c[1:][same_row]
    lab = key[r0, x0]
    keep = lab != 0
    r0, x0, x1, lab = r0[keep], x0[keep], x1[keep], lab[keep]
    if len(lab) == 0:
        return {}
    # Vertical merge: identical (label, x0, x1) runs on consecutive rows form one rectangle.
    order = np.lexsort((r0, x1, x0, lab))
    r0, x0, x1, lab = r0[order], x0[order], x1[order], lab[order]
    new = np.ones(len(lab), bool)
    new[1:] = (lab[1:] != lab[:-1]) | (x0[1:] != x0[:-1]) | (x1[1:] != x1[:-1]) | (r0[1:] != r0[:-1] + 1)
    start = np.flatnonzero(new)
    y0 = r0[start]
    y1 = np.maximum.reduceat(r0, start) + 1
    bx0, bx1, blab = x0[start], x1[start], lab[start]
    boxes = shapely.box(bx0, y0, bx1, y1)
    out = {}
    bounds = np.flatnonzero(np.r_[True, blab[1:] != blab[:-1]])
    ends = np.r_[bounds[1:], len(blab)]
    for s, e in zip(bounds, ends):  # one union per label: few labels
        geom = shapely.union_all(boxes[s:e])
        out[int(blab[s])] = geom.simplify(tolerance_px, preserve_topology=True) if tolerance_px > 0 else geom
    return out




# --- entry points ---------------------------------------------------------------------------------

def render_raster(scene: Scene, camera: Camera, occluder: Occluder | None, options: RasterOptions,
                  vnormals: np.ndarray | None = None, *, reference: bool = False,
                  work=None, timings: dict | None = None, threads: int = 1) -> RasterFrame:
    """Sample one frame and label its bands. Call only when a raster output is asked for.

    The z-buffer rasterizer samples it (`raster.hits.ZBufferHits`); `reference=True` casts Embree
    rays through the same samples instead (`occluder`, the scene's; not needed otherwise): the
    reference tests and `strokekit bench` hold the rasterizer against. Smooth shading uses the
    normals split at options.smooth_angle_deg (cached per scene); `vnormals` (V, 3) replaces
    them by given vertex normals, interpolated without splitting.
    `work`: a zbuffer.Workspace whose buffers the frame then uses (until the next frame drawn
    with it; `raster.hits.thread_workspace()`). `timings`: {stage: seconds} gets 'rasterize'
    (the sample grid), 'shading' (labels, mixed pixels) and 'edge samples' (their R x R samples).
    `threads`: the z-buffer's (the same arrays for any count)."""
    ensure_kernels()  # (loaded, or compiled, before the frame's clock starts)
    t0 = time.perf_counter()
    if reference:
        if occluder is None:
            occluder = Occluder(scene)
        src = RayHits(scene, camera, occluder)
    else:
        src = ZBufferHits(scene, camera, work, threads)
    K = int(options.supersample)
    face, bary, depth = src.grid(K)
    W, H, f = int(camera.width), int(camera.height), camera.focal_px
    hits = RasterHits(face=face, bary=bary, depth=depth, camera=camera, supersample=K,
                      ray_dir_x=((np.arange(W * K) + 0.5) / K - W / 2.0) / f,
                      ray_dir_y=(H / 2.0 - (np.arange(H * K) + 0.5) / K) / f)
    t1 = time.perf_counter()
    light = light_direction(camera, options)
    shading = face_shading(scene, camera, options, light, vnormals)
    labels_ss, keys_ss = shading.labels(face, bary)
    frame = RasterFrame(scene=scene, camera=camera, options=options, hits=hits, labels_ss=labels_ss, light=light,
                        shading=shading, keys_ss=keys_ss, source=src)
    R = int(options.edge_supersample)
    t3 = None
    mixed = None
    if R > K:
        pix = _mixed_pixels(frame, src)
        t2b = time.perf_counter()
        if len(pix):
            ef, eb, ed = src.pixels(pix, R)
            t3 = time.perf_counter()
            el, ek = shading.labels(ef, eb)
            mixed = MixedPixels(pixels=pix, face=ef, bary=eb, depth=ed, labels=el, keys=ek)
    elif K > 1:
        k0 = keys_ss[::K, ::K]
        differ = np.zeros(k0.shape, bool)
        for dy in range(K):
            for dx in range(K):
                if dy or dx:
                    differ |= keys_ss[dy::K, dx::K] != k0
        pix = np.flatnonzero(differ)
        if len(pix):
            mixed = MixedPixels(pixels=pix, face=_block_samples(face, K, pix), bary=_block_samples(bary, K, pix),
                                depth=_block_samples(depth, K, pix), labels=_block_samples(labels_ss, K, pix),
                                keys=_block_samples(keys_ss, K, pix))
    t4 = time.perf_counter()
    if timings is not None:
        edge = (t3 - t2b) if t3 is not None else 0.0
        timings["rasterize"] = timings.get("rasterize", 0.0) + (t1 - t0)
        timings["edge samples"] = timings.get("edge samples", 0.0) + edge
        timings["shading"] = timings.get("shading", 0.0) + (t4 - t1) - edge
    return replace(frame, mixed=mixed) if mixed is not None else frame


def _mixed_pixels(frame: RasterFrame, src) -> np.ndarray:
    """Flat indices (increasing) of the output pixels that may hold more than one key (label,
    material, object): the pixels whose K x K samples disagree or differ from a next sample of a
    neighbouring pixel (`_sample_edge_pixels`), and the pixels a triangle too thin for the K x K
    grid crosses where it may show another key than the samples there (`_thin_face_pixels`)."""
    edge = _sample_edge_pixels(frame.keys_ss, frame.K)
    _thin_face_pixels(frame, src, edge)
    return np.flatnonzero(edge)


def _sample_edge_pixels(keys_ss: np.ndarray, k: int) -> np.ndarray:
    """(H, W) bool: output pixels with a sample whose key differs from one of its 8 neighbour
    samples, i.e. whose K x K samples plus the ring of nearest samples of the neighbouring pixels
    do not all agree. An edge between two samples a sample spacing apart may run through
    either of their pixels, so both are refined (a pixel-majority rule misses an edge that only
    grazes a pixel, and refines pixels whose own samples are a full spacing from any edge)."""
    L = keys_ss
    E = np.zeros(L.shape, bool)
    dh = L[:, 1:] != L[:, :-1]
    dv = L[1:, :] != L[:-1, :]
    E[:, 1:] |= dh
    E[:, :-1] |= dh
    E[1:, :] |= dv
    E[:-1, :] |= dv
    # Diagonal neighbours: two diagonal samples differ only if their 2 x 2 square has an
    # axis-aligned difference; mark all four samples of such squares.
    sq = dh[1:, :] | dh[:-1, :]
    sq |= dv[:, 1:]
    sq |= dv[:, :-1]
    E[1:, 1:] |= sq
    E[:-1, :-1] |= sq
    E[1:, :-1] |= sq
    E[:-1, 1:] |= sq
    if k == 1:
        return E
    out = E[::k, ::k].copy()
    for dy in range(k):
        for dx in range(k):
            if dy or dx:
                out |= E[dy::k, dx::k]
    return out


#: Relative depth slack of the thin-triangle occlusion test (float32 depths, curvature between
#: samples).
THIN_DEPTH_SLACK = 1e-3


def _thin_face_pixels(frame: RasterFrame, src, out: np.ndarray) -> None:
    """Mark in out (H, W) bool the output pixels that a thin triangle crosses where it may show
    a key the pixel's K x K samples do not have (compiled: `raster.compiled.thin_face_pixels`).

    A triangle whose screen footprint holds a disk of diameter s sqrt 2 (s = 1/K px, the sample
    spacing: the diagonal of a sample cell) always holds a sample, and where it ends between
    samples it is next to a sampled part, which `_sample_edge_pixels` refines. A triangle with a
    smaller incircle (inradius < s / sqrt 2) can fall between the samples along whole stretches:
    a sliver band, trim or a thin part narrower than the sample spacing, missed in most pixels
    it crosses. Every point of such a triangle is within its inradius (< 1 px) of an edge, so
    the pixels it touches are the pixels its edges pass through: found exactly as the two
    pixels on either side of every crossing of an edge with a pixel row or column line, and the
    pixels of its corners. A pixel is kept unless the triangle is hidden there (its depth where
    the edge enters or leaves the pixel is behind every sample of the 3 x 3 pixels around it) or
    cannot change it (the pixel's samples all carry the one key the face can have). A thin face
    inside a patch of one band and region, every neighbour across its edges seen from the same
    side with that same one band and region (no border, fold or silhouette at its edges), is
    skipped: where it is missed, the samples around it carry its key."""
    scene, cam, hits, sh = frame.scene, frame.camera, frame.hits, frame.shading
    xy, z = src.vertices_px
    reg = sh.region if sh.region is not None else np.zeros(len(scene.faces), np.int32)
    compiled().thin_face_pixels(np.ascontiguousarray(xy, np.float64), np.ascontiguousarray(z, np.float64),
                                scene.faces_int32, cam.near_distance(scene.radius), int(cam.width), int(cam.height),
                                frame.K, sh.lo, sh.hi, sh.back, reg, scene.face_neighbours, sh.bands + 1,
                                hits.depth, frame.keys_ss, cam.is_ortho, THIN_DEPTH_SLACK, out)


# --- measurement ----------------------------------------------------------------------------------

def soft_iou(a: np.ndarray, b: np.ndarray) -> float:
    """IoU of two coverage masks in [0, 1]: sum(min) / sum(max); 1 when both are empty."""
    den = float(np.maximum(a, b).sum())
    return float(np.minimum(a, b).sum()) / den if den > 0 else 1.0


def mask_agreement(scene: Scene, cameras, occluder: Occluder | None = None, ks=(1, 2, 4), reference: int = 4,
                   options: RasterOptions | None = None) -> list[dict]:
    """Band masks of the z-buffer pass at each supersample K (an int, or (K, R) for K with
    edge_supersample R) against the ray-cast reference (`render_raster(reference=True)`) at the
    uniform `reference` K, over `cameras`.

    Returns one dict per entry: {'supersample': K, 'edge_supersample': R, 'ms_per_frame'
    (median, samples + bands + coverage), 'iou' (worst band, background included, over all
    frames), 'iou_pooled' (all bands and frames together), 'iou_thick' (worst band whose area
    is at least 10 x its count of partly covered pixels: sliver bands a few pixels wide cannot
    reach 0.99 against a supersampled reference with uniform K, the reference itself moves by
    that much), 'bands_below_099' (how many (frame, band) pairs are below 0.99), 'bands'}."""

    occluder = occluder or Occluder(scene)
    base = options or RasterOptions()
    refs = [render_raster(scene, c, occluder, replace(base, supersample=reference, edge_supersample=0),
                          reference=True).coverage for c in cameras]
    rows = []
    for entry in ks:
        K, R = (entry, 0) if np.isscalar(entry) else entry
        opts = replace(base, supersample=K, edge_supersample=R)
        times, ious, thick, mins, maxs, below = [], [], [], 0.0, 0.0, 0
        for c, r in zip(cameras, refs):
            t = time.perf_counter()
            cov = render_raster(scene, c, occluder, opts).coverage
            times.append(time.perf_counter() - t)
            for b in range(cov.shape[2]):
                a, q = cov[..., b], r[..., b]
                if not (a.any() or q.any()):
                    continue
                iou = soft_iou(a, q)
                ious.append(iou)
                below += iou < 0.99
                mins += float(np.minimum(a, q).sum())
                maxs += float(np.maximum(a, q).sum())
                if q.sum() >= 10 * ((q > 0) & (q < 1)).sum():
                    thick.append(iou)
        rows.append({"supersample": K, "edge_supersample": R, "ms_per_frame": 1e3 * float(np.median(times)),
                     "iou": min(ious, default=1.0), "iou_pooled": mins / maxs if maxs > 0 else 1.0,
                     "iou_thick": min(thick, default=1.0), "bands_below_099": int(below), "bands": len(ious)})
    return rows
