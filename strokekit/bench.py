"""What accuracy costs in time (issue 6): every --quality preset and a sweep of the main knob,
timed per frame and measured against the `exact` preset (BRIEF 2).

Time per frame is what a render spends on lines after loading: LineRenderer.render(camera) then
the SVG and JSON bytes of the frame (strokekit.writers), the median over repeats of the mean per
frame. Accuracy is precision/recall of visible line length at several tolerances (px) against the
exact preset's strokes of the same cameras (strokekit.accuracy).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from .accuracy import DEFAULT_TOLS, Accuracy, accuracy
from .camera import Camera, orbit_path
from .lines import LineRenderer
from .model import Strokes
from .options import QUALITY_PRESETS, LineOptions
from .scene import Scene

#: The main knob and the values `strokekit bench` sweeps (px between visibility samples), the
#: other knobs held at the default preset.
MAIN_KNOB = "sample_spacing_px"
DEFAULT_SWEEP: tuple[float, ...] = (0.5, 1.0, 2.0, 4.0, 8.0, 16.0)
REFERENCE = "exact"


@dataclass
class BenchRow:
    """One configuration: `curve` is the knob it belongs to ('quality' for the presets),
    `label` its value. ms_per_frame: median over repeats of the mean time per frame (ms)."""

    curve: str
    label: str
    options: LineOptions
    ms_per_frame: float = float("nan")
    ms_repeats: list[float] = field(default_factory=list)
    strokes_per_frame: float = 0.0
    accuracy: Accuracy | None = None

    def to_json(self) -> dict:
        return {"curve": self.curve, "label": self.label, "ms_per_frame": self.ms_per_frame,
                "ms_repeats": self.ms_repeats, "strokes_per_frame": self.strokes_per_frame,
                "accuracy": self.accuracy.to_json() if self.accuracy else None,
                "knobs": {k: getattr(self.options, k) for k in QUALITY_PRESETS["default"]}}


def frame_bytes(strokes: Strokes, camera: Camera, frame: int, kinds: tuple[str, ...]) -> tuple[bytes, bytes]:
    """The SVG and JSON bytes of one frame, as `strokekit render` writes them."""
    from .writers.strokes_json import strokes_json
    from .writers.svg import svg_document

    svg = svg_document(strokes, camera.width, camera.height, kinds).encode("utf-8")
    return svg, strokes_json(strokes, camera.width, camera.height, frame)


def time_lines(renderer: LineRenderer, cameras: list[Camera], repeats: int = 3) -> tuple[list[float], list[Strokes]]:
    """Render every camera `repeats` times (plus one untimed warm-up pass that also gives the
    strokes). Returns the mean ms per frame of each repeat, and the strokes of each frame."""
    out = []
    for k, cam in enumerate(cameras):
        s = renderer.render(cam, k + 1)
        frame_bytes(s, cam, k + 1, renderer.options.kinds)
        out.append(s)
    ms = []
    for _ in range(repeats):  # 0: strokes only, no timing
        t0 = time.perf_counter()
        for k, cam in enumerate(cameras):
            frame_bytes(renderer.render(cam, k + 1), cam, k + 1, renderer.options.kinds)
        ms.append(1000.0 * (time.perf_counter() - t0) / len(cameras))
    return ms, out


def bench_configs(sweep: tuple[float, ...] = DEFAULT_SWEEP, presets=tuple(QUALITY_PRESETS)) -> list[BenchRow]:
    """The rows to measure: each preset, then the main knob swept on the default preset."""
    rows = [BenchRow("quality", q, LineOptions.preset(q)) for q in presets]
    rows += [BenchRow(MAIN_KNOB, f"{v:g}", LineOptions.preset("default", **{MAIN_KNOB: v})) for v in sweep]
    return rows


def run_bench(scene: Scene, cameras: list[Camera], *, repeats: int = 3, tols=DEFAULT_TOLS,
              sweep: tuple[float, ...] = DEFAULT_SWEEP, presets=tuple(QUALITY_PRESETS),
              log=None) -> dict:
    """Measure every row of `bench_configs` on the scene and cameras. Returns
    {'scene', 'frames', 'width', 'height', 'repeats', 'rows': [BenchRow], 'raster': [...]}.
    `log(str)` receives progress lines."""
    if not cameras:
        raise ValueError("bench needs at least one camera")
    rows = bench_configs(tuple(sweep), tuple(presets))
    check = LineRenderer(scene, LineOptions.preset(REFERENCE))
    for k, cam in enumerate(cameras):
        check.check_camera(cam, k + 1)  # eye inside the mesh: one clear error before any timing
    # The reference first: every other row is measured against its strokes.
    is_ref = [r.curve == "quality" and r.label == REFERENCE for r in rows]
    ref_strokes = None
    if not any(is_ref):
        _, ref_strokes = time_lines(check, cameras, 0)
    for i in sorted(range(len(rows)), key=lambda i: not is_ref[i]):
        row = rows[i]
        row.ms_repeats, strokes = time_lines(LineRenderer(scene, row.options), cameras, repeats)
        row.ms_per_frame = float(np.median(row.ms_repeats))
        row.strokes_per_frame = float(np.mean([len(s) for s in strokes]))
        if is_ref[i]:
            ref_strokes = strokes
        row.accuracy = accuracy(strokes, ref_strokes, tols)
        if log:
            log(f"{row.curve} {row.label}: {row.ms_per_frame:.1f} ms/frame")
    cam0 = cameras[0]
    return {"scene": scene.source, "faces": int(len(scene.faces)), "frames": len(cameras), "width": cam0.width,
            "height": cam0.height, "repeats": repeats, "tols": tuple(tols), "rows": rows,
            "raster": raster_rows(scene, cameras)}


def raster_rows(scene: Scene, cameras: list[Camera]) -> list[dict]:
    """RASTER SECTION (issue 6): IoU of the raster pass at supersample K = 1, 2, 4 against K = 4,
    with ms per frame. The raster pass has not landed yet; when it does, return one dict per K
    here: {'supersample': K, 'ms_per_frame': ..., 'iou': ...}. format_table and plot_bench
    already print and draw whatever this returns."""
    return []


def default_cameras(scene: Scene, frames: int = 8, width: int = 1024, height: int = 1024) -> list[Camera]:
    """The bench's default camera path: an orbit of `frames` frames around the scene."""
    return list(orbit_path(scene.center, scene.radius, frames, width=width, height=height).cameras)


def format_table(result: dict) -> str:
    """The bench table as text: one line per row."""
    tols = result["tols"]
    head = f"{'knob':<18} {'value':>7} {'ms/frame':>9} {'strokes':>8} " + " ".join(
        f"{'P@' + format(t, 'g'):>8} {'R@' + format(t, 'g'):>8}" for t in tols)
    lines = [f"scene {result['scene']} ({result['faces']} faces), {result['frames']} frames at "
             f"{result['width']}x{result['height']}, median of {result['repeats']} repeats, accuracy against "
             f"'{REFERENCE}'", head, "-" * len(head)]
    for r in result["rows"]:
        acc = r.accuracy
        cells = " ".join(f"{acc.precision[t]:>8.5f} {acc.recall[t]:>8.5f}" for t in tols) if acc else ""
        lines.append(f"{r.curve:<18} {r.label:>7} {r.ms_per_frame:>9.1f} {r.strokes_per_frame:>8.1f} {cells}")
    if result.get("raster"):
        lines.append("")
        lines.append(f"{'raster supersample':<18} {'ms/frame':>9} {'IoU vs 4':>9}")
        for r in result["raster"]:
            lines.append(f"{r['supersample']:<18} {r['ms_per_frame']:>9.1f} {r['iou']:>9.5f}")
    return "\n".join(lines)


def result_json(result: dict) -> dict:
    out = dict(result)
    out["tols"] = list(result["tols"])
    out["rows"] = [r.to_json() for r in result["rows"]]
    return out


def plot_bench(result: dict, path, tol: float = 1.0) -> None:
    """Accuracy against time, one curve per knob: min(precision, recall) at `tol` px (left) and
    at the smallest tol (right) against ms per frame (log scale)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .fileio import atomic_write_bytes
    import io

    tols = result["tols"]
    panels = [tol] + [t for t in tols if t != tol][:1]
    fig, axes = plt.subplots(1, len(panels), figsize=(6 * len(panels), 4.5), squeeze=False)
    curves: dict[str, list[BenchRow]] = {}
    for r in result["rows"]:
        curves.setdefault(r.curve, []).append(r)
    for ax, t in zip(axes[0], panels):
        for name, rows in curves.items():
            rows = sorted(rows, key=lambda r: r.ms_per_frame)
            x = [r.ms_per_frame for r in rows]
            y = [min(r.accuracy.precision[t], r.accuracy.recall[t]) for r in rows]
            ax.plot(x, y, "o-", label=name)
            for xi, yi, r in zip(x, y, rows):
                ax.annotate(r.label, (xi, yi), textcoords="offset points", xytext=(4, 4), fontsize=8)
        for r in result.get("raster") or []:
            ax.plot([r["ms_per_frame"]], [r["iou"]], "s", label=f"raster K={r['supersample']} (IoU)")
        ax.set_xscale("log")
        ax.set_xlabel("ms per frame (lines + SVG + JSON)")
        ax.set_ylabel(f"min(precision, recall) at {t:g} px vs {REFERENCE}")
        ax.set_title(f"{result['scene'].split('/')[-1]}: accuracy at {t:g} px against time")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    atomic_write_bytes(path, buf.getvalue())
