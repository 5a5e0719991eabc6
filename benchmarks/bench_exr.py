"""What the multilayer EXR costs against the PNG passes it replaces (issue 18).

Each variant writes one frame's raster files the way `strokekit render` does
(the raster pass, then `run.tasks.raster_files`: the images and their encoding, into a
temporary folder), for every frame of an orbit, in turns, `--repeats` times:

- `no files`: the raster pass alone (what the others add is measured against it);
- `band PNGs`: render's default raster output (`--bands 3`: bands/ and shade/);
- `all PNGs`: the PNG passes that carry what the EXR holds (`--bands 3 --masks --objectid --depth
  --lines-png`: labels, band masks, shade colours, object ids, depth, the lines);
- `EXR`: `--exr` with every layer (depth, normals, shade, bands, Cryptomatte, lines), no PNG,
  its default codec; `EXR zip`, `EXR rle`: with `--exr-codec zip` / `rle`; `EXR full`: the
  default codec with `--exr-float full` (every channel float32).

Printed: process CPU ms a frame (all threads; steadier than wall time on a shared machine) and
wall ms a frame, median over the repeats; what the EXR adds against each PNG variant (the bar:
at most the time of the PNGs it replaces); the EXR's own parts (compositing passes, channels,
encoding) with the encoding's CPU and size under each lossless codec Blender 3.4 reads (RLE and
none by strokekit's compiled writer and, for comparison, by OpenEXR).

    python benchmarks/bench_exr.py [--models bunny,still-life] [--size 1024] [--frames 4] [--repeats 5]
"""

from __future__ import annotations

import argparse
import functools
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


from strokekit import LineOptions, LineRenderer, load_scene  # noqa: E402
from strokekit.metrics.bench import default_cameras  # noqa: E402
from strokekit.raster.bands import RasterOptions, render_raster  # noqa: E402
from strokekit.raster.hits import thread_workspace, warm_kernels  # noqa: E402
from strokekit.raster.passes import PassOptions, compositing_passes  # noqa: E402
from strokekit.run.frame import Frame  # noqa: E402
from strokekit.run.spec import OutputOptions  # noqa: E402
from strokekit.run.tasks import raster_files  # noqa: E402
from strokekit.writers.exr import COMPILED, COMPRESSION, compiled_exr, exr_bytes, exr_channels, openexr_file  # noqa: E402

MODELS = {"bunny": ROOT.parent / "shared" / "models" / "stanford-bunny.obj",
          "still-life": ROOT / "samples" / "still_life.glb",
          "truck": ROOT.parent / "shared" / "models" / "CesiumMilkTruck.glb"}


def variants(out: Path) -> dict[str, tuple[RasterOptions, OutputOptions]]:
    return {
        "no files": (RasterOptions(bands=3, pngs=False), OutputOptions(out)),
        "band PNGs": (RasterOptions(bands=3), OutputOptions(out)),
        "all PNGs": (RasterOptions(bands=3, masks=True, objectid=True, depth=True), OutputOptions(out, lines_png=True)),
        "EXR": (RasterOptions(bands=3, pngs=False), OutputOptions(out, exr=PassOptions())),
        "EXR zip": (RasterOptions(bands=3, pngs=False), OutputOptions(out, exr=PassOptions(codec="zip"))),
        "EXR rle": (RasterOptions(bands=3, pngs=False), OutputOptions(out, exr=PassOptions(codec="rle"))),
        "EXR full": (RasterOptions(bands=3, pngs=False), OutputOptions(out, exr=PassOptions(precision="full"))),
    }


def raster_and_files(scene, cam, occ, strokes, number, variant) -> list[str]:
    """One frame's raster pass and its files, as a render's frame task makes them."""
    raster_options, outputs = variant
    raster = render_raster(scene, cam, occ, raster_options, work=thread_workspace())
    return raster_files(Frame(number, cam, strokes, {}, (), raster=raster), outputs, {})


def timed(fn, *args) -> tuple[float, float]:
    """(process CPU s, wall s) of fn(*args)."""
    c, w = time.process_time(), time.perf_counter()
    fn(*args)
    return time.process_time() - c, time.perf_counter() - w


def bench_model(name: str, args) -> None:
    scene = load_scene(MODELS[name])
    cams = default_cameras(scene, args.frames, args.size)
    renderer = LineRenderer(scene, LineOptions())
    strokes = [renderer.render(c, i + 1) for i, c in enumerate(cams)]
    occ = renderer.occluder
    with tempfile.TemporaryDirectory(prefix="bench-exr-") as d:
        vs = variants(Path(d))
        cpu = {k: [] for k in vs}
        wall = {k: [] for k in vs}
        for f, cam in enumerate(cams):  # warm: per-scene tables, first-call costs
            for o in vs.values():
                raster_and_files(scene, cam, occ, strokes[f], f + 1, o)
        for _ in range(args.repeats):
            for key, o in vs.items():  # in turns: the machine's load hits every variant alike
                c = w = 0.0
                for f, cam in enumerate(cams):
                    dc, dw = timed(raster_and_files, scene, cam, occ, strokes[f], f + 1, o)
                    c, w = c + dc, w + dw
                cpu[key].append(1000 * c / len(cams))
                wall[key].append(1000 * w / len(cams))
    med = {k: (statistics.median(cpu[k]), statistics.median(wall[k])) for k in vs}
    print(f"\n{name}, {args.size} x {args.size}, {args.frames} frames, median of {args.repeats}: ms a frame "
          "(raster pass + its files)")
    print(f"  {'variant':10} {'CPU':>8} {'wall':>8}")
    for k, (c, w) in med.items():
        print(f"  {k:10} {c:8.1f} {w:8.1f}")
    for k in ("band PNGs", "all PNGs"):
        print(f"  EXR / {k}: CPU {med['EXR'][0] / med[k][0]:.2f}x, wall {med['EXR'][1] / med[k][1]:.2f}x")
    # What the files add to the raster pass (the bar: the EXR adds at most 1.5 times what the PNGs add).
    adds = {k: (c - med["no files"][0], w - med["no files"][1]) for k, (c, w) in med.items()}
    for k in ("EXR", "EXR zip", "EXR rle", "EXR full"):
        print(f"  {k} adds / all PNGs add: CPU {adds[k][0] / adds['all PNGs'][0]:.2f}x "
              f"({adds[k][0]:.1f} / {adds['all PNGs'][0]:.1f} ms), wall {adds[k][1] / adds['all PNGs'][1]:.2f}x")

    # The EXR's parts, on the first frame.
    raster = render_raster(scene, cams[0], occ, RasterOptions(bands=3, pngs=False), work=thread_workspace())
    codec = PassOptions().codec
    parts = {"passes": [], "channels": [], f"encode ({codec})": []}
    for _ in range(args.repeats):
        c, _w = timed(compositing_passes, raster, strokes[0], PassOptions())
        parts["passes"].append(c)
        p = compositing_passes(raster, strokes[0], PassOptions())
        parts["channels"].append(timed(exr_channels, p)[0])
        parts[f"encode ({codec})"].append(timed(exr_bytes, p, codec)[0] - parts["channels"][-1])
    ch, attrs = exr_channels(p)
    print(f"  EXR parts, CPU ms (frame 1, {len(ch)} channels, "
          f"{sum(a.nbytes for a in ch.values()) / 1e6:.0f} MB raw): "
          + ", ".join(f"{k} {1000 * statistics.median(v):.0f}" for k, v in parts.items()))
    encoders = {f"{c} (OpenEXR)": functools.partial(openexr_file, ch, attrs, c) for c in COMPRESSION}
    encoders.update({f"{c} (compiled)": functools.partial(compiled_exr, ch, attrs, c) for c in COMPILED})
    ts = {k: [] for k in encoders}
    size = {}
    for _ in range(args.repeats):
        for k, enc in encoders.items():  # in turns
            t = time.process_time()
            size[k] = len(enc())
            ts[k].append(time.process_time() - t)
    print("  encoding by codec, one thread, CPU: " + ", ".join(
        f"{k} {1000 * statistics.median(ts[k]):.0f} ms {size[k] / 1e6:.1f} MB" for k in encoders))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--models", default="bunny,still-life")
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--frames", type=int, default=4)
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    warm_kernels()
    for name in args.models.split(","):
        bench_model(name, args)


if __name__ == "__main__":
    main()
