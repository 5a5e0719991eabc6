"""Issue 7 benchmark: frames in parallel, and end-to-end throughput.

  python benchmarks/bench_parallel.py [--frames 48] [--repeats 3] [--gltf]

Runs `strokekit.pipeline.run` on a bunny orbit at 1024 x 1024 with 1 and 2 workers, in one
process run so the ratio is measured under the same conditions. Reports the median wall time of
each, the speed-up, and the speed-up of the frame work alone (wall time minus the start-up of a
one-frame run with the same worker count, which is scene loading and worker spawn).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from strokekit.camera import orbit_path  # noqa: E402
from strokekit.options import LineOptions  # noqa: E402
from strokekit.pipeline import OutputOptions, RunSpec, run  # noqa: E402
from strokekit.scene import load_scene  # noqa: E402


def spec_for(scene_path, cams, workers, out_dir, gltf, tracking):
    return RunSpec(scene_path=str(scene_path), cameras=tuple(cams), lines=LineOptions(),
                   outputs=OutputOptions(out_dir=Path(out_dir), gltf=gltf, gltf_options=_gltf_options() if gltf else None),
                   tracking=tracking, workers=workers)


def _gltf_options():
    from strokekit.writers.gltf import GltfOptions

    return GltfOptions()


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", default=str(ROOT.parent / "shared" / "models" / "stanford-bunny.obj"))
    ap.add_argument("--frames", type=int, default=48)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--gltf", action="store_true", help="also write GLB ribbons")
    ap.add_argument("--tracking", action="store_true", help="coherent tracking on")
    a = ap.parse_args()
    s = load_scene(a.scene)
    path = orbit_path(s.center, s.radius, a.frames, degrees_per_frame=3.0)
    cams = [(i + 1, c) for i, c in enumerate(path.cameras)]
    tracking = None
    if a.tracking:
        from strokekit.tracking import TrackingOptions

        tracking = TrackingOptions()
    times = {}
    for workers in (1, 2):
        full, start = [], []
        for _ in range(a.repeats):
            with tempfile.TemporaryDirectory() as d:
                t = time.perf_counter()
                res = run(spec_for(a.scene, cams, workers, d, a.gltf, tracking))
                full.append(time.perf_counter() - t)
                assert not res.failures, res.failures
            with tempfile.TemporaryDirectory() as d:
                t = time.perf_counter()
                run(spec_for(a.scene, cams[:workers], workers, d, a.gltf, tracking))
                start.append(time.perf_counter() - t)
        times[workers] = (statistics.median(full), statistics.median(start))
    print(f"{a.frames}-frame orbit of {Path(a.scene).name}, 1024x1024, lines + SVG + JSON"
          f"{' + GLB' if a.gltf else ''}{' + tracking' if a.tracking else ''}, median of {a.repeats}")
    print(f"{'workers':>8} {'wall s':>8} {'frames/s':>9} {'start-up s':>11} {'frame work s':>13}")
    for w, (full, start) in times.items():
        print(f"{w:>8} {full:8.2f} {a.frames / full:9.1f} {start:11.2f} {full - start:13.2f}")
    (f1, s1), (f2, s2) = times[1], times[2]
    print(f"speed-up with 2 workers: {f1 / f2:.2f}x end to end, {(f1 - s1) / max(f2 - s2, 1e-9):.2f}x on the frame work")


if __name__ == "__main__":
    main()
