"""Options of `strokekit render` for the optional stages (tracking, glTF ribbons, raster masks),
kept apart so render.py stays a list of the core options."""

from __future__ import annotations


def render_extra_options(f):
    return f


def tracking_options_from(extra: dict, lines, n_frames: int):
    return None


def gltf_options_from(extra: dict, lines):
    return None


def raster_options_from(extra: dict, quality: str):
    return None
