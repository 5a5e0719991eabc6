"""Coherence bars of issue 3, side by side for the tracking methods.

For each model: a 120-frame orbit (3 degrees per frame) at 1024 x 1024 and a dolly from 1x to 8x
the framing distance; frames rendered with LineRenderer(scene, LineOptions()) (independent per
frame), then tracked in order with method none (`--no-coherence`), seed (seed 000 baseline),
kalnins (default) and kalnins-raw (the default method on lines rendered with doubled contour
pieces kept, LineOptions(doubled_px=0), and no bridges of up to join_tol_px where chains are
joined: what those two steps give). Prints M1, M2 (median
per pair), M4 (median / p95 / max px), M5 (octaves, with self-similar levels; raw u in
brackets) on the orbit, M5 on the dolly, and the tracking time per
frame against the lines-only time per frame (process CPU time, medians over frames, best of
`--repeat` runs: the machine is shared, CPU time is steadier than wall time).

    python benchmarks/bench_coherence.py [--frames 120] [--models spot,fandisk,bunny] [--json out.json]
        [--methods none,seed,kalnins,kalnins-raw] [--doubled 1]

`--doubled PX` renders the lines with LineOptions(doubled_px=PX) (kalnins-raw keeps 0): the trade-off
between steadier ids and drawing every visible contour edge (README, coherence section).

`strokes` is the mean number of strokes per tracked frame (the input lines: `strokes_in` in the JSON).

`--hidden` renders the hidden lines too (LineOptions(occlusion=(0, 15)), `strokekit render --hidden`),
tracked like the rest; each row is followed by M1 of the hidden lines alone (levels >= 1).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from strokekit.camera.paths import dolly_path, orbit_path
from strokekit.lines.renderer import LineRenderer
from strokekit.metrics.coherence import sequence_metrics
from strokekit.options import LineOptions
from strokekit.scene.load import load_scene
from strokekit.tracking.options import TrackingOptions
from strokekit.tracking.tracker import Tracker

MODELS = Path(__file__).resolve().parents[2] / "shared" / "models"
FILES = {"spot": "spot.obj", "fandisk": "fandisk.obj", "bunny": "stanford-bunny.obj", "cow": "cow.obj",
         "torus": "torus.STL"}
METHODS = ("none", "seed", "kalnins")
#: Rows: label -> TrackingOptions. "kalnins-raw": the default method on lines with their doubled
#: contour pieces kept (RAW_LINES) and no bridges at joins, to show what those two steps give.
VARIANTS = {"none": dict(method="none"), "seed": dict(method="seed"), "kalnins": dict(method="kalnins"),
            "kalnins-raw": dict(method="kalnins", join_tol_px=1e-6)}
RAW_LINES = {"kalnins-raw": dict(doubled_px=0.0)}
BARS = "bars: M1 >= 0.95, M2 median <= 0.02, M4 median <= 0.5 px and p95 <= 1.5 px, M5 (dolly) <= 0.35, track <= +30%"


def render(renderer: LineRenderer, path) -> tuple[list, np.ndarray]:
    frames, times = [], []
    for k, cam in enumerate(path.cameras):
        t = time.process_time()
        frames.append(renderer.render(cam, k + 1))
        times.append(time.process_time() - t)
    return frames, np.array(times)


def track(frames, method: str, repeat: int) -> tuple[list, np.ndarray]:
    best = None
    for _ in range(repeat):
        tr = Tracker(TrackingOptions(**VARIANTS[method]))
        out, times = [], []
        for f in frames:
            t = time.process_time()
            out.append(tr.step(f))
            times.append(time.process_time() - t)
        times = np.array(times)
        if best is None or np.median(times) < np.median(best):
            best = times
    return out, best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=120)
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--models", default="spot,fandisk,bunny")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--json", default=None, help="also write the rows as JSON here")
    ap.add_argument("--doubled", type=float, default=LineOptions.doubled_px,
                    help="LineOptions.doubled_px of the line pass (the trade-off in the README's coherence section)")
    ap.add_argument("--methods", default=",".join(VARIANTS), help="rows: " + ", ".join(VARIANTS))
    ap.add_argument("--hidden", action="store_true", help="draw hidden lines too (every occlusion level)")
    a = ap.parse_args()
    hidden = {"occlusion": (0, 15)} if a.hidden else {}
    rows = []
    print(BARS)
    head = (f"{'model':8} {'method':11} {'M1':>6} {'M2 med':>7} {'M4 med':>7} {'M4 p95':>7} {'M4 max':>7} "
            f"{'M5 orb':>13} {'M5 dolly':>14} {'M7 med':>7} {'strokes':>7} {'lines ms':>9} {'track ms':>9} {'+%':>6}")
    print(head)
    for name in a.models.split(","):
        sc = load_scene(MODELS / FILES[name])
        r = LineRenderer(sc, LineOptions(doubled_px=a.doubled, **hidden))
        orbit = orbit_path(sc.center, sc.radius, a.frames, degrees_per_frame=3.0, width=a.size, height=a.size)
        dolly = dolly_path(sc.center, sc.radius, a.frames, start=1.0, end=8.0, width=a.size, height=a.size)
        frames, t_lines = render(r, orbit)
        for _ in range(a.repeat - 1):  # lines-only time: best median of several runs
            t2 = render(r, orbit)[1]
            if np.median(t2) < np.median(t_lines):
                t_lines = t2
        dframes, _ = render(r, dolly)
        raw = {}  # frames rendered with other line options (RAW_LINES), once per variant
        for method in a.methods.split(","):
            f_in, d_in = frames, dframes
            if method in RAW_LINES:
                if method not in raw:
                    r_raw = LineRenderer(sc, LineOptions(**RAW_LINES[method], **hidden))
                    raw[method] = (render(r_raw, orbit)[0], render(r_raw, dolly)[0])
                f_in, d_in = raw[method]
            out, t_track = track(f_in, method, a.repeat)
            _, ov = sequence_metrics(out)
            dout, _ = track(d_in, method, 1)
            _, dv = sequence_metrics(dout)
            lm, tm = 1e3 * np.median(t_lines), 1e3 * np.median(t_track)
            row = {"model": name, "method": method, "frames": a.frames, **ov, "dolly_M5": dv["M5"],
                   "dolly_M5_raw": dv["M5_raw"], "dolly_M1": dv["M1"], "dolly_M4_median": dv["M4_median"],
                   "lines_ms": lm, "track_ms": tm, "track_overhead": tm / lm,
                   "strokes_in": float(np.mean([len(f) for f in f_in])),
                   "strokes_out": float(np.mean([len(f) for f in out]))}
            rows.append(row)
            print(f"{name:8} {method:11} {ov['M1']:6.3f} {ov['M2_median']:7.4f} {ov['M4_median']:7.2f} "
                  f"{ov['M4_p95']:7.2f} {ov['M4_max']:7.2f} {ov['M5']:6.3f} ({ov['M5_raw']:4.2f}) "
                  f"{dv['M5']:6.3f} ({dv['M5_raw']:5.2f}) {ov['M7_median']:7.2f} {row['strokes_out']:7.0f} {lm:9.1f} {tm:9.2f} "
                  f"{100 * tm / lm:5.0f}%", flush=True)
            if a.hidden:
                _, hv = sequence_metrics([f.select(f.occlusion >= 1) for f in out])
                row["M1_hidden"] = hv["M1"]
                print(f"{'':8} {'':11} hidden lines alone: M1 {hv['M1']:.3f}", flush=True)
    if a.json:
        Path(a.json).write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
