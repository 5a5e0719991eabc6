"""The options of `strokekit render` that no library field holds (`RenderCommand`: where the
cameras come from, the preset, hidden lines, the run's report), when an option means something
(`NEEDS`), and the library's request and outputs made from what the command line said."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

from strokekit.camera.limits import MAX_PATH_FRAMES
from strokekit.errors import UsageError
from strokekit.kinds import MAX_OCCLUSION
from strokekit.options import QUALITY_PRESETS, LineOptions, option
from strokekit.paths.options import PathOptions
from strokekit.raster.options import PassOptions, RasterOptions
from strokekit.run.request import RenderRequest
from strokekit.run.spec import OutputOptions
from strokekit.style.file import read_style, style_error
from strokekit.style.linesets import Style
from strokekit.tracking.options import TrackingOptions
from strokekit.writers.options import GltfOptions

from ..common import floats, split_list
from ..flags import OPTION_CLASSES, field_values, flags_of


@dataclass(frozen=True)
class RenderCommand:
    """The command's own options, declared as the library's fields are (never instantiated)."""

    camera: str | None = option(None, "--camera", "Camera path JSON (format: docs/camera-files.md), or a "
                                "glTF/GLB file with a camera node (its animation, if any, sampled at 24 fps).", path=True)
    orbit: int | None = option(None, "--orbit", "Orbit the scene in N frames (instead of --camera; at most as many "
                               "as a camera file may have).", low=1, high=MAX_PATH_FRAMES)
    elevation: float = option(15.0, "--elevation", "Orbit elevation, degrees.", low=-90, high=90, show_default=True,
                              needs="orbit")
    fov: float = option(40.0, "--fov", "Orbit field of view, degrees.", low=0.1, high=179.9, show_default=True,
                        needs="orbit")
    up: str = option("y", "--up", "Orbit up axis.", choices=("y", "z"), show_default=True, needs="orbit")
    size: str | None = option(None, "--size", "Image size WxH (overrides the camera file), e.g. 1024x1024.")
    frames: str | None = option(None, "--frames", "Frames to render, 1-based: 1-24 or 1,3,5-9 (default all).")
    out: str = option("out", "--out", "Folder for the frame files (created if missing).", path=True,
                      show_default=True)
    quality: str = option("default", "--quality", "Accuracy preset: draft (fast), default, exact (slow reference).",
                          choices=tuple(QUALITY_PRESETS), show_default=True)
    no_coherence: bool = option(False, "--no-coherence", "Same as --coherence none: ids per frame, u = arc length / P "
                                "(brush paths: made afresh every frame).", switch=True)
    hidden: bool = option(False, "--hidden", "Also draw the hidden lines (occlusion level >= 1: behind 1, 2, ... "
                          "surfaces), dashed, in hidden-<kind> layers under the visible ones; each JSON stroke gets "
                          "its level.", switch=True)
    occlusion_range: str | None = option(
        None, "--occlusion", "Draw the pieces whose occlusion level is in A-B (Line Art's range): 0-2, 1 (just behind "
        f"one surface), 2- (two or more); 0 is visible; levels deeper than {MAX_OCCLUSION} count as {MAX_OCCLUSION}.",
        name_of_value="occlusion_range")
    dashes: str | None = option(None, "--dashes", "Hidden lines' dash and gap in px (SVG stroke-dasharray), e.g. 6,3, "
                                "or 'solid' [ISO 128 dashed: 12 and 3 stroke widths].")
    style: str | None = option(
        None, "--style", "Line styles from a TOML file: line sets selecting lines by kind, visibility, object or "
        "material, each with its colour, width, dashes and thickness modifiers (along, depth, curvature, calligraphy, "
        "noise; docs/styles.md); --stroke-width and --dashes set its defaults.", path=True)
    exr: bool = option(False, "--exr", "Write frame_NNNN.exr: multilayer OpenEXR with float depth Z, normals N, shade "
                       "RGBA (premultiplied), band labels, Cryptomatte (objects, materials) and the lines per kind.",
                       switch=True)
    quiet: bool = option(False, "--quiet", "No progress and no summary.", short="-q", switch=True)
    report: str | None = option(None, "--report", "Write a JSON run report.", path=True)
    explain: bool = option(False, "--explain", "List the stages that ran, why, and their time.", switch=True)


#: Every class whose fields are options of `strokekit render`, in the order --help lists them.
RENDER_CLASSES = (RenderCommand, *OPTION_CLASSES)

#: When an option means something: {Flag.needs: (what it needs, whether the parsed values have it)}.
NEEDS = {
    "orbit": ("--orbit (they shape the orbit; a --camera file has its own)", lambda x: not x["camera"]),
    "seed": ("--coherence seed", lambda x: x["coherence"] == "seed" and not x["no_coherence"]
             and x["strokes"] != "brush"),
    "fill": ("--fill", lambda x: x["fill"]),
    "exr": ("--exr", lambda x: x["exr"]),
    "brush": ("brush paths (--strokes brush, the default for a sequence)", lambda x: x["strokes"] != "lines"),
    "svg layer": ("the SVG (they are a layer of it; not --no-svg)", lambda x: x["svg"]),
    "gltf": ("--gltf or --gltf-sequence", lambda x: x["gltf"] or x["gltf_sequence"]),
    "raster": ("a raster output (--bands, --masks, --fill, --objectid, --depth, --band-polygons or --exr)",
               lambda x: wants_raster(x) or x["exr"]),
    "suggestive": ("suggestive in --kinds", lambda x: "suggestive" in (split_list(x["kinds"], "--kinds") or ())),
    "svg": ("the SVG (its coordinates; not --no-svg)", lambda x: x["svg"]),
    "no scheduler": ("no --scheduler (a dask cluster's workers draw the frames)", lambda x: not x["scheduler"]),
}


def check_needs(values: dict, said: dict) -> None:
    """A usage error for options said that mean nothing beside the others (NEEDS)."""
    flags = [flag for cls in RENDER_CLASSES for _, flag, _ in flags_of(cls) if flag.needs]
    for key, (need, holds) in NEEDS.items():
        names = [flag.name for flag in flags if flag.needs == key and flag.dest in said]
        if names and not holds(values):
            raise UsageError(f"{', '.join(names)} {'needs' if len(names) == 1 else 'need'} {need}")


def wants_raster(values: dict) -> bool:
    """Whether any raster PNG is asked for (--bands, --band-thresholds, --masks, --fill,
    --objectid, --depth, --band-polygons)."""
    return any(values.get(k) for k in ("bands", "band_thresholds", "masks", "fill", "objectid", "depth",
                                       "band_polygons"))


def request_from(values: dict, said: dict) -> RenderRequest:
    """The RenderRequest the command line says: the --quality preset, the options said over it,
    the style of --style with --stroke-width and --dashes over it (their shortcuts)."""
    lines = field_values(LineOptions, said)
    occlusion = occlusion_from(values)
    if occlusion is not None:
        lines["occlusion"] = occlusion
    style = style_from(values, said, occlusion)
    raster = None
    if wants_raster(values) or values["exr"]:
        raster = {**field_values(RasterOptions, said), "pngs": wants_raster(values)}
        thresholds, bands = raster.get("thresholds", ()), raster.get("bands")
        if thresholds and bands and bands != len(thresholds) + 1:
            raise UsageError(f"--bands {bands} but --band-thresholds gives {len(thresholds) + 1} bands "
                             "(N thresholds make N + 1 bands; give one of the two)")
    fields = field_values(RenderRequest, said)
    if values["no_coherence"]:
        fields["coherence"] = "none"
    try:
        request = RenderRequest.preset(values["quality"], lines=lines, raster=raster,
                                       tracking=TrackingOptions(**field_values(TrackingOptions, said)),
                                       paths=PathOptions(**field_values(PathOptions, said)), style=style, **fields)
    except UsageError as e:
        if (e.option or "").startswith("lineset."):  # a set that selects nothing the run draws
            raise style_error(style, e) from None
        raise
    if style.sets:
        ribbon = [flag for flag, dest in (("--ribbon-width", "ribbon_width"), ("--taper", "taper")) if dest in said]
        if ribbon:
            raise UsageError(f"{' and '.join(ribbon)} shape the ribbons of the default style: the line sets of "
                             f"--style {values['style']} give the ribbons their widths (a thickness "
                             "{ by = \"along\", ... } tapers them)")
    r = raster.get("edge_supersample") if raster is not None else None
    if r and r <= request.raster.supersample:
        raise UsageError(f"--edge-supersample {r} must be above --supersample {request.raster.supersample} (or 0, "
                         "off): the edge pixels would get no more samples than the others")
    return request


def style_from(values: dict, said: dict, occlusion: tuple[int, int] | None) -> Style:
    """The Style of --style (a bad file: an InputError naming its line, before any work), the
    shortcuts said over its defaults: --stroke-width (its width), --dashes (its hidden dashes)."""
    style = read_style(values["style"]) if values.get("style") else Style()
    shortcuts = field_values(Style, said)
    dashes = dashes_from(values, occlusion)
    if dashes is not None:
        shortcuts["dashes"] = dashes
    return replace(style, **shortcuts) if shortcuts else style


def outputs_from(values: dict, said: dict, occlusion: tuple[int, int] | None, fps: float) -> OutputOptions:
    """The OutputOptions the command line says; `fps`: the camera path's (the glTF's timing)."""
    gltf = values["gltf"] or values["gltf_sequence"]
    exr = PassOptions(**field_values(PassOptions, said), stroke_width_px=values["stroke_width"]) \
        if values["exr"] else None
    return OutputOptions(out_dir=Path(values["out"]), **{**field_values(OutputOptions, said), "gltf": gltf},
                         gltf_options=gltf_options_from(values, said, fps) if gltf else None, exr=exr)


def gltf_options_from(values: dict, said: dict, fps: float) -> GltfOptions:
    """GltfOptions of the ribbons. A bad brush fails here, before any work."""
    from strokekit.ribbons.brushes import get_brush

    if values["ribbon_width"] <= 0:
        raise UsageError(f"--ribbon-width must be > 0, got {values['ribbon_width']}")
    opts = GltfOptions(**field_values(GltfOptions, said), fps=fps)
    get_brush(opts.brush)
    return opts


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
    """Style.dashes from --dashes (None: not said, the ISO 128 default); a usage error when
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
    vals = floats(text, "--dashes")
    if len(vals) % 2 or any(not (math.isfinite(v) and v >= 0) for v in vals) or not sum(vals) > 0:
        raise UsageError(f"bad --dashes {text!r}: give dash and gap lengths in px (pairs of numbers >= 0, not all 0), "
                         "or 'solid'")
    return vals


