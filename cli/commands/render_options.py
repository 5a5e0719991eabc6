"""Options of `strokekit render` for the optional stages (tracking, glTF ribbons, raster masks),
kept apart so render.py stays a list of the core options. Each `*_options_from` turns the parsed
values into the library's options dataclass, or None when that stage is off."""

from __future__ import annotations

import click

from strokekit.errors import UsageError

_GLTF = [
    click.option("--gltf/--no-gltf", default=False, show_default=True, help="Write textured ribbons as frame_NNNN.glb."),
    click.option("--gltf-sequence", is_flag=True, help="One sequence.glb for all frames (a node per frame) instead."),
    click.option("--ribbon-width", type=float, default=3.0, show_default=True, help="Ribbon width in px."),
    click.option("--taper", type=float, default=1.0, show_default=True, help="Head/tail taper (0: none)."),
    click.option("--brush", default="ink", show_default=True, help="plain, ink, dry, or a PNG of your own stroke."),
    click.option("--alpha-mode", type=click.Choice(["blend", "mask"]), default="blend", show_default=True),
    click.option("--ribbon-space", type=click.Choice(["world", "image"]), default="world", show_default=True,
                 help="Ribbons in the scene facing the camera, or flat in pixel units for 2D compositing."),
]


_TRACKING = [
    click.option("--coherence", "coherence_method", type=click.Choice(["kalnins", "seed", "none"]), default="kalnins",
                 show_default=True, help="Frame-to-frame tracking: Kalnins-style votes, the seed-000 baseline, or none."),
    click.option("--no-coherence", is_flag=True, help="Same as --coherence none: ids per frame, u = arc length / P."),
    click.option("--max-growth", type=float, default=20.0, show_default=True,
                 help="Seed baseline: a stroke grows at most N px per frame (strategy 3)."),
    click.option("--min-carry", type=float, default=10.0, show_default=True,
                 help="Seed baseline: strokes shorter than N px are not carried to the next frame (strategy 5)."),
]


def render_extra_options(f):
    for deco in reversed(_TRACKING + _GLTF):
        f = deco(f)
    return f


def tracking_options_from(extra: dict, lines, n_frames: int):
    """TrackingOptions for a sequence with coherence on; None for one frame or --no-coherence."""
    method = "none" if extra.get("no_coherence") else extra.get("coherence_method", "kalnins")
    if n_frames < 2 or method == "none":
        return None
    from strokekit.tracking import TrackingOptions

    return TrackingOptions(method=method, period_px=lines.period_px, max_growth_px=extra["max_growth"],
                           min_carry_px=extra["min_carry"])


def gltf_options_from(extra: dict, lines, fps: float = 24.0):
    """GltfOptions when glTF output is on, else None. A bad brush fails here, before any work."""
    if extra.get("gltf_sequence"):
        extra["gltf"] = True
    if not extra.get("gltf"):
        return None
    from strokekit.brushes import get_brush
    from strokekit.writers.gltf import GltfOptions

    if extra["ribbon_width"] <= 0:
        raise UsageError(f"--ribbon-width must be > 0, got {extra['ribbon_width']}")
    opts = GltfOptions(width_px=extra["ribbon_width"], taper=extra["taper"], brush=extra["brush"],
                       alpha_mode=extra["alpha_mode"].upper(), space=extra["ribbon_space"], fps=fps)
    get_brush(opts.brush)
    return opts


def raster_options_from(extra: dict, quality: str):
    return None
