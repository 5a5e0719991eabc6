"""Options of `strokekit render` for the optional stages (tracking, glTF ribbons, raster masks),
kept apart so render.py stays a list of the core options. Each `*_options_from` turns the parsed
values into the library's options dataclass, or None when that stage is off."""

from __future__ import annotations

import math

import click

from strokekit.errors import UsageError
from strokekit.model import MAX_OCCLUSION
from strokekit.options import QUALITY_PRESETS
from strokekit.paths.options import PathOptions
from strokekit.raster.bands import RasterOptions
from strokekit.raster.passes import CODECS, PASSES, PassOptions
from strokekit.ribbons.brushes import get_brush
from strokekit.tracking.options import TrackingOptions
from strokekit.writers.gltf import GltfOptions

from ..common import FINITE, split_list

_GLTF = [
    click.option("--gltf/--no-gltf", default=False, show_default=True, help="Write textured ribbons as frame_NNNN.glb."),
    click.option("--gltf-sequence", is_flag=True, help="One sequence.glb for all frames (a node per frame) instead."),
    click.option("--ribbon-width", type=FINITE, default=3.0, show_default=True, help="Ribbon width in px."),
    click.option("--taper", type=FINITE, default=1.0, show_default=True, help="Head/tail taper (0: none)."),
    click.option("--brush", default="ink", show_default=True, help="plain, ink, dry, or a PNG of your own stroke."),
    click.option("--alpha-mode", type=click.Choice(["blend", "mask"]), default="blend", show_default=True,
                 help="glTF alpha of the ribbons: blended, or cut out (mask)."),
    click.option("--ribbon-space", type=click.Choice(["world", "image"]), default="world", show_default=True,
                 help="Ribbons in the scene facing the camera, or flat in pixel units for 2D compositing."),
]


_TRACKING = [
    click.option("--strokes", "strokes_mode", type=click.Choice(["brush", "lines"]), default=None,
                 help="What the SVG, the JSON's strokes and the ribbons draw: brush paths (smooth strokes that "
                      "persist from frame to frame, each covering nearby line pieces; the JSON keeps the exact lines "
                      "beside them) or the exact lines [brush for a sequence with coherence on, unless --coherence "
                      "is given; lines for one frame or --no-coherence]."),
    click.option("--path-merge", type=FINITE, default=None,
                 help="With brush paths: a path shorter than N px (two frames running) merges into the path it "
                      "touches [5; 0: never, the highest id persistence, but paths crumble over long sequences]."),
    click.option("--coherence", "coherence_method", type=click.Choice(["kalnins", "seed", "none"]), default="kalnins",
                 show_default=True, help="Frame-to-frame tracking of the lines (--strokes lines): kalnins (samples carry "
                      "ids and u to the next frame), seed (simple baseline: limited growth, short strokes not carried), "
                      "or none."),
    click.option("--no-coherence", is_flag=True, help="Same as --coherence none: ids per frame, u = arc length / P "
                      "(brush paths: made afresh every frame)."),
    click.option("--max-growth", type=FINITE, default=20.0, show_default=True,
                 help="With --coherence seed: a stroke grows at most N px per frame."),
    click.option("--min-carry", type=FINITE, default=10.0, show_default=True,
                 help="With --coherence seed: strokes shorter than N px are not carried to the next frame."),
]


_RASTER = [
    click.option("--bands", type=click.IntRange(min=1, max=254), default=None,
                 help="Toon bands: write bands/frame_NNNN.png (labels) and shade/frame_NNNN.png with N bands of quantized n.l."),
    click.option("--band-thresholds", default=None, help="Explicit n.l thresholds a,b,.. instead of N equal bands."),
    click.option("--shading", type=click.Choice(["flat", "smooth"]), default="smooth", show_default=True,
                 help="Band normals: per face, or interpolated and split at edges sharper than --crease-angle."),
    click.option("--light", default="-0.4,0.6,0.7", show_default=True, help="Direction toward the light x,y,z."),
    click.option("--light-space", type=click.Choice(["camera", "world"]), default="camera", show_default=True,
                 help="--light is given in camera space (moves with the view) or in world space."),
    click.option("--supersample", type=click.Choice(["1", "2", "4"]), default=None,
                 help="Samples per pixel side everywhere (default from --quality: 1 draft, 1 default, 4 exact)."),
    click.option("--edge-supersample", type=click.IntRange(min=0, max=8), default=None,
                 help="Resample only the pixels at band, material or object edges R x R (default from --quality: "
                      "0 draft, 4 default, 0 exact)."),
    click.option("--masks", is_flag=True, help="Also one anti-aliased mask PNG per band (maskN/frame_NNNN.png)."),
    click.option("--no-shade", is_flag=True, help="No shade/ PNGs (the ramp colours)."),
    click.option("--objectid", is_flag=True, help="Also objectid/frame_NNNN.png (8-bit object ids, 0 background)."),
    click.option("--depth", is_flag=True, help="Also depth/frame_NNNN.png (16-bit linear depth; its range in the PNG and the JSON)."),
    click.option("--fill", is_flag=True, help="Also fill/frame_NNNN.png: hatching that keeps its screen size at any zoom (self-similar 3D texture)."),
    click.option("--fill-pattern", type=click.Choice(["hatch", "dots", "noise"]), default="hatch", show_default=True,
                 help="Texture of the fill."),
    click.option("--fill-period", type=FINITE, default=16.0, show_default=True, help="Fill texture period in px."),
    click.option("--gooch", is_flag=True, help="Gooch warm/cool ramp instead of darker shades."),
    click.option("--band-polygons", is_flag=True, help="Also the bands as vector polygons in an SVG layer under the lines."),
    click.option("--exr", is_flag=True,
                 help="Write frame_NNNN.exr: multilayer OpenEXR with float depth Z, normals N, shade RGBA "
                      "(premultiplied), band labels, Cryptomatte (objects, materials) and the lines per kind."),
    click.option("--exr-layers", default=None,
                 help="The EXR's layers, comma-separated: depth, normal, shade, bands, crypto, lines [all]."),
    click.option("--exr-codec", type=click.Choice(CODECS), default="zip", show_default=True,
                 help="The EXR's lossless compression: zip and zips are the smallest, piz encodes faster at about "
                      "twice their size, rle in about half zip's time at four to eight times the size."),
    click.option("--lines-png", is_flag=True, help="Also lines/frame_NNNN.png: the visible strokes as an RGBA image."),
]

_HIDDEN = [
    click.option("--hidden", is_flag=True,
                 help="Also draw the hidden lines (occlusion level >= 1: behind 1, 2, ... surfaces), dashed, in "
                      "hidden-<kind> layers under the visible ones; each JSON stroke gets its level."),
    click.option("--occlusion", "occlusion_range", default=None,
                 help="Draw the pieces whose occlusion level is in A-B (Line Art's range): 0-2, 1 (just behind one "
                      f"surface), 2- (two or more); 0 is visible; levels deeper than {MAX_OCCLUSION} count as "
                      f"{MAX_OCCLUSION}."),
    click.option("--dashes", default=None,
                 help="Hidden lines' dash and gap in px (SVG stroke-dasharray), e.g. 6,3, or 'solid' [ISO 128 "
                      "dashed: 12 and 3 stroke widths]."),
    click.option("--dash-paths", is_flag=True,
                 help="Write the hidden lines' dashes as geometry (a subpath per dash) instead of a dash style: "
                      "for plotters (vpype draws a styled dash pattern solid)."),
]


def render_extra_options(f):
    for deco in reversed(_TRACKING + _GLTF + _RASTER + _HIDDEN):
        f = deco(f)
    return f


def occlusion_from(extra: dict) -> tuple[int, int] | None:
    """LineOptions.occlusion from --hidden (every level) or --occlusion A-B; None: visible lines."""
    text = extra.get("occlusion_range")
    if extra.get("hidden") and text is not None:
        raise UsageError("--hidden and --occlusion both choose the levels drawn: give one (--hidden is "
                         f"--occlusion 0-{MAX_OCCLUSION})")
    if extra.get("hidden"):
        return 0, MAX_OCCLUSION
    if text is None:
        return None
    lo, sep, hi = text.strip().partition("-")
    try:
        a = int(lo)
        b = (MAX_OCCLUSION if not hi.strip() else int(hi)) if sep else a
    except ValueError:
        raise UsageError(f"bad --occlusion {text!r}: give levels A-B (whole numbers >= 0), A, or A-") from None
    if not 0 <= a <= b:
        raise UsageError(f"bad --occlusion {text!r}: give levels A-B with 0 <= A <= B")
    if b > MAX_OCCLUSION:
        raise UsageError(f"bad --occlusion {text!r}: levels go to {MAX_OCCLUSION} (deeper pieces count as "
                         f"{MAX_OCCLUSION}: write {a}- for every level from {a})")
    return a, b


def dashes_from(extra: dict, occlusion: tuple[int, int] | None) -> tuple[float, ...] | None:
    """OutputOptions.hidden_dashes from --dashes (None: the ISO 128 default); a usage error when
    no hidden line is drawn (the option would be ignored) or the pattern is not one."""
    text = extra.get("dashes")
    for flag, on in (("--dashes", text is not None), ("--dash-paths", extra.get("dash_paths"))):
        if on and (occlusion is None or occlusion[1] < 1):
            raise UsageError(f"{flag} styles the hidden lines: it needs --hidden or an --occlusion range with levels >= 1")
        if on and not extra.get("svg", True):
            raise UsageError(f"{flag} styles the SVG's hidden layers: it cannot go with --no-svg")
    if text is None:
        return None
    if text.strip().lower() == "solid":
        if extra.get("dash_paths"):
            raise UsageError("--dash-paths with --dashes solid: there are no dashes to write")
        return ()
    vals = _floats(text, "--dashes")
    if len(vals) % 2 or any(not (math.isfinite(v) and v >= 0) for v in vals) or not sum(vals) > 0:
        raise UsageError(f"bad --dashes {text!r}: give dash and gap lengths in px (pairs of numbers >= 0, not all 0), "
                         "or 'solid'")
    return vals


def strokes_mode(extra: dict, n_frames: int, coherence_given: bool) -> str:
    """'brush' or 'lines': --strokes, or by default brush paths for a sequence with coherence on
    (what a sequence is drawn for: strokes that persist), the exact lines for one frame, with
    --no-coherence or a --coherence method named (they track lines)."""
    if extra.get("strokes_mode"):
        return extra["strokes_mode"]
    coherent = not extra.get("no_coherence") and extra.get("coherence_method", "kalnins") != "none"
    return "brush" if n_frames >= 2 and coherent and not coherence_given else "lines"


def tracking_options_from(extra: dict, n_frames: int, mode: str = "lines"):
    """TrackingOptions for a sequence of lines with coherence on; None for one frame, brush paths
    or --no-coherence."""
    method = "none" if extra.get("no_coherence") else extra.get("coherence_method", "kalnins")
    if n_frames < 2 or method == "none" or mode == "brush":
        return None
    return TrackingOptions(method=method, max_growth_px=extra["max_growth"],
                           min_carry_px=extra["min_carry"])


def path_options_from(extra: dict, mode: str):
    """PathOptions for brush paths (history off with --no-coherence); None for lines."""
    if mode != "brush":
        return None
    merge = {} if extra.get("path_merge") is None else {"merge_px": extra["path_merge"]}
    return PathOptions(history=not extra.get("no_coherence") and extra.get("coherence_method") != "none", **merge)


def gltf_options_from(extra: dict, lines, fps: float = 24.0):
    """GltfOptions when glTF output is on, else None. A bad brush fails here, before any work."""
    if extra.get("gltf_sequence"):
        extra["gltf"] = True
    if not extra.get("gltf"):
        return None

    if extra["ribbon_width"] <= 0:
        raise UsageError(f"--ribbon-width must be > 0, got {extra['ribbon_width']}")
    opts = GltfOptions(width_px=extra["ribbon_width"], taper=extra["taper"], brush=extra["brush"],
                       alpha_mode=extra["alpha_mode"].upper(), space=extra["ribbon_space"], fps=fps)
    get_brush(opts.brush)
    return opts


def _floats(text: str, what: str, n: int | None = None) -> tuple[float, ...]:
    try:
        vals = tuple(float(x) for x in text.split(","))
    except ValueError:
        raise UsageError(f"bad {what} {text!r}: give numbers separated by commas") from None
    if n is not None and len(vals) != n:
        raise UsageError(f"bad {what} {text!r}: give {n} numbers")
    return vals


def wants_raster(extra: dict) -> bool:
    """Whether any raster output is asked for (--bands, --masks, --fill, --objectid, --depth,
    --band-polygons)."""
    return any(extra.get(k) for k in ("bands", "band_thresholds", "masks", "fill", "objectid", "depth",
                                      "band_polygons"))


def raster_options_from(extra: dict, quality: str):
    """RasterOptions when any raster output is asked for (--bands, --masks, --fill, --objectid,
    --depth, --band-polygons, or --exr), else None: lines-only runs do no raster pass at all.
    (Smooth shading splits normals at the line options' --crease-angle: the run passes it.)"""
    pngs = wants_raster(extra)
    if not (pngs or extra.get("exr")):
        return None
    k_default = QUALITY_PRESETS[quality]["supersample"]
    r_default = QUALITY_PRESETS[quality]["edge_supersample"]
    thresholds = _floats(extra["band_thresholds"], "--band-thresholds") if extra.get("band_thresholds") else ()
    if thresholds and extra.get("bands") and extra["bands"] != len(thresholds) + 1:
        raise UsageError(f"--bands {extra['bands']} but --band-thresholds gives {len(thresholds) + 1} bands "
                         "(N thresholds make N + 1 bands; give one of the two)")
    bands = extra.get("bands") or (len(thresholds) + 1 if thresholds else 3)
    K = int(extra["supersample"] or k_default)
    R = extra.get("edge_supersample")
    if R is None:
        R = r_default if r_default > K else 0  # (--supersample 4 on the default preset: uniform 4 x 4)
    elif R and R <= K:
        raise UsageError(f"--edge-supersample {R} must be above --supersample {K} (or 0, off): the edge pixels "
                         "would get no more samples than the others")
    return RasterOptions(bands=bands, thresholds=thresholds, shading=extra["shading"],
                         light=_floats(extra["light"], "--light", 3), light_space=extra["light_space"],
                         supersample=K, edge_supersample=R,
                         masks=extra["masks"], shade=not extra["no_shade"], objectid=extra["objectid"],
                         depth=extra["depth"], fill=extra["fill"], fill_pattern=extra["fill_pattern"],
                         fill_period_px=extra["fill_period"], gooch=extra["gooch"],
                         band_polygons=extra["band_polygons"], pngs=pngs)


def exr_options_from(extra: dict, stroke_width_px: float):
    """PassOptions of the EXR (--exr, --exr-layers), or None without --exr."""
    if not extra.get("exr"):
        return None
    layers = split_list(extra["exr_layers"], "--exr-layers") if extra.get("exr_layers") else PASSES
    return PassOptions(passes=layers, stroke_width_px=stroke_width_px, codec=extra.get("exr_codec") or "zip")
