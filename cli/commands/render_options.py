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


def render_extra_options(f):
    for deco in reversed(_GLTF):
        f = deco(f)
    return f


def tracking_options_from(extra: dict, lines, n_frames: int):
    return None


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
