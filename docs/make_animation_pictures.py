"""Redraw docs/animation.png, the picture of docs/animation.md (deterministic).

Runs the page's commands in a temporary folder: the two scenes of samples/make_animated.py
(spot on a turntable, a skinned tube), each rendered before a still camera with the default
brush paths, then draws frames 1, 16, 31 and 46 of the turntable and 1, 9, 17 and 25 of the
tube from their frame JSON, each stroke in a colour of its id (a stroke that keeps its id keeps
its colour). Run: python docs/make_animation_pictures.py
"""

from __future__ import annotations

import colorsys
import json
import subprocess
import sys
import tempfile
from pathlib import Path

from PIL import Image, ImageDraw

ROOT = Path(__file__).resolve().parent.parent
SIZE = 512  # each frame is rendered at SIZE x SIZE px


def strokekit(*args) -> None:
    subprocess.run([sys.executable, "-m", "strokekit_cli.main", *map(str, args)], check=True)


def colour(i: int) -> tuple[int, int, int]:
    h = (i * 0.618033988749895) % 1.0
    r, g, b = colorsys.hsv_to_rgb(h, 0.75, 0.8)
    return int(255 * r), int(255 * g), int(255 * b)


def bounds(paths: list[Path], margin: int = 12) -> tuple[int, int, int, int]:
    """The box (px) of every stroke point of the frames, a margin around it."""
    xs, ys = [], []
    for path in paths:
        for st in json.loads(path.read_text())["strokes"]:
            xs += [x for x, _ in st["points"]]
            ys += [y for _, y in st["points"]]
    return (max(0, int(min(xs)) - margin), max(0, int(min(ys)) - margin), min(SIZE, int(max(xs)) + margin),
            min(SIZE, int(max(ys)) + margin))


def frame_image(path: Path, crop: tuple[int, int, int, int]) -> Image.Image:
    d = json.loads(path.read_text())
    scale = 2  # drawn at twice the size, then halved: smooth lines
    im = Image.new("RGB", (d["width"] * scale, d["height"] * scale), "white")
    draw = ImageDraw.Draw(im)
    for st in d["strokes"]:
        pts = [(x * scale, y * scale) for x, y in st["points"]]
        if len(pts) > 1:
            draw.line(pts, fill=colour(st["id"]), width=2 * scale, joint="curve")
    im = im.resize((d["width"], d["height"]), Image.LANCZOS)
    return im.crop(crop)


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        t = Path(tmp)
        subprocess.run([sys.executable, str(ROOT / "samples/make_animated.py"), str(t)], check=True)
        rows = []
        for name, frames, n, elevation in (("turntable", (1, 16, 31, 46), 48, 20), ("bend", (1, 9, 17, 25), 25, 10)):
            cam = t / f"{name}.json"
            strokekit("camera", "orbit", t / f"{name}.glb", "--frames", n, "--degrees-per-frame", 0,
                      "--elevation", elevation, "--width", SIZE, "--height", SIZE, "-o", cam)
            strokekit("render", t / f"{name}.glb", "--camera", cam, "--out", t / name, "-q")
            files = [t / name / f"frame_{f:04d}.json" for f in frames]
            crop = bounds(files)
            rows.append([frame_image(f, crop) for f in files])
        widths = [sum(im.width for im in r) for r in rows]
        picture = Image.new("RGB", (max(widths), sum(r[0].height for r in rows)), "white")
        y = 0
        for r, w in zip(rows, widths):
            x = (picture.width - w) // 2  # (each row centred)
            for im in r:
                picture.paste(im, (x, y))
                x += im.width
            y += r[0].height
        picture.save(ROOT / "docs/animation.png", optimize=True)


if __name__ == "__main__":
    main()
