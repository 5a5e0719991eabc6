"""Issue 20 bars for hidden lines, printed as three tables.

1. Accuracy against the exact reference (strokekit.metrics.hidden: every candidate mesh edge
   sampled every 0.25 px, levels counted by the definition in float64): precision / recall at
   1 px of the visible (level 0) and of the hidden (level >= 1) lines, and the share of the drawn
   length whose level is right, on fandisk, rocker-arm and the bunny, 8-frame orbit, 1024 x 1024,
   with the default preset and with its cleanup of doubled lines off (`--doubled 0
   --keep-retraced`: the reference keeps every edge, the default drops contour shingles within
   1 px). Bars: >= 0.999 each.
2. Cost: ms per frame, lines + SVG + JSON (as `strokekit bench` times them), lines only and with
   `--hidden`, process CPU time (the machine is shared: steadier than wall time), median over
   repeats run in turns, and what --hidden adds. Bar: at most +60% on the bunny.
3. How to count the surfaces a ray crosses (the bunny's level samples of one frame): open3d's
   list_intersections with the dedup of strokekit (chosen), rays continued past each hit
   (cast_rays from just past the hit, a round per crossing), open3d's count_intersections (two
   calls: from the origin, and from the target on, subtracted); time per call and agreement
   with the exact level, and the same on the isometric unit cube (rays along face diagonals).

    python benchmarks/bench_hidden.py [--frames 8] [--repeats 5] [--models fandisk,rocker-arm,bunny]
                                      [--skip-accuracy] [--skip-speed] [--skip-rays] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from strokekit import LineOptions, LineRenderer, build_scene, load_scene  # noqa: E402
from strokekit.camera.view import Camera  # noqa: E402
from strokekit.lines.facing import FrameView  # noqa: E402
from strokekit.lines.features import feature_edges  # noqa: E402
from strokekit.lines.levels import _count_crossings_stepping, count_crossings  # noqa: E402
from strokekit.lines.occlusion import own_faces  # noqa: E402
from strokekit.lines.sightlines import segments  # noqa: E402
from strokekit.lines.visibility import clip_segments  # noqa: E402
from strokekit.metrics.bench import default_cameras, frame_bytes  # noqa: E402
from strokekit.metrics.hidden import exact_levels, hidden_accuracy, reference_drawing  # noqa: E402

MODELS = ROOT.parent / "shared" / "models"
FILES = {"fandisk": "fandisk.obj", "rocker-arm": "rocker-arm.obj", "bunny": "stanford-bunny.obj"}
HIDDEN = {"occlusion": (0, 15)}
RAW = {"doubled_px": 0.0, "merge_overlaps": False}


def accuracy_rows(args) -> list[dict]:
    rows = []
    print(f"{'model':11} {'lines':8} {'vis P':>8} {'vis R':>8} {'hid P':>8} {'hid R':>8} {'level ok':>9} "
          f"{'ref s/frame':>11}")
    for name in args.models.split(","):
        scene = load_scene(MODELS / FILES[name])
        cams = default_cameras(scene, args.frames)
        refs = None
        for label, extra in (("default", {}), ("raw", RAW)):
            opts = LineOptions.preset("default", **HIDDEN, **extra)
            r = LineRenderer(scene, opts)
            drawn = [r.render(c, k + 1) for k, c in enumerate(cams)]
            t = time.perf_counter()
            if refs is None:  # one reference for both rows (it depends on the kinds only)
                refs = [reference_drawing(scene, c, opts, occluder=r.occluder) for c in cams]
            ref_s = (time.perf_counter() - t) / len(cams)
            acc = hidden_accuracy(scene, drawn, refs, tols=(1.0,), occluder=r.occluder)
            row = {"model": name, "lines": label, **acc.to_json()}
            rows.append(row)
            print(f"{name:11} {label:8} {acc.visible.precision[1.0]:8.5f} {acc.visible.recall[1.0]:8.5f} "
                  f"{acc.hidden.precision[1.0]:8.5f} {acc.hidden.recall[1.0]:8.5f} {acc.level_right:9.5f} "
                  f"{ref_s:11.1f}", flush=True)
    return rows


def _time(renderer, cams) -> tuple[float, dict]:
    """Process CPU ms per frame (lines + SVG + JSON) and wall ms per stage."""
    stages: dict = {}
    c0 = time.process_time()
    for k, c in enumerate(cams):
        s = renderer.render(c, k + 1, timings=stages)
        frame_bytes(s, c, k + 1, renderer.options.layers)
    n = len(cams)
    return 1000.0 * (time.process_time() - c0) / n, {k: 1000.0 * v / n for k, v in stages.items()}


def speed_rows(args) -> list[dict]:
    rows = []
    print(f"{'model':11} {'lines ms':>9} {'hidden ms':>10} {'added':>7}  stages (hidden, ms)")
    for name in args.models.split(","):
        scene = load_scene(MODELS / FILES[name])
        cams = default_cameras(scene, args.frames)
        base = LineRenderer(scene, LineOptions.preset("default"))
        hid = LineRenderer(scene, LineOptions.preset("default", **HIDDEN))
        for r in (base, hid):  # warm-up: caches, BVH, imports
            _time(r, cams)
        tb, th, stages = [], [], []
        for _ in range(args.repeats):  # in turns: load on the machine falls on both alike
            tb.append(_time(base, cams)[0])
            ms, st = _time(hid, cams)
            th.append(ms)
            stages.append(st)
        b, h = float(np.median(tb)), float(np.median(th))
        st = {k: float(np.median([s[k] for s in stages])) for k in stages[0]}
        rows.append({"model": name, "lines_ms": b, "hidden_ms": h, "added": h / b - 1.0, "lines_repeats": tb,
                     "hidden_repeats": th, "hidden_stages_ms": st,
                     "strokes": [len(base.render(cams[0])), len(hid.render(cams[0]))]})
        print(f"{name:11} {b:9.1f} {h:10.1f} {100 * (h / b - 1):6.0f}%  " +
              ", ".join(f"{k} {v:.1f}" for k, v in st.items()), flush=True)
    return rows


def _samples(scene, cam, options):
    """The points the level pass counts first on one frame: the middles of 4 px parts of every
    clipped candidate edge, with their own faces (lines.occlusion)."""
    fe = feature_edges(FrameView(scene, cam), options, with_lift=True)
    t0, t1 = clip_segments(fe.a, fe.b, cam, cam.near_distance(scene.radius))
    idx = np.flatnonzero(t1 > t0)
    A = fe.a[idx] + t0[idx, None] * (fe.b[idx] - fe.a[idx])
    B = fe.a[idx] + t1[idx, None] * (fe.b[idx] - fe.a[idx])
    L = np.linalg.norm(cam.project(B)[0] - cam.project(A)[0], axis=1)
    m = np.maximum(1, np.ceil(L / 4.0)).astype(np.int64)
    seg = np.repeat(np.arange(len(idx)), m)
    s = (np.arange(m.sum()) - np.repeat(np.cumsum(m) - m, m) + 0.5) / m[seg]
    X = A[seg] + s[:, None] * (B[seg] - A[seg])  # (parallel parameter: the comparison needs points only)
    own, _ = own_faces(scene, fe, idx)
    return X, own[seg]


def _continued(occ, o, t, own):
    """Rays continued past each hit: cast_rays from just past it to the same target, a round per
    crossing (levels._count_crossings_stepping, the non-open3d path)."""
    return _count_crossings_stepping(occ, o, t, 16, skip=own)[0]


def _count_twice(occ, o, t, own):
    """open3d's count_intersections counts along the whole ray: from the origin, minus from the
    target on. It cannot skip the point's own faces or merge a shared edge's double report."""

    k = occ.inv_scale
    lo = (o - occ.origin) * k
    d = (t - o) * k
    a = occ.count_intersections(np.concatenate([lo, d], 1).astype(np.float32))
    b = occ.count_intersections(np.concatenate([lo + d, d], 1).astype(np.float32))
    return a.astype(np.int64) - b.astype(np.int64)


def ray_rows(args) -> list[dict]:
    methods = {"list_intersections (chosen)": lambda occ, o, t, own: count_crossings(occ, o, t, 16, skip=own)[0],
               "continued cast_rays": _continued, "count_intersections x2": _count_twice}
    rows = []
    v = np.array([[x, y, z] for x in (0.0, 1) for y in (0.0, 1) for z in (0.0, 1)])
    f = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1], [2, 3, 7], [2, 7, 6],
                  [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    cube = build_scene(v, f)
    cube_cam = Camera.parallel("isometric", (0.5, 0.5, 0.5), 4.0, ortho_height=3.0, width=400, height=400)
    bunny = load_scene(MODELS / FILES["bunny"])
    print(f"{'scene':14} {'method':30} {'rays':>6} {'ms/call':>8} {'= exact':>8}")
    for label, scene, cam in (("bunny", bunny, default_cameras(bunny, 8)[1]), ("cube isometric", cube, cube_cam)):
        r = LineRenderer(scene, LineOptions(**HIDDEN))
        occ = r.occluder
        X, own = _samples(scene, cam, r.options)
        eps = 1e-5 * np.maximum(np.linalg.norm(X - occ.origin, axis=1), scene.radius * 1e-3)
        o, t = segments(occ, X, cam, eps, 1e-5)
        exact = exact_levels(scene, cam, X, own, occ)
        for name, fn in methods.items():
            fn(occ, o, t, own)
            c0 = time.perf_counter()
            for _ in range(args.repeats):
                got = fn(occ, o, t, own)
            ms = 1000.0 * (time.perf_counter() - c0) / args.repeats
            agree = float((got == exact).mean())
            rows.append({"scene": label, "method": name, "rays": len(X), "ms_per_call": ms, "agree_exact": agree})
            print(f"{label:14} {name:30} {len(X):6d} {ms:8.2f} {agree:8.4f}", flush=True)
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=8)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--models", default="fandisk,rocker-arm,bunny")
    ap.add_argument("--skip-accuracy", action="store_true")
    ap.add_argument("--skip-speed", action="store_true")
    ap.add_argument("--skip-rays", action="store_true")
    ap.add_argument("--json", default=None)
    a = ap.parse_args()
    out = {}
    if not a.skip_accuracy:
        out["accuracy"] = accuracy_rows(a)
    if not a.skip_speed:
        out["speed"] = speed_rows(a)
    if not a.skip_rays:
        out["rays"] = ray_rows(a)
    if a.json:
        Path(a.json).write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
