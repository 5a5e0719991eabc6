"""The line styles gallery (docs/gallery): one frame of the bunny, the fandisk in isometric with
its hidden lines and the still life, each drawn in the gallery's styles (docs/gallery/*.toml),
the SVGs drawn to PNG by cairosvg and checked with Inkscape.

    python samples/make_gallery.py OUT        # SVGs in OUT, PNGs in docs/gallery
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
GALLERY = ROOT / "docs" / "gallery"
MODELS = ROOT.parent / "shared" / "models"

#: (name, scene, camera arguments, styles)
SHOTS = [
    ("bunny", MODELS / "stanford-bunny.obj", ["--orbit", "24", "--frames", "4", "--size", "640x640",
                                              "--strokes", "brush"],
     ("ink", "depth", "calligraphy", "pencil")),
    ("fandisk", MODELS / "fandisk.obj", ["--camera", "{iso}", "--hidden"], ("technical", "ink", "calligraphy", "depth")),
    ("still_life", ROOT / "samples" / "still_life.glb", ["--camera", str(ROOT / "samples" / "orbit.json"), "--frames",
                                                         "1", "--strokes", "brush"],
     ("still_life_objects", "ink", "depth", "pencil")),
]


def strokekit(*args, quiet: bool = True) -> None:
    cmd = [sys.executable, "-m", "strokekit_cli.main", *map(str, args), *(["-q"] if quiet else [])]
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        raise SystemExit(f"failed ({p.returncode}): {' '.join(cmd)}\n{p.stderr}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--no-inkscape", action="store_true", help="skip the Inkscape check")
    a = ap.parse_args()
    import cairosvg

    out = a.out.resolve()
    out.mkdir(parents=True, exist_ok=True)
    iso = out / "fandisk_iso.json"
    strokekit("camera", "parallel", MODELS / "fandisk.obj", "--projection", "isometric", "--width", "640",
              "--height", "480", "-o", iso, quiet=False)
    inkscape = None if a.no_inkscape else shutil.which("inkscape")
    for name, scene, cam, styles in SHOTS:
        cam = [c.replace("{iso}", str(iso)) for c in cam]
        for style in styles:
            d = out / f"{name}_{style}"
            strokekit("render", scene, *cam, "--style", GALLERY / f"{style}.toml", "--no-json", "--out", d)
            svg = next(d.glob("frame_*.svg"))
            png = GALLERY / f"{name}_{style}.png"
            cairosvg.svg2png(url=str(svg), write_to=str(png), background_color="white")
            line = f"{png.relative_to(ROOT)}"
            if inkscape:
                ink_png = d / "inkscape.png"
                r = subprocess.run([inkscape, str(svg), "--export-type=png", f"--export-filename={ink_png}"],
                                   capture_output=True, text=True)
                ok = r.returncode == 0 and ink_png.is_file() and ink_png.stat().st_size > 0
                line += f"  inkscape: {'ok' if ok else 'FAILED ' + r.stderr.strip()[-200:]}"
            print(line)


if __name__ == "__main__":
    main()
