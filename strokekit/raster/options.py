"""What the raster pass computes and writes (`RasterOptions`) and which compositing passes an EXR
holds (`PassOptions`): the options alone, which the command line declares its flags from without
loading the raster pass."""

from __future__ import annotations

import math
from dataclasses import dataclass

from strokekit.errors import UsageError
from strokekit.options import QUALITY_PRESETS, option

SHADINGS = ("flat", "smooth")
LIGHT_SPACES = ("camera", "world")
FILL_PATTERNS = ("hatch", "dots", "noise")


@dataclass(frozen=True)
class RasterOptions:
    """What the raster pass computes and writes. Only what is asked is computed.

    bands: N; thresholds: explicit n.l thresholds (increasing, in (0, 1)), which override N with
    len(thresholds) + 1; shading 'flat' (face normals) or 'smooth' (corner normals interpolated
    across each face, split at edges sharper than smooth_angle_deg like Blender's auto smooth,
    `Scene.split_normals`: a box's faces stay flat, a sphere shades smoothly; shading has its own
    angle, smaller than the lines' crease angle: a countersunk hole's 45-degree rim split only at
    60 would smear its shade across the flat plate around it); light: direction
    toward the light, in camera space (x right, y up, z toward the viewer) or world space;
    supersample K in {1, 2, 4}: samples per pixel side everywhere; masks: one anti-aliased PNG per
    band; shade: ramp colours (RGBA); objectid, depth: compositing passes; fill: self-similar
    hatching/dots/noise of `fill_pattern` with a base period of `fill_period_px` output pixels;
    gooch: warm/cool ramps; band_polygons: the bands as SVG polygons (see `band_polygons_svg`);
    edge_supersample R (0 = off; R <= K has no effect, the K x K grid is as fine): the pixels that may hold more than one label, material or
    object are resampled on an R x R grid (masks, labels, alpha, colours), so edges get R x R
    quality at a fraction of the cost: pixels whose K x K samples, or the nearest samples of
    their neighbours, disagree, and pixels crossed by a triangle too thin for the K x K grid
    (slivers, trim, thin parts) where it may show another label (see `_mixed_pixels`)."""

    bands: int = option(3, "--bands", "Toon bands: write bands/frame_NNNN.png (labels) and shade/frame_NNNN.png "
                        "with N bands of quantized n.l.", low=1, high=254)
    thresholds: tuple[float, ...] = option(
        (), "--band-thresholds", "Explicit n.l thresholds a,b,.. instead of N equal bands.", text="numbers")
    shading: str = option(
        "smooth", "--shading", "Band normals: per face, or interpolated and split at edges sharper than "
        "--smooth-angle.", choices=SHADINGS, show_default=True, needs="raster")
    smooth_angle_deg: float = option(
        30.0, "--smooth-angle", "Smooth shading: normals split at edges sharper than N degrees (Blender's auto "
        "smooth; the lines' --crease-angle is another).", show_default=True, needs="raster")
    light: tuple[float, float, float] = option(
        (-0.4, 0.6, 0.7), "--light", "Direction toward the light x,y,z.", text="numbers", count=3, show_default=True,
        needs="raster")
    light_space: str = option(
        "camera", "--light-space", "--light is given in camera space (moves with the view) or in world space.",
        choices=LIGHT_SPACES, show_default=True, needs="raster")
    supersample: int = option(
        1, "--supersample", "Samples per pixel side everywhere (default from --quality: 1 draft, 1 default, 4 exact).",
        choices={"1": 1, "2": 2, "4": 4}, needs="raster")
    masks: bool = option(False, "--masks", "Also one anti-aliased mask PNG per band (maskN/frame_NNNN.png).",
                         switch=True)
    shade: bool = option(True, "--no-shade", "No shade/ PNGs (the ramp colours).", switch=True, invert=True,
                         needs="raster")
    objectid: bool = option(False, "--objectid", "Also objectid/frame_NNNN.png (8-bit object ids, 0 background).",
                            switch=True)
    depth: bool = option(
        False, "--depth", "Also depth/frame_NNNN.png (16-bit linear depth; its range in the PNG and the JSON).",
        switch=True)
    fill: bool = option(
        False, "--fill", "Also fill/frame_NNNN.png: hatching that keeps its screen size at any zoom (self-similar "
        "3D texture).", switch=True)
    fill_pattern: str = option("hatch", "--fill-pattern", "Texture of the fill.", choices=FILL_PATTERNS,
                               show_default=True, needs="fill")
    fill_period_px: float = option(16.0, "--fill-period", "Fill texture period in px.", show_default=True,
                                   needs="fill")
    gooch: bool = option(False, "--gooch", "Gooch warm/cool ramp instead of darker shades.", switch=True,
                         needs="raster")
    band_polygons: bool = option(False, "--band-polygons", "Also the bands as vector polygons in an SVG layer under "
                                 "the lines.", switch=True, needs="svg layer")
    pngs: bool = True  # write the PNG passes (off: the raster pass runs for the EXR alone)
    edge_supersample: int = option(
        4, "--edge-supersample", "Resample only the pixels at band, material or object edges R x R (default from "
        "--quality: 0 draft, 4 default, 0 exact).", low=0, high=8, needs="raster")

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
        if not 0 < self.smooth_angle_deg < 180:
            raise UsageError(f"smooth_angle_deg must be in (0, 180) degrees, got {self.smooth_angle_deg:g}",
                             option="smooth_angle_deg")
        if self.light_space not in LIGHT_SPACES:
            raise UsageError(f"light space must be one of {', '.join(LIGHT_SPACES)}, got {self.light_space!r}")
        try:
            light = tuple(float(v) for v in self.light)
        except (TypeError, ValueError):
            light = ()
        finite = len(light) == 3 and all(math.isfinite(v) for v in light)
        # (squares summed as floats: a length beyond float range, (1e300, 0, 0), is inf and refused too)
        length = math.sqrt(sum(v * v for v in light)) if finite else 0.0
        if not (finite and 0 < length < math.inf):
            raise UsageError(f"light must be 3 finite numbers, not all zero, got {self.light!r}"
                             + (" (its length is beyond float range)" if length == math.inf else ""))
        if int(self.supersample) not in (1, 2, 4):
            raise UsageError(f"supersample must be 1, 2 or 4, got {self.supersample}")
        if int(self.edge_supersample) not in (0, 2, 4, 8):
            raise UsageError(f"edge supersample must be 0 (off), 2, 4 or 8, got {self.edge_supersample}")
        if self.fill_pattern not in FILL_PATTERNS:
            raise UsageError(f"fill pattern must be one of {', '.join(FILL_PATTERNS)}, got {self.fill_pattern!r}")
        if not self.fill_period_px > 0:
            raise UsageError(f"fill period must be > 0 px, got {self.fill_period_px}")

    @staticmethod
    def preset(quality: str = "default", **overrides) -> "RasterOptions":
        """Options of a named quality preset (options.QUALITY_PRESETS: supersample K and
        edge_supersample R) with explicit overrides (None values ignored). A K given above the
        preset's R turns the edge resampling off: the K x K grid is then as fine."""
        if quality not in QUALITY_PRESETS:
            raise UsageError(f"unknown quality {quality!r} (known: {', '.join(QUALITY_PRESETS)})")
        given = {k: v for k, v in overrides.items() if v is not None}
        k = int(given.pop("supersample", QUALITY_PRESETS[quality]["supersample"]))
        r = QUALITY_PRESETS[quality]["edge_supersample"]
        r = int(given.pop("edge_supersample", r if r > k else 0))
        return RasterOptions(supersample=k, edge_supersample=r, **given)


#: The passes an EXR can hold, in the order they are written.
PASSES = ("depth", "normal", "shade", "bands", "crypto", "lines")
#: The EXR's lossless compressions that readers built on OpenEXR < 3.3 (Blender 3.4) read: ZIP (the
#: default, as Blender writes) and ZIPS the smallest, RLE the fastest (strokekit's compiled writer, in
#: a fraction of ZIP's time at four to eight times its size), PIZ between (docs/compositing.md).
CODECS = ("zip", "zips", "piz", "rle", "none")
#: --exr-float: half float where Blender writes it (depth and Cryptomatte stay float32), or
#: float32 everywhere.
PRECISIONS = ("half", "full")


@dataclass(frozen=True)
class PassOptions:
    """Which compositing passes to compute (PASSES), the stroke width of the lines pass (px), and
    the EXR's compression (CODECS)."""

    passes: tuple[str, ...] = option(
        PASSES, "--exr-layers", "The EXR's layers, comma-separated: depth, normal, shade, bands, crypto, lines [all].",
        text="names", needs="exr")
    stroke_width_px: float = 1.5  # (the SVG's: --stroke-width)
    codec: str = option(
        "zip", "--exr-codec", "The EXR's lossless compression: zip (as Blender writes) and zips are the smallest, "
        "rle the fastest to write (four to eight times zip's size), piz between.", choices=CODECS,
        show_default=True, needs="exr")
    precision: str = option(
        "half", "--exr-float", "The EXR's float types: half (as Blender writes its passes: colour, normals, band "
        "labels and lines in half float, depth and Cryptomatte in float32) or full (every channel float32).",
        choices=PRECISIONS, show_default=True, needs="exr")

    def __post_init__(self):
        unknown = [p for p in self.passes if p not in PASSES]
        if unknown or not self.passes:
            raise UsageError(f"unknown or no EXR layer(s) {', '.join(unknown) or '(none)'} "
                             f"(known: {', '.join(PASSES)})", option="passes")
        if self.codec not in CODECS:
            raise UsageError(f"codec {self.codec!r} is not one of {', '.join(CODECS)} (the lossless ones: "
                             "Cryptomatte ids and depth must come back exact)", option="codec")
        if self.precision not in PRECISIONS:
            raise UsageError(f"EXR float type {self.precision!r} is not one of {', '.join(PRECISIONS)}",
                             option="precision")
        object.__setattr__(self, "passes", tuple(p for p in PASSES if p in self.passes))
