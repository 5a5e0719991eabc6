"""Redraw docs/still_life.png, the README's picture, from the bundled sample (deterministic).

Frame 1 of samples/orbit.json three times: the SVG lines; the same lines over the shade pass
(`--bands 3`); the hidden lines dashed (`--hidden`). Each SVG is rasterized with cairosvg.
Run: python docs/make_picture.py
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
from pathlib import Path

import cairosvg
from PIL import Image

ROOT = Path(__file__).resolve().parent.parent
CROP = (150, 165, 615, 500)  # the still life within the 800 x 600 frame, a margin around it


def render(out: Path, *options: str) -> Image.Image:
    subprocess.run(
        [sys.executable, "-m", "strokekit_cli.main", "render", str(ROOT / "samples/still_life.glb"),
         "--camera", str(ROOT / "samples/orbit.json"), "--frames", "1", "--no-json", "--out", str(out), "-q",
         *options],
        check=True,
    )
    png = out / "lines.png"
    cairosvg.svg2png(url=str(out / "frame_0001.svg"), write_to=str(png), background_color="white")
    return Image.open(png).convert("RGBA")


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        lines = render(tmp / "lines")
        render(tmp / "bands", "--bands", "3")
        shade = Image.open(tmp / "bands/shade/frame_0001.png").convert("RGBA")
        cairosvg.svg2png(url=str(tmp / "bands/frame_0001.svg"), write_to=str(tmp / "ink.png"))  # no background
        ink = Image.open(tmp / "ink.png").convert("RGBA")
        shaded = Image.alpha_composite(Image.alpha_composite(Image.new("RGBA", shade.size, "white"), shade), ink)
        hidden = render(tmp / "hidden", "--hidden")
        panels = [im.crop(CROP).convert("RGB") for im in (lines, shaded, hidden)]
        w, h = panels[0].size
        picture = Image.new("RGB", (3 * w, h), "white")
        for i, panel in enumerate(panels):
            picture.paste(panel, (i * w, 0))
        picture.save(ROOT / "docs/still_life.png", optimize=True)


if __name__ == "__main__":
    main()
