"""Raster pass benchmark (issues 5 and 17).

1. Speed of the pass: the bunny at 1024 x 1024, render's default raster quality (supersample 1,
   edge pixels resampled 4 x 4, 3 smooth bands, bands + shade PNGs), ms a frame of each part
   (z-buffer, labels + mixed pixels, edge samples, images, PNG), median over the frames of an
   8-frame orbit; beside it the same pass cast with Embree rays (the path the z-buffer replaced).
2. Band-mask accuracy: spot, fandisk, the bunny and CesiumMilkTruck at 1024 x 1024 on 4 orbit
   frames: for the z-buffer at K = 1, 2, 4, 1+4 and 2+4, the soft IoU per band (and background)
   against the Embree ray-cast reference at K = 4 (sum min / sum max of the per-pixel
   coverages): worst band, pooled, worst 'thick' band (strokekit.raster.bands.mask_agreement).
3. With --one-worker: issue 32's bar, one worker and no tracking (`--workers 1 --no-coherence`),
   the bunny at 1024 x 1024: the raster pass a frame, (25 frames with `--bands 3` minus 25
   without) / 25, against the lines a frame, (25 frames minus 1 frame) / 24; runs in turns,
   medians of --cli-repeats (wall time of the whole command).
4. With --cli: the issue-17 bars end to end from the command line, runs in turns (median of
   --cli-repeats): `strokekit render bunny --orbit 120 --size 1024x1024` with and without
   `--bands 3`: ((with) - (without)) / frames against the lines-only ms a frame (the run's wall
   time / frames, and its --explain line stages / frames); and the README's first command (a
   second run, 12 frames of the sample) with and without --bands 3.

Run: python benchmarks/bench_raster.py [--size 1024] [--repeats 3] [--skip-accuracy] [--one-worker] [--cli]
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from strokekit.camera.paths import orbit_path  # noqa: E402
from strokekit.raster.bands import RasterOptions, mask_agreement, render_raster  # noqa: E402
from strokekit.raster.hits import thread_workspace, warm_kernels  # noqa: E402
from strokekit.scene.load import load_scene  # noqa: E402
from strokekit.scene.occluder import Occluder  # noqa: E402
from strokekit.writers.png import png_files  # noqa: E402

MODELS = ROOT.parent / "shared" / "models"
#: The checkout whose command line the --cli and --one-worker runs time (--root: another one, to
#: compare two in turns).
CLI_ROOT = ROOT
LINE_STAGES = ("feature edges", "visibility", "occlusion levels", "chaining", "tracking", "svg", "json")


def speed(size: int, repeats: int) -> None:
    seconds, compiled = warm_kernels()
    scene = load_scene(MODELS / "stanford-bunny.obj")
    occ = Occluder(scene)
    cams = orbit_path(scene.center, scene.radius, 8, width=size, height=size).cameras
    opts = RasterOptions(bands=3)
    work = thread_workspace()
    render_raster(scene, cams[0], None, opts, work=work)  # per-scene tables (split normals), cached
    parts = defaultdict(list)
    rays = []
    for _ in range(repeats):
        for c in cams:
            t = {}
            t0 = time.perf_counter()
            fr = render_raster(scene, c, None, opts, work=work, timings=t)
            t1 = time.perf_counter()
            images = fr.images()
            t2 = time.perf_counter()
            png_files(images)
            t3 = time.perf_counter()
            for k, v in t.items():
                parts[k].append(v)
            parts["images"].append(t2 - t1)
            parts["PNG encode"].append(t3 - t2)
            parts["total"].append(t3 - t0)
            parts["mixed pixels (thousands)"].append(len(fr.mixed.pixels) / 1e3 * 1e-3)
            t0 = time.perf_counter()
            png_files(render_raster(scene, c, occ, opts, reference=True).images())
            rays.append(time.perf_counter() - t0)
    print(f"\n## raster pass: bunny {len(scene.faces)} faces, {size}x{size}, supersample 1 + edge 4x4, 3 smooth bands, "
          f"bands + shade PNGs, {len(parts['total'])} frames (kernels {'compiled' if compiled else 'loaded'} in "
          f"{seconds:.2f} s)")
    print("| part | median ms a frame |")
    print("|---|---|")
    for k, v in parts.items():
        print(f"| {k} | {1e3 * statistics.median(v):.1f} |")
    print(f"| the same cast with Embree rays (reference) | {1e3 * statistics.median(rays):.1f} |")


def accuracy_table(size: int, frames: int, bands: int, shading: str) -> None:
    print(f"\n## band masks vs Embree rays at 4x4, {size}x{size}, {bands} bands, {shading} shading, {frames} orbit frames")
    print("IoU = sum(min)/sum(max) of per-pixel coverages; 'thick' = bands whose area >= 10 x their partly covered pixels")
    print("K+R: z-buffer at supersample K, edge pixels resampled R x R (RasterOptions.edge_supersample; render's "
          "default 1+4)")
    print("| model | faces | K | ms per frame (median) | min IoU | pooled IoU | min IoU thick bands | bands < 0.99 |")
    print("|---|---|---|---|---|---|---|---|")
    for name in ("spot.obj", "fandisk.obj", "stanford-bunny.obj", "CesiumMilkTruck.glb"):
        scene = load_scene(MODELS / name)
        cams = orbit_path(scene.center, scene.radius, frames, width=size, height=size).cameras
        rows = mask_agreement(scene, cams, Occluder(scene), ks=(1, 2, 4, (1, 4), (2, 4)),
                              options=RasterOptions(bands=bands, shading=shading))
        for r in rows:
            k = f"{r['supersample']}" + (f"+{r['edge_supersample']}" if r["edge_supersample"] else "")
            print(f"| {name} | {len(scene.faces)} | {k} | {r['ms_per_frame']:.1f} | {r['iou']:.6f} | "
                  f"{r['iou_pooled']:.6f} | {r['iou_thick']:.6f} | {r['bands_below_099']}/{r['bands']} |")


def _render(args: list[str], out: str) -> tuple[float, dict]:
    """Wall seconds of one `strokekit render ... --explain -q` and its stage ms (from --explain)."""
    env = dict(os.environ, PYTHONPATH=str(CLI_ROOT))
    t = time.perf_counter()
    p = subprocess.run([sys.executable, "-m", "strokekit_cli.main", "render", *args, "--out", out, "--explain", "-q"],
                       cwd=CLI_ROOT, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t
    if p.returncode:
        raise SystemExit(p.stderr)
    stages = {}
    for line in p.stdout.splitlines():
        m = re.match(r"\s*\[ran \] (.+?)\s+([0-9.]+) ms", line)
        if m:
            stages[m.group(1).strip()] = float(m.group(2))
    return wall, stages


def cli_bars(repeats: int, frames: int) -> None:
    bunny = str(MODELS / "stanford-bunny.obj")
    base = [bunny, "--orbit", str(frames), "--size", "1024x1024"]
    sample = [str(ROOT / "samples" / "still_life.glb"), "--camera", str(ROOT / "samples" / "orbit.json"),
              "--frames", "1-12", "--gltf"]
    res = defaultdict(list)
    st_with, st_without = defaultdict(list), defaultdict(list)
    with tempfile.TemporaryDirectory() as tmp:
        _render(base[:2] + ["1", "--size", "64x64", "--bands", "3"], f"{tmp}/warm")  # kernels and scene cache
        for _ in range(repeats):
            w, s = _render(base, f"{tmp}/a")
            res["lines"].append(w)
            for k, v in s.items():
                st_without[k].append(v)
            w, s = _render(base + ["--bands", "3"], f"{tmp}/b")
            res["bands"].append(w)
            for k, v in s.items():
                st_with[k].append(v)
            _render(sample, f"{tmp}/s1")  # first run into the folder, then the timed second one
            res["readme"].append(_render(sample, f"{tmp}/s1")[0])
            _render(sample + ["--bands", "3"], f"{tmp}/s2")
            res["readme bands"].append(_render(sample + ["--bands", "3"], f"{tmp}/s2")[0])
    med = {k: statistics.median(v) for k, v in res.items()}
    lines_frame = 1e3 * med["lines"] / frames
    lines_stages = sum(statistics.median(st_without[k]) for k in LINE_STAGES if k in st_without) / frames
    added = 1e3 * (med["bands"] - med["lines"]) / frames
    print(f"\n## end to end from the CLI, median of {repeats} runs in turns (bunny {frames}-frame orbit, 1024x1024, "
          "default workers)")
    print(f"lines only: {med['lines']:.2f} s = {lines_frame:.1f} ms a frame (line stages from --explain: "
          f"{lines_stages:.1f} ms a frame of CPU)")
    raster_cpu = statistics.median(st_with["raster pass"]) / frames if "raster pass" in st_with else float("nan")
    print(f"with --bands 3: {med['bands']:.2f} s; added {added:.1f} ms a frame = {added / lines_frame:.2f} x the "
          f"lines-only ms a frame; bar <= 5 (the raster pass's CPU, {raster_cpu:.1f} ms a frame over the processes, "
          f"is {raster_cpu / lines_stages:.2f} x the line stages' CPU)")
    print("raster stages (--explain, ms a frame summed over processes): " + ", ".join(
        f"{k.strip()} {statistics.median(v) / frames:.1f}" for k, v in st_with.items()
        if k.strip() in ("raster pass", "z-buffer", "labels + mixed pixels", "edge samples", "images", "PNG encode")))
    print(f"README first command, second run: {med['readme']:.2f} s without --bands, {med['readme bands']:.2f} s with "
          f"--bands 3: {med['readme bands'] / med['readme']:.2f} x; bar <= 2")


def one_worker_bar(repeats: int) -> None:
    bunny = str(MODELS / "stanford-bunny.obj")
    base = [bunny, "--size", "1024x1024", "--workers", "1", "--no-coherence"]
    runs = {"lines 1": ["--orbit", "1"], "lines 25": ["--orbit", "25"], "bands 25": ["--orbit", "25", "--bands", "3"]}
    res = defaultdict(list)
    with tempfile.TemporaryDirectory() as tmp:
        _render(base + ["--orbit", "1", "--bands", "3"], f"{tmp}/warm")  # kernels and scene cache
        for _ in range(repeats):
            for name, extra in runs.items():
                res[name].append(_render(base + extra, f"{tmp}/{name.replace(' ', '')}")[0])
    lines = [(b - a) / 24 for a, b in zip(res["lines 1"], res["lines 25"])]
    raster = [(b - a) / 25 for a, b in zip(res["lines 25"], res["bands 25"])]
    ratio = [r / ln for r, ln in zip(raster, lines)]
    print(f"\n## issue 32's raster bar: bunny, 1024x1024, --workers 1 --no-coherence, {repeats} runs in turns")
    print("| run | median s |")
    print("|---|---|")
    for k, v in res.items():
        print(f"| {k} | {statistics.median(v):.3f} |")
    print(f"lines a frame {1e3 * statistics.median(lines):.1f} ms, raster pass a frame "
          f"{1e3 * statistics.median(raster):.1f} ms: {statistics.median(ratio):.2f} x (runs "
          + ", ".join(f"{r:.2f}" for r in ratio) + "); bar <= 5")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--bands", type=int, default=3)
    ap.add_argument("--shading", default="smooth", choices=("flat", "smooth", "both"))
    ap.add_argument("--frames", type=int, default=4)
    ap.add_argument("--skip-accuracy", action="store_true")
    ap.add_argument("--skip-speed", action="store_true")
    ap.add_argument("--cli", action="store_true", help="also the end-to-end bars from the command line")
    ap.add_argument("--one-worker", action="store_true", help="issue 32's bar: one worker, no tracking")
    ap.add_argument("--cli-repeats", type=int, default=3)
    ap.add_argument("--root", type=Path, default=ROOT, help="the checkout whose command line is timed")
    ap.add_argument("--cli-frames", type=int, default=120)
    a = ap.parse_args()
    global CLI_ROOT
    CLI_ROOT = a.root.resolve()
    if not a.skip_speed:
        speed(a.size, a.repeats)
    if not a.skip_accuracy:
        for sh in (("flat", "smooth") if a.shading == "both" else (a.shading,)):
            accuracy_table(a.size, a.frames, a.bands, sh)
    if a.one_worker:
        one_worker_bar(a.cli_repeats)
    if a.cli:
        cli_bars(a.cli_repeats, a.cli_frames)


if __name__ == "__main__":
    main()
