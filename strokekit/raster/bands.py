"""Toon bands (seed 002, seed 001 section 6, seed 000 section 2.1.1): quantized Lambert shading
from the raster pass, per-material 1D ramps, anti-aliased band masks and band polygons.

Labels: 0 is background, 1..N are bands from darkest to brightest. With N bands and no explicit
thresholds the band of a sample is floor(max(0, n.l) N) (seed 002: floor(diffuse * levels)),
with n.l = 1 put in the top band. Lighting is two-sided: the normal is turned to face the viewer,
so open meshes and inconsistent windings (common in glTF) are lit from the side we see.

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
from strokekit.errors import UsageError
from strokekit.model import BandRegion
from strokekit.raster.fill import fill_ink
from strokekit.raster.rays import RasterHits, box_filter, cast_pixels, cast_samples  # noqa: F401 (the shortcut, re-exported)
from strokekit.scene.load import Scene
from strokekit.scene.occluder import Occluder
from strokekit.scene.tables import scene_cache, split_normals

SHADINGS = ("flat", "smooth")
LIGHT_SPACES = ("camera", "world")
FILL_PATTERNS = ("hatch", "dots", "noise")
#: The ramp's darkest shade, as a fraction of the base colour (seed 000 Fig 2.7: shades are the
#: base colour darkened).
RAMP_DARKEST = 0.45


@dataclass(frozen=True)
class RasterOptions:
    """What the raster pass computes and writes. Only what is asked is computed.

    bands: N; thresholds: explicit n.l thresholds (increasing, in (0, 1)), which override N with
    len(thresholds) + 1; shading 'flat' (face normals) or 'smooth' (corner normals interpolated
    across each face, split at creases sharper than `crease_angle_deg` degrees like Blender's
    auto smooth, `contours.split_normals`: a box's faces stay flat, a sphere shades smoothly);
    light: direction toward the light, in camera space (x right, y up, z toward the viewer) or
    world space; supersample K in {1, 2, 4}; masks: one anti-aliased PNG per band; shade: ramp
    colours (RGBA); objectid, depth: compositing passes; fill: seed 003 hatching/dots/noise of
    `fill_pattern` with a base period of `fill_period_px` output pixels; gooch: warm/cool ramps;
    band_polygons: the bands as SVG polygons (see `band_polygons_svg`); edge_supersample R > K
    (0 = off): output pixels that may hold a band edge are resampled on an R x R grid for the
    coverages (masks, labels, alpha), so band edges get R x R quality for a fraction of the
    rays: pixels whose K x K samples, or the nearest samples of their neighbours, disagree, and
    pixels crossed by a triangle too thin for the K x K grid (slivers, trim, thin parts) where it
    may show another band (see `_edge_coverage`)."""

    bands: int = 3
    thresholds: tuple[float, ...] = ()
    shading: str = "smooth"
    light: tuple[float, float, float] = (-0.4, 0.6, 0.7)
    light_space: str = "camera"
    supersample: int = 2
    masks: bool = False
    shade: bool = True
    objectid: bool = False
    depth: bool = False
    fill: bool = False
    fill_pattern: str = "hatch"
    fill_period_px: float = 16.0
    gooch: bool = False
    band_polygons: bool = False
    pngs: bool = True  # write the PNG passes (off: the raster pass runs for the EXR alone)
    edge_supersample: int = 0
    crease_angle_deg: float = 60.0

    def __post_init__(self):
        th = tuple(float(t) for t in self.thresholds)
        object.__setattr__(self, "thresholds", th)
        if th:
            if not all(0.0 < t < 1.0 for t in th) or any(b <= a for a, b in zip(th, th[1:])):
                raise UsageError(f"band thresholds must increase strictly inside (0, 1), got {list(th)}")
            object.__setattr__(self, "bands", len(th) + 1)
        if not 1 <= int(self.bands) <= 254:
            raise UsageError(f"bands must be in 1..254, got {self.bands}")
        if self.shading not in SHADINGS:
            raise UsageError(f"shading must be one of {', '.join(SHADINGS)}, got {self.shading!r}")
        if self.light_space not in LIGHT_SPACES:
            raise UsageError(f"light space must be one of {', '.join(LIGHT_SPACES)}, got {self.light_space!r}")
        light = np.asarray(self.light, float)
        with np.errstate(over="ignore"):  # a length beyond float range (1e300, 0, 0) is refused too
            length = np.linalg.norm(light) if light.shape == (3,) else 0.0
        if light.shape != (3,) or not np.all(np.isfinite(light)) or not (0 < length < np.inf):
            raise UsageError(f"light must be 3 finite numbers, not all zero, got {self.light!r}"
                             + (" (its length is beyond float range)" if length == np.inf else ""))
        if int(self.supersample) not in (1, 2, 4):
            raise UsageError(f"supersample must be 1, 2 or 4, got {self.supersample}")
        if int(self.edge_supersample) and (int(self.edge_supersample) not in (2, 4, 8)
                                           or int(self.edge_supersample) <= int(self.supersample)):
            raise UsageError(f"edge supersample must be 0 (off) or 2, 4, 8 above the supersample "
                             f"{self.supersample}, got {self.edge_supersample}")
        if not 0 < self.crease_angle_deg < 180:
            raise UsageError(f"crease angle must be in (0, 180) degrees, got {self.crease_angle_deg}")
        if self.fill_pattern not in FILL_PATTERNS:
            raise UsageError(f"fill pattern must be one of {', '.join(FILL_PATTERNS)}, got {self.fill_pattern!r}")
        if not self.fill_period_px > 0:
            raise UsageError(f"fill period must be > 0 px, got {self.fill_period_px}")


# --- shading --------------------------------------------------------------------------------------

def light_direction(camera: Camera, options: RasterOptions) -> np.ndarray:
    """(3,) unit world vector toward the light."""
    l = np.asarray(options.light, float)
    if options.light_space == "camera":
        right, up, fwd = camera.basis
        l = l[0] * right + l[1] * up - l[2] * fwd
    return l / np.linalg.norm(l)


def _facing_sign(scene: Scene, camera: Camera, fi: np.ndarray, ax: np.ndarray, ay: np.ndarray) -> np.ndarray:
    """(M,) +1 where the hit face's winding normal faces the viewer, -1 where we see its back;
    ax, ay (M,) the samples' camera-plane offsets (see raster.cast_samples)."""
    right, up, fwd = camera.basis
    nf = scene.face_normals
    # n.d for d = fwd + x right + y up (perspective) or the rays' direction (parallel: fwd but for
    # the oblique projections), from per-face dot products.
    s = (nf @ (camera.ray_dir if camera.is_ortho else fwd))[fi]
    if not camera.is_ortho:
        s = s + ax * (nf @ right)[fi] + ay * (nf @ up)[fi]
    return np.where(s > 0, -1.0, 1.0)


def corner_shading(scene: Scene, crease_angle_deg: float = 60.0, vnormals: np.ndarray | None = None
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(corner (F, 3) node of each face corner, normals (N, 3) unit node normals, gram (F, 3)
    n_a.n_b, n_b.n_c, n_c.n_a of each face's corner normals) for smooth shading.

    The nodes and normals are `scene.tables.split_normals(scene, crease_angle_deg)`, the ones smooth
    contours use (angle-weighted, Blender's auto smooth rule): corners share a normal only across
    edges flatter than the crease angle, so a face next to a sharp edge keeps its own normal
    there. Cached per scene and angle in `contours.scene_cache`. With `vnormals` (V, 3) those
    vertex normals are interpolated instead, unsplit (not cached)."""
    if vnormals is not None:
        return _with_gram(scene.faces, np.asarray(vnormals, float))

    key = ("raster_corner_shading", float(crease_angle_deg))
    c = scene_cache(scene)
    if key not in c:
        sn = split_normals(scene, crease_angle_deg)
        c[key] = _with_gram(sn.corner, sn.normals)
    return c[key]


def _with_gram(corner: np.ndarray, normals: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    N = normals[corner]  # (F, 3, 3)
    gram = np.stack([np.einsum("ij,ij->i", N[:, k], N[:, (k + 1) % 3]) for k in range(3)], axis=1)
    return corner, normals, gram


def sample_n_dot_l(scene: Scene, camera: Camera, fi: np.ndarray, uv: np.ndarray, ax: np.ndarray, ay: np.ndarray,
                   light: np.ndarray, shading: str = "flat", vnormals: np.ndarray | None = None,
                   crease_angle_deg: float = 60.0) -> np.ndarray:
    """(M,) two-sided n.l of M hit samples: faces fi (M,), barycentrics uv (M, 2), camera-plane
    offsets ax, ay (M,).

    flat: face normals; smooth: barycentric interpolation of the face's corner normals split at
    creases sharper than `crease_angle_deg` (`corner_shading`; `vnormals` (V, 3) to interpolate
    given vertex normals instead), renormalized. The smooth case works on per-corner scalars
    (node n.l and the cached pairwise normal dot products), so no (M, 3) normal array is built."""
    sign = _facing_sign(scene, camera, fi, ax, ay)
    if shading == "flat":
        d = (scene.face_normals @ light)[fi]
    else:
        corner, normals, gram = corner_shading(scene, crease_angle_deg, vnormals)
        nl = normals @ light
        la, lb, lc = (nl[corner[:, k]][fi] for k in range(3))
        gab, gbc, gca = (gram[:, k][fi] for k in range(3))
        uv = np.asarray(uv, np.float64)
        wb, wc = uv[:, 0], uv[:, 1]
        wa = 1.0 - wb - wc
        # |wa na + wb nb + wc nc|^2 from the pairwise dot products.
        norm2 = wa * wa + wb * wb + wc * wc + 2 * (wa * wb * gab + wb * wc * gbc + wc * wa * gca)
        d = (wa * la + wb * lb + wc * lc) / np.sqrt(np.maximum(norm2, 1e-24))
    # The geometric side decides two-sidedness, also for smooth normals.
    return sign * d


def hit_n_dot_l(scene: Scene, hits: RasterHits, light: np.ndarray, shading: str = "flat",
                vnormals: np.ndarray | None = None, crease_angle_deg: float = 60.0) -> tuple[np.ndarray, np.ndarray]:
    """(sel, ndl): flat indices of the hit samples (M,) and their two-sided n.l (M,) float64."""
    face = hits.face.ravel()
    sel = np.flatnonzero(face >= 0)
    rows, cols = np.divmod(sel, hits.shape[1])
    d = sample_n_dot_l(scene, hits.camera, face[sel], hits.bary.reshape(-1, 2)[sel], hits.ray_dir_x[cols],
                       hits.ray_dir_y[rows], light, shading, vnormals, crease_angle_deg)
    return sel, d


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


# --- supersampled labels -> output images ---------------------------------------------------------

def _blocks(img: np.ndarray, k: int) -> np.ndarray:
    """(H*k, W*k) -> (H, W, k*k) samples of each output pixel."""
    HK, WK = img.shape
    return img.reshape(HK // k, k, WK // k, k).transpose(0, 2, 1, 3).reshape(HK // k, WK // k, k * k)


def label_coverage(labels_ss: np.ndarray, k: int, n_labels: int) -> np.ndarray:
    """(H, W, n_labels) float32 fraction of each output pixel's samples carrying each label
    (box filter of the supersampled labels)."""
    H, W = labels_ss.shape[0] // k, labels_ss.shape[1] // k
    counts = np.zeros((n_labels, H, W), np.uint8 if k * k < 256 else np.uint16)
    # Sum the k*k strided sub-images into one contiguous plane per label.
    for dy in range(k):
        for dx in range(k):
            sub = labels_ss[dy::k, dx::k]
            for c in range(n_labels):
                counts[c] += sub == c
    return np.moveaxis(counts, 0, -1).astype(np.float32) * np.float32(1.0 / (k * k))


def representative(img: np.ndarray, k: int) -> np.ndarray:
    """The sample nearest each output pixel's centre (for ids and depth, which must not be
    averaged): index (k//2, k//2) of each k x k block."""
    return img[k // 2::k, k // 2::k] if k > 1 else img


@dataclass(frozen=True, eq=False)
class RasterFrame:
    """One frame's raster products. labels_ss (HK, WK) uint8 band labels at the supersampled
    resolution; everything at output resolution is derived on demand."""

    scene: Scene
    camera: Camera
    options: RasterOptions
    hits: RasterHits
    labels_ss: np.ndarray
    light: np.ndarray
    # (pixel flat indices (P,), coverages (P, N+1)) from edge resampling, or None.
    edge_coverage: tuple | None = None

    @property
    def n_bands(self) -> int:
        return int(self.options.bands)

    @cached_property
    def sample_coverage(self) -> np.ndarray:
        """(H, W, N+1) float32: box filter of the K x K labels alone."""
        return label_coverage(self.labels_ss, self.hits.supersample, self.n_bands + 1)

    @cached_property
    def coverage(self) -> np.ndarray:
        """(H, W, N+1) float32: coverage of background (0) and of each band (edge pixels from the
        R x R resampling when options.edge_supersample is on)."""
        if self.edge_coverage is None:
            return self.sample_coverage
        cov = self.sample_coverage.copy()
        idx, c = self.edge_coverage
        cov.reshape(-1, cov.shape[2])[idx] = c
        return cov

    @cached_property
    def labels(self) -> np.ndarray:
        """(H, W) uint8: the label covering most of each output pixel (ties: the lower label)."""
        if self.hits.supersample == 1 and self.edge_coverage is None:
            return self.labels_ss
        return np.argmax(self.coverage, axis=2).astype(np.uint8)

    def mask(self, band: int) -> np.ndarray:
        """(H, W) uint8 anti-aliased mask of band 1..N (0 for background), 255 = fully covered."""
        return np.round(self.coverage[..., band] * 255.0).astype(np.uint8)

    @cached_property
    def material_ss(self) -> np.ndarray:
        """(HK, WK) int32 material index per sample, -1 on background."""
        f = self.hits.face
        return np.where(f >= 0, self.scene.face_material[np.maximum(f, 0)], -1).astype(np.int32)

    def shade_image(self) -> np.ndarray:
        """(H, W, 4) uint8 RGBA: the ramp colour of each sample's material and band, box-filtered
        with alpha = covered fraction (straight, not premultiplied, alpha in the PNG)."""
        ramps = band_ramps(self.scene, self.n_bands, self.options.gooch)
        table = np.concatenate([np.zeros((1, 3)), ramps.reshape(-1, 3)])  # row 0: background
        idx = np.where(self.labels_ss > 0, 1 + np.maximum(self.material_ss, 0) * self.n_bands
                       + self.labels_ss.astype(np.int32) - 1, 0)
        rgb = box_filter(table[idx].astype(np.float32), self.hits.supersample)
        # Colour from the K x K samples, alpha from the (possibly edge-resampled) coverage.
        alpha_k = 1.0 - self.sample_coverage[..., 0]
        with np.errstate(invalid="ignore", divide="ignore"):
            straight = np.where(alpha_k[..., None] > 0, rgb / alpha_k[..., None], 0.0)
        alpha = 1.0 - self.coverage[..., 0]
        if self.edge_coverage is not None:
            # A pixel no K sample hit but edge samples did: no sample tells its material, so it
            # takes the first material's top band.
            lost = (alpha_k == 0) & (alpha > 0)
            straight[lost] = ramps[0, -1]
        # Filtered in linear light, written sRGB-encoded (the scene's colours are linear: a base
        # colour 0.4 was written as 102 instead of 170, darker than any viewer shows it).
        out = np.concatenate([srgb_encode(straight), alpha[..., None]], axis=2)
        return np.round(np.clip(out, 0, 1) * 255.0).astype(np.uint8)

    def objectid_image(self) -> np.ndarray:
        """(H, W) uint8 (uint16 past 254 objects): 0 background, object index + 1."""
        f = representative(self.hits.face, self.hits.supersample)
        obj = np.where(f >= 0, self.scene.face_object[np.maximum(f, 0)].astype(np.int64) + 1, 0)
        return obj.astype(np.uint8 if len(self.scene.objects) < 255 else np.uint16)

    def depth_range(self) -> tuple[float, float]:
        """(z_near, z_far) world units mapped to 0 and 65534 in the depth PNG: the scene's bounding
        sphere along the view axis, so the mapping only moves with the camera."""
        _, _, fwd = self.camera.basis
        zc = float((self.scene.center - np.asarray(self.camera.eye)) @ fwd)
        zn = max(zc - self.scene.radius, self.camera.near_distance(self.scene.radius))
        return zn, max(zc + self.scene.radius, zn * (1 + 1e-9) + 1e-300)

    def depth_image(self) -> np.ndarray:
        """(H, W) uint16 linear view depth: 0 at z_near, 65534 at z_far (see depth_range), 65535
        background."""
        z = representative(self.hits.depth, self.hits.supersample)
        zn, zf = self.depth_range()
        q = np.clip(np.round((z - zn) / (zf - zn) * 65534.0), 0, 65534)
        return np.where(np.isfinite(z), q, 65535).astype(np.uint16)

    def fill_image(self) -> np.ndarray:
        """(H, W) uint8 grey: seed 003 binary marks per band (0 ink, 255 paper), anti-aliased."""

        ink = fill_ink(self.scene, self.hits, self.labels_ss, self.n_bands, self.options.fill_pattern,
                       self.options.fill_period_px)
        return np.round(255.0 * (1.0 - box_filter(ink.astype(np.float32), self.hits.supersample))).astype(np.uint8)

    def images(self) -> dict[str, np.ndarray]:
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
        k = self.hits.supersample
        mat = self.material_ss if k == 1 else _blocks(self.material_ss, k).max(axis=2)
        mat = np.maximum(mat, 0)
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

def render_raster(scene: Scene, camera: Camera, occluder: Occluder, options: RasterOptions,
                  vnormals: np.ndarray | None = None) -> RasterFrame:
    """Cast the rays and label the bands of one frame. Call only when a raster output is asked
    for. Smooth shading uses the normals split at options.crease_angle_deg (cached per scene);
    `vnormals` (V, 3) replaces them by given vertex normals, interpolated without splitting."""
    hits = cast_pixels(camera, occluder, options.supersample)
    light = light_direction(camera, options)
    sel, ndl = hit_n_dot_l(scene, hits, light, options.shading, vnormals, options.crease_angle_deg)
    labels_ss = np.zeros(hits.face.size, np.uint8)
    labels_ss[sel] = quantize_bands(ndl, options.bands, options.thresholds)
    labels_ss = labels_ss.reshape(hits.shape)
    frame = RasterFrame(scene=scene, camera=camera, options=options, hits=hits, labels_ss=labels_ss, light=light)
    R = int(options.edge_supersample)
    if R > hits.supersample:
        frame = RasterFrame(scene=scene, camera=camera, options=options, hits=hits, labels_ss=labels_ss,
                            light=light, edge_coverage=_edge_coverage(frame, occluder, R, vnormals))
    return frame


def _edge_coverage(frame: RasterFrame, occluder: Occluder, R: int, vnormals: np.ndarray | None):
    """(pixel indices (P,), coverages (P, N+1)) of the output pixels that may hold more than one
    label, from R x R samples through each such pixel (sample centres ((a + 0.5) / R) inside the
    pixel, like a uniform R-times supersampling there). Refined: the pixels whose K x K samples
    disagree or differ from a next sample of a neighbouring pixel (`_sample_edge_pixels`), and the
    pixels a triangle too thin for the K x K grid crosses where it may show another label than
    the samples there (`_thin_face_pixels`)."""
    cam, o = frame.camera, frame.options
    n = frame.n_bands + 1
    edge = _sample_edge_pixels(frame.labels_ss, frame.hits.supersample)
    edge.ravel()[_thin_face_pixels(frame, vnormals)] = True
    mixed = np.flatnonzero(edge)
    if len(mixed) == 0:
        return None
    W, H, f = int(cam.width), int(cam.height), cam.focal_px
    py, px = np.divmod(mixed, W)
    sub = (np.arange(R) + 0.5) / R
    # (P, R*R) sample positions in output pixels, row-major inside each pixel.
    x = (px[:, None] + np.tile(sub, R)[None, :]).ravel()
    y = (py[:, None] + np.repeat(sub, R)[None, :]).ravel()
    ax, ay = (x - W / 2.0) / f, (H / 2.0 - y) / f

    h = cast_samples(cam, occluder, ax, ay)
    hit = np.flatnonzero(h["face"] >= 0)
    lab = np.zeros(len(x), np.uint8)
    ndl = sample_n_dot_l(frame.scene, cam, h["face"][hit], h["bary"][hit], ax[hit], ay[hit], frame.light,
                         o.shading, vnormals, o.crease_angle_deg)
    lab[hit] = quantize_bands(ndl, o.bands, o.thresholds)
    counts = np.bincount(np.repeat(np.arange(len(mixed)), R * R) * n + lab, minlength=len(mixed) * n)
    return mixed, (counts.reshape(len(mixed), n) / (R * R)).astype(np.float32)


def _sample_edge_pixels(labels_ss: np.ndarray, k: int) -> np.ndarray:
    """(H, W) bool: output pixels with a sample whose label differs from one of its 8 neighbour
    samples, i.e. whose K x K samples plus the ring of nearest samples of the neighbouring pixels
    do not all agree. A label edge between two samples a sample spacing apart may run through
    either of their pixels, so both are refined (a pixel-majority rule misses an edge that only
    grazes a pixel, and refines pixels whose own samples are a full spacing from any edge)."""
    L = labels_ss
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


def _face_band_range(frame: RasterFrame, vnormals: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(lo, hi, back): (F,) uint8 the lowest and highest band label a sample anywhere on each
    face could get (a conservative interval; bands are monotone in n.l), and (F,) bool where we
    see the face's back side.

    flat: the face's n.l. smooth: the interpolated numerator (wa la + wb lb + wc lc) is linear,
    so its extremes are corner values, and the renormalization divides it by |n| in
    [sqrt(min n_i.n_j), 1] (|sum w_i n_i|^2 = sum w_i w_j n_i.n_j >= min n_i.n_j). Two-sided
    lighting flips the sign on the back side, which is the same over a whole face (its corners
    lie in its plane, so n.(P - eye) is one number; see _facing_sign)."""
    scene, cam, o = frame.scene, frame.camera, frame.options
    nf = scene.face_normals
    if cam.is_ortho:
        back = nf @ cam.ray_dir > 0  # (fwd but for the oblique projections)
    else:
        back = scene.face_offsets - nf @ np.asarray(cam.eye, float) > 0
    if o.shading == "flat":
        lo = hi = nf @ frame.light
    else:
        corner, normals, _ = corner_shading(scene, o.crease_angle_deg, vnormals)
        nl = normals @ frame.light
        la, lb, lc = (np.take(nl, corner[:, k]) for k in range(3))
        lmin, lmax = np.minimum(np.minimum(la, lb), lc), np.maximum(np.maximum(la, lb), lc)
        root = _min_norm(scene, o.crease_angle_deg, vnormals)
        lo = np.where(lmin >= 0, lmin, lmin / root)
        hi = np.where(lmax >= 0, lmax / root, lmax)
    LO, HI = np.where(back, -hi, lo), np.where(back, -lo, hi)
    return quantize_bands(LO, o.bands, o.thresholds), quantize_bands(HI, o.bands, o.thresholds), back


def _min_norm(scene: Scene, crease_angle_deg: float, vnormals: np.ndarray | None) -> np.ndarray:
    """(F,) a lower bound of |w_a n_a + w_b n_b + w_c n_c| over each face (weights >= 0 summing
    to 1) for smooth shading's corner normals: sqrt of the smallest pairwise dot product,
    floored at 1e-3 (see _face_band_range). Cached per scene and angle like corner_shading."""

    key = ("raster_min_norm", float(crease_angle_deg))
    c = scene_cache(scene) if vnormals is None else {}
    if key not in c:
        gram = corner_shading(scene, crease_angle_deg, vnormals)[2]
        c[key] = np.sqrt(np.clip(np.minimum(np.minimum(gram[:, 0], gram[:, 1]), gram[:, 2]), 1e-6, 1.0))
    return c[key]


def _face_neighbours(scene: Scene) -> np.ndarray:
    """(F, 3) int64 the faces across each face's manifold edges, -1 for a border or non-manifold
    edge (order not by edge). Cached per scene."""

    c = scene_cache(scene)
    if "raster_face_neighbours" not in c:
        ef = scene.edge_faces[scene.edge_face_count == 2]
        src, dst = np.concatenate([ef[:, 0], ef[:, 1]]), np.concatenate([ef[:, 1], ef[:, 0]])
        order = np.argsort(src, kind="stable")
        src, dst = src[order], dst[order]
        first = np.searchsorted(src, src)
        rank = np.arange(len(src)) - first
        nb = np.full((len(scene.faces), 3), -1, np.int64)
        keep = rank < 3
        nb[src[keep], rank[keep]] = dst[keep]
        c["raster_face_neighbours"] = nb
    return c["raster_face_neighbours"]


#: Relative depth slack of the thin-triangle occlusion test (float32 depths, curvature between
#: samples).
THIN_DEPTH_SLACK = 1e-3


def _thin_face_pixels(frame: RasterFrame, vnormals: np.ndarray | None) -> np.ndarray:
    """Flat indices (with repeats) of the output pixels that a thin triangle crosses where it
    may show a label the pixel's K x K samples do not have.

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
    cannot change it (the pixel's samples all carry the one label the face can have,
    `_face_band_range`)."""
    scene, cam, hits = frame.scene, frame.camera, frame.hits
    K = hits.supersample
    W, H = int(cam.width), int(cam.height)
    xy, z = cam.project(scene.vertices)
    f = scene.faces
    near = cam.near_distance(scene.radius)  # (orthographic too: the lines are clipped there)
    (xa, xb, xc), (ya, yb, yc), (za, zb, zc) = (tuple(v[f[:, k]] for k in range(3)) for v in (xy[:, 0], xy[:, 1], z))
    ok = (np.minimum(np.minimum(za, zb), zc) > near)
    ok &= (np.maximum(np.maximum(xa, xb), xc) >= 0) & (np.minimum(np.minimum(xa, xb), xc) < W)
    ok &= (np.maximum(np.maximum(ya, yb), yc) >= 0) & (np.minimum(np.minimum(ya, yb), yc) < H)
    # inradius = 2 area / perimeter < s / sqrt 2
    twice_area = np.abs((xb - xa) * (yc - ya) - (yb - ya) * (xc - xa))
    perimeter = np.hypot(xb - xa, yb - ya) + np.hypot(xc - xb, yc - yb) + np.hypot(xa - xc, ya - yc)
    ok &= twice_area < perimeter * (np.sqrt(0.5) / K)
    lo, hi, back = _face_band_range(frame, vnormals)
    # A thin face inside a patch of one band, every neighbour across its edges seen from the
    # same side with that same one band (no border, fold or silhouette at its edges), cannot
    # change a label where it is missed: the samples around it carry its band.
    nb = _face_neighbours(scene)
    cand = np.flatnonzero(ok)
    nbc = nb[cand]
    nbs = np.maximum(nbc, 0)
    l0 = lo[cand][:, None]
    plain = (hi[cand] == lo[cand]) & ((nbc >= 0) & (lo[nbs] == l0) & (hi[nbs] == l0)
                                      & (back[nbs] == back[cand][:, None])).all(axis=1)
    cand = cand[~plain]
    if len(cand) == 0:
        return np.zeros(0, np.int64)
    lo, hi = lo[cand], hi[cand]
    # The 3 edges of each candidate, corner k -> k + 1: start a, direction d, end depths.
    c3 = np.stack([np.take(v, cand) for v in (xa, xb, xc, ya, yb, yc, za, zb, zc)]).reshape(3, 3, -1)
    a = c3[:2].transpose(2, 1, 0).reshape(-1, 2)
    d = np.roll(c3[:2], -1, axis=1).transpose(2, 1, 0).reshape(-1, 2) - a
    z0 = c3[2].T.reshape(-1)
    z1 = np.roll(c3[2], -1, axis=0).T.reshape(-1)
    # Cells an edge passes through: the pixel of its start corner, and the pixels on both sides
    # of each crossing with a pixel column line x = g (c = 0) or row line y = g (c = 1).
    edge_of, pts, ts = [np.arange(len(a))], [a], [np.zeros(len(a))]
    for c in range(2):
        # Only the lines inside the image matter.
        lo_c, hi_c = np.minimum(a[:, c], a[:, c] + d[:, c]), np.maximum(a[:, c], a[:, c] + d[:, c])
        g0 = np.clip(np.floor(lo_c), -1, (W, H)[c]) + 1
        g1 = np.clip(np.floor(hi_c), -1, (W, H)[c])
        cnt = np.maximum(g1 - g0 + 1, 0).astype(np.int64)
        own = np.repeat(np.arange(len(a)), cnt)
        g = np.repeat(g0 - (np.cumsum(cnt) - cnt), cnt) + np.arange(len(own))
        t = np.clip((g - a[own, c]) / d[own, c], 0.0, 1.0)  # cnt > 0 only where d != 0
        p = a[own] + t[:, None] * d[own]
        p[:, c] = g
        q = p.copy()
        q[:, c] -= 0.5  # the pixel before the line; p itself names the one after
        p[:, c] += 0.5
        edge_of += [own, own]
        pts += [p, q]
        ts += [t, t]
    edge_of = np.concatenate(edge_of)
    t = np.concatenate(ts)
    pts = np.concatenate(pts)
    px, py = np.floor(pts[:, 0]).astype(np.int64), np.floor(pts[:, 1]).astype(np.int64)
    inside = (px >= 0) & (px < W) & (py >= 0) & (py < H)
    pix = (py * W + px)[inside]
    e, t = edge_of[inside], t[inside]
    # View depth along the edge: 1/z is linear in the screen parameter (perspective), z is (ortho).
    if cam.is_ortho:
        zt = z0[e] + t * (z1[e] - z0[e])
    else:
        zt = 1.0 / ((1 - t) / z0[e] + t / z1[e])
    # Per pixel touched: the deepest sample of the 3 x 3 pixels around it (inf where one is
    # background: nothing hides there) and the smallest and largest label of its own samples.
    mark = np.zeros(W * H, bool)
    mark[pix] = True
    upix = np.flatnonzero(mark)
    slot = np.empty(W * H, np.int64)
    slot[upix] = np.arange(len(upix))
    inv = slot[pix]
    uy, ux = np.divmod(upix, W)
    rr = np.clip(uy[:, None] * K + np.arange(-K, 2 * K), 0, H * K - 1)
    cc = np.clip(ux[:, None] * K + np.arange(-K, 2 * K), 0, W * K - 1)
    zmax = hits.depth[rr[:, :, None], cc[:, None, :]].reshape(len(upix), -1).max(axis=1)
    labs = frame.labels_ss[rr[:, K:2 * K, None], cc[:, None, K:2 * K]].reshape(len(upix), -1)
    lmin, lmax = labs.min(axis=1), labs.max(axis=1)
    fo = e // 3
    seen = zt <= np.take(zmax, inv).astype(np.float64) * (1 + THIN_DEPTH_SLACK)
    lm = np.take(lmin, inv)
    same = (lm == np.take(lmax, inv)) & (np.take(lo, fo) == lm) & (np.take(hi, fo) == lm)
    return pix[seen & ~same]


# --- measurement ----------------------------------------------------------------------------------

def soft_iou(a: np.ndarray, b: np.ndarray) -> float:
    """IoU of two coverage masks in [0, 1]: sum(min) / sum(max); 1 when both are empty."""
    den = float(np.maximum(a, b).sum())
    return float(np.minimum(a, b).sum()) / den if den > 0 else 1.0


def mask_agreement(scene: Scene, cameras, occluder: Occluder | None = None, ks=(1, 2, 4), reference: int = 4,
                   options: RasterOptions | None = None) -> list[dict]:
    """Band masks at each supersample K (an int, or (K, R) for K with edge_supersample R)
    against the uniform `reference` K, over `cameras`.

    Returns one dict per entry: {'supersample': K, 'edge_supersample': R, 'ms_per_frame'
    (median, rays + bands + coverage), 'iou' (worst band, background included, over all
    frames), 'iou_pooled' (all bands and frames together), 'iou_thick' (worst band whose area
    is at least 10 x its count of partly covered pixels: sliver bands a few pixels wide cannot
    reach 0.99 against a supersampled reference with uniform K, the reference itself moves by
    that much), 'bands_below_099' (how many (frame, band) pairs are below 0.99), 'bands'}."""

    occluder = occluder or Occluder(scene)
    base = options or RasterOptions()
    refs = [render_raster(scene, c, occluder, replace(base, supersample=reference, edge_supersample=0)).coverage
            for c in cameras]
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
