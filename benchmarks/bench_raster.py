"""Raster pass benchmark (issue 5).

1. Band-mask accuracy and cost: spot, fandisk, CesiumMilkTruck at 1024 x 1024 on 4 orbit frames;
   for K = 1, 2, 4: median time of render_raster + coverage, and the soft IoU per band (and
   background) against the 4x supersampled reference (sum min / sum max of the per-pixel
   coverages): worst band, pooled, worst 'thick' band (strokekit.raster.bands.mask_agreement).
2. Speed bar: the raster pass at 1024 x 1024, K = 1 on the bunny, median of several frames.

Run: python benchmarks/bench_raster.py [--size 1024] [--repeats 5]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from strokekit.camera.paths import orbit_path  # noqa: E402
from strokekit.raster.bands import RasterOptions, mask_agreement, render_raster  # noqa: E402
from strokekit.scene.load import load_scene  # noqa: E402
from strokekit.scene.occluder import Occluder  # noqa: E402
from strokekit.writers.png import png_bytes  # noqa: E402

MODELS = ROOT.parent / "shared" / "models"


def accuracy_table(size: int, frames: int, bands: int, shading: str) -> None:
    print(f"\n## band masks vs 4x reference, {size}x{size}, {bands} bands, {shading} shading, {frames} orbit frames")
    print("IoU = sum(min)/sum(max) of per-pixel coverages; 'thick' = bands whose area >= 10 x their partly covered pixels")
    print("K+R: supersample K, edge pixels resampled R x R (RasterOptions.edge_supersample)")
    print("| model | faces | K | ms per frame (median) | min IoU | pooled IoU | min IoU thick bands | bands < 0.99 |")
    print("|---|---|---|---|---|---|---|---|")
    for name in ("spot.obj", "fandisk.obj", "CesiumMilkTruck.glb"):
        scene = load_scene(MODELS / name)
        cams = orbit_path(scene.center, scene.radius, frames, width=size, height=size).cameras
        rows = mask_agreement(scene, cams, Occluder(scene), ks=(1, 2, 4, (1, 4), (2, 4)),
                              options=RasterOptions(bands=bands, shading=shading))
        for r in rows:
            k = f"{r['supersample']}" + (f"+{r['edge_supersample']}" if r["edge_supersample"] else "")
            print(f"| {name} | {len(scene.faces)} | {k} | {r['ms_per_frame']:.1f} | {r['iou']:.4f} | "
                  f"{r['iou_pooled']:.4f} | {r['iou_thick']:.4f} | {r['bands_below_099']}/{r['bands']} |")


def speed_bar(size: int, repeats: int) -> None:
    scene = load_scene(MODELS / "stanford-bunny.obj")
    occ = Occluder(scene)
    cams = orbit_path(scene.center, scene.radius, 8, width=size, height=size).cameras
    opts = RasterOptions(bands=3, supersample=1, shade=False)
    _ = scene.face_normals  # cached once per scene, like the BVH
    render_raster(scene, cams[0], occ, opts)  # warm-up
    t_pass, t_png, t_smooth = [], [], []
    smooth = RasterOptions(bands=3, supersample=1, shade=False, shading="smooth")
    # Smooth shading's corner normals (split at the crease angle) are cached per scene on the
    # first call; time that once, apart from the per-frame pass.
    t = time.perf_counter()
    render_raster(scene, cams[0], occ, smooth)
    t_first_smooth = time.perf_counter() - t
    for _ in range(repeats):
        for c in cams:
            t = time.perf_counter()
            fr = render_raster(scene, c, occ, opts)
            t_pass.append(time.perf_counter() - t)
            t = time.perf_counter()
            png_bytes(fr.labels)
            t_png.append(time.perf_counter() - t)
            t = time.perf_counter()
            render_raster(scene, c, occ, smooth)
            t_smooth.append(time.perf_counter() - t)
    print(f"\n## speed bar: bunny {len(scene.faces)} faces, {size}x{size}, K=1, {len(t_pass)} frames")
    print("| step | median ms | bar |")
    print("|---|---|---|")
    print(f"| raster pass, flat (rays + n.l + bands) | {1e3 * statistics.median(t_pass):.1f} | <= 120 |")
    print(f"| raster pass, smooth | {1e3 * statistics.median(t_smooth):.1f} | |")
    print(f"| first smooth pass (+ split normals, cached per scene) | {1e3 * t_first_smooth:.1f} | |")
    print(f"| bands PNG encode | {1e3 * statistics.median(t_png):.1f} | |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--bands", type=int, default=3)
    ap.add_argument("--shading", default="both", choices=("flat", "smooth", "both"))
    ap.add_argument("--frames", type=int, default=4)
    ap.add_argument("--skip-accuracy", action="store_true")
    a = ap.parse_args()
    speed_bar(a.size, a.repeats)
    if not a.skip_accuracy:
        for sh in (("flat", "smooth") if a.shading == "both" else (a.shading,)):
            accuracy_table(a.size, a.frames, a.bands, sh)


if __name__ == "__main__":
    main()
