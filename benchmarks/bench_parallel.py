"""Issue 7 benchmark: frames in parallel, and end-to-end throughput.

  python benchmarks/bench_parallel.py [--frames 48] [--repeats 3] [--gltf] [--tracking] [--kind threads]

Runs `strokekit.run.run` on a bunny orbit at 1024 x 1024 with 1 and 2 workers (--kind: threads,
the default, or processes), in one process run so the ratios are measured under the same
conditions, two ways:
- cold: each run starts its own pool, as `strokekit render --workers N` does (a thread starts at
  once; a spawned worker spends about a second on imports, the scene and its BVH before its
  first frame);
- warm: one pool per worker count, started before the timing and kept across runs (as a
  library user rendering several shots keeps it: `run(spec, workers=make_executor(...))`), so
  the ratio is that of the frame work alone.
Medians of --repeats runs; cold and warm runs alternate between 1 and 2 workers.

Why warm stays near 1.7x on a 2-core machine (measured per thread, quiet machine): the 1-worker
run is not single-core: open3d's Embree queries run a helper thread on the idle core (~70 ms of
~680 ms CPU over 48 frames, wall ~615 ms). With 2 workers both cores are busy (about 97%), the
helper work moves back onto the main threads and a frame costs 3-5% more CPU (two independent
processes with no IPC at all show the same). Bound: 2 x 615 / ~715 ms = ~1.72x; perfect
scaling of the CPU time alone would give (610 + 70) / 2 = 340 ms, 1.81x.
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

from strokekit.camera.paths import orbit_path  # noqa: E402
from strokekit.options import LineOptions  # noqa: E402
from strokekit.run.request import RenderRequest  # noqa: E402
from strokekit.run.runner import run  # noqa: E402
from strokekit.run.spec import OutputOptions, RunSpec  # noqa: E402
from strokekit.run.workers import SceneRef, make_executor  # noqa: E402
from strokekit.scene.load import load_scene  # noqa: E402


def spec_for(scene_path, cams, workers, out_dir, gltf, tracking, kind="threads"):
    return RunSpec(scene_path=str(scene_path), cameras=tuple(cams),
                   outputs=OutputOptions(out_dir=Path(out_dir), gltf=gltf, gltf_options=_gltf_options() if gltf else None),
                   request=RenderRequest(strokes="lines", coherence=None if tracking else "none"), workers=workers,
                   worker_kind=kind)


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
    ap.add_argument("--kind", default="threads", choices=("threads", "processes"), help="what the workers are")
    a = ap.parse_args()
    s = load_scene(a.scene)
    path = orbit_path(s.center, s.radius, a.frames, degrees_per_frame=3.0)
    cams = [(i + 1, c) for i, c in enumerate(path.cameras)]
    tracking = a.tracking
    cold, warm = {1: [], 2: []}, {1: [], 2: []}
    for _ in range(a.repeats):
        for workers in (1, 2):
            with tempfile.TemporaryDirectory() as d:
                t = time.perf_counter()
                res = run(spec_for(a.scene, cams, workers, d, a.gltf, tracking, a.kind))
                cold[workers].append(time.perf_counter() - t)
                assert not res.failures, res.failures
    pools = {w: make_executor(w, None, SceneRef(a.scene, "", LineOptions()), kind=a.kind) for w in (1, 2)}
    try:
        while pools[2].started.value < 1:  # the pool worker has its scene and BVH
            time.sleep(0.02)
        for _ in range(a.repeats):
            for workers in (1, 2):
                with tempfile.TemporaryDirectory() as d:
                    t = time.perf_counter()
                    res = run(spec_for(a.scene, cams, workers, d, a.gltf, tracking, a.kind), workers=pools[workers],
                              scene=s)
                    warm[workers].append(time.perf_counter() - t)
                    assert not res.failures, res.failures
    finally:
        for p in pools.values():
            p.close()
    print(f"{a.frames}-frame orbit of {Path(a.scene).name}, 1024x1024, {a.kind}, lines + SVG + JSON"
          f"{' + GLB' if a.gltf else ''}{' + tracking' if a.tracking else ''}, median of {a.repeats}")
    print(f"{'workers':>8} {'cold s':>8} {'frames/s':>9} {'warm s':>8} {'frames/s':>9}")
    med = {k: {w: statistics.median(v) for w, v in d.items()} for k, d in (("cold", cold), ("warm", warm))}
    for w in (1, 2):
        c, h = med["cold"][w], med["warm"][w]
        print(f"{w:>8} {c:8.2f} {a.frames / c:9.1f} {h:8.2f} {a.frames / h:9.1f}")
    print(f"speed-up with 2 workers: {med['cold'][1] / med['cold'][2]:.2f}x cold (pool started by the run), "
          f"{med['warm'][1] / med['warm'][2]:.2f}x warm (pool already up)")


if __name__ == "__main__":
    main()
