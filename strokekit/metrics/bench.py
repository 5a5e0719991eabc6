"""What accuracy costs in time: every --quality preset and a sweep of the main knob,
timed per frame and measured against the `exact` preset (BRIEF 2).

Time per frame is what a render spends on lines after loading: LineRenderer.render(camera) then
the SVG and JSON bytes of the frame (strokekit.writers), the median over repeats of the mean per
frame. Accuracy is precision/recall of visible line length at several tolerances (px) against the
exact preset's strokes of the same cameras (strokekit.metrics.accuracy).
"""

from __future__ import annotations

import copy
import io
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from strokekit.camera.paths import orbit_path
from strokekit.camera.view import Camera
from strokekit.extras import need
from strokekit.fileio import atomic_write_bytes
from strokekit.lines.features import static_features
from strokekit.lines.renderer import LineRenderer
from strokekit.metrics.accuracy import DEFAULT_TOLS, Accuracy, accuracy
from strokekit.model import Strokes
from strokekit.options import QUALITY_PRESETS, LineOptions
from strokekit.raster.bands import render_raster
from strokekit.raster.hits import thread_workspace, warm_kernels
from strokekit.raster.options import RasterOptions
from strokekit.scene.load import Scene
from strokekit.scene.occluder import Occluder
from strokekit.writers.png import png_files
from strokekit.writers.strokes_json import strokes_json
from strokekit.writers.svg import svg_document

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
    cpu_ms_per_frame: float = float("nan")
    strokes_per_frame: float = 0.0
    accuracy: Accuracy | None = None

    def to_json(self) -> dict:
        return {"curve": self.curve, "label": self.label, "ms_per_frame": self.ms_per_frame,
                "cpu_ms_per_frame": self.cpu_ms_per_frame,
                "ms_repeats": self.ms_repeats, "strokes_per_frame": self.strokes_per_frame,
                "accuracy": self.accuracy.to_json() if self.accuracy else None,
                "knobs": {k: getattr(self.options, k) for k in QUALITY_PRESETS["default"] if hasattr(self.options, k)}}


def frame_bytes(strokes: Strokes, camera: Camera, frame: int, kinds: tuple[str, ...]) -> tuple[bytes, bytes]:
    """The SVG and JSON bytes of one frame, as `strokekit render` writes them."""

    svg = svg_document(strokes, camera.width, camera.height, kinds).encode("utf-8")
    return svg, strokes_json(strokes, camera.width, camera.height, frame)


def time_lines(renderer: LineRenderer, cameras: list[Camera], repeats: int = 3,
               cpu_out: list | None = None, warm: bool = True) -> tuple[list[float], list[Strokes]]:
    """Render every camera `repeats` times, after one untimed warm-up pass that also gives the
    strokes (skipped when `warm` is False: then no strokes are returned). Returns the mean
    wall-clock ms per frame of each repeat and the strokes of each frame; `cpu_out`, if given,
    receives the process CPU ms per frame of each repeat (steadier than wall clock on a shared
    machine; counts every thread Embree uses)."""
    out = []
    for k, cam in enumerate(cameras if warm else ()):
        s = renderer.render(cam, k + 1)
        frame_bytes(s, cam, k + 1, renderer.options.kinds)
        out.append(s)
    ms, cpu = [], []
    for _ in range(repeats):  # 0: strokes only, no timing
        t0, c0 = time.perf_counter(), time.process_time()
        for k, cam in enumerate(cameras):
            frame_bytes(renderer.render(cam, k + 1), cam, k + 1, renderer.options.kinds)
        ms.append(1000.0 * (time.perf_counter() - t0) / len(cameras))
        cpu.append(1000.0 * (time.process_time() - c0) / len(cameras))
    if cpu_out is not None:
        cpu_out.extend(cpu)
    return ms, out


def bench_configs(sweep: tuple[float, ...] = DEFAULT_SWEEP, presets=tuple(QUALITY_PRESETS)) -> list[BenchRow]:
    """The rows to measure: each preset, then the main knob swept on the default preset."""
    rows = [BenchRow("quality", q, LineOptions.preset(q)) for q in presets]
    rows += [BenchRow(MAIN_KNOB, f"{v:g}", LineOptions.preset("default", **{MAIN_KNOB: v})) for v in sweep]
    return rows


def _renderer_with(base: LineRenderer, options: LineOptions) -> LineRenderer:
    """A renderer for `options` sharing `base`'s occluder (one BVH for every bench row: the rows
    differ only in accuracy knobs, never in the scene)."""
    r = copy.copy(base)
    r.options = options
    r.static = static_features(base.scene, options)
    return r


def run_bench(scene: Scene, cameras: list[Camera], *, repeats: int = 3, tols=DEFAULT_TOLS,
              sweep: tuple[float, ...] = DEFAULT_SWEEP, presets=tuple(QUALITY_PRESETS),
              raster_frames: int = 2, log=None) -> dict:
    """Measure every row of `bench_configs` on the scene and cameras, and the raster pass on the
    first `raster_frames` cameras (0: skip; supersample 4 costs seconds per frame). Returns
    {'scene', 'frames', 'width', 'height', 'repeats', 'rows': [BenchRow], 'raster': [dict]}.
    `log(str)` receives progress lines."""
    if not cameras:
        raise ValueError("bench needs at least one camera")
    rows = bench_configs(tuple(sweep), tuple(presets))
    check = LineRenderer(scene, LineOptions.preset(REFERENCE))
    for k, cam in enumerate(cameras):
        check.check_camera(cam, k + 1)  # eye inside the mesh: one clear error before any timing
    # Warm-up pass per row (gives the strokes), reference first: every row is measured against it.
    is_ref = [r.curve == "quality" and r.label == REFERENCE for r in rows]
    ref_strokes = None
    if not any(is_ref):
        _, ref_strokes = time_lines(check, cameras, 0)
    renderers = [_renderer_with(check, r.options) for r in rows]
    for i in sorted(range(len(rows)), key=lambda i: not is_ref[i]):
        _, strokes = time_lines(renderers[i], cameras, 0)
        if is_ref[i]:
            ref_strokes = strokes
        rows[i].strokes_per_frame = float(np.mean([len(s) for s in strokes]))
        rows[i].accuracy = accuracy(strokes, ref_strokes, tols)
    # Timed passes round-robin over the rows, so that the load of a shared machine falls on every
    # row alike instead of on whichever row ran during a busy minute.
    cpu: list[list[float]] = [[] for _ in rows]
    for _ in range(repeats):
        for i, row in enumerate(rows):
            ms, _ = time_lines(renderers[i], cameras, 1, cpu[i], warm=False)
            row.ms_repeats += ms
    for i, row in enumerate(rows):
        row.ms_per_frame = float(np.median(row.ms_repeats)) if row.ms_repeats else float("nan")
        row.cpu_ms_per_frame = float(np.median(cpu[i])) if cpu[i] else float("nan")
        if log:
            log(f"{row.curve} {row.label}: {row.ms_per_frame:.1f} ms/frame")
    cam0 = cameras[0]
    return {"scene": scene.source, "faces": int(len(scene.faces)), "frames": len(cameras), "width": cam0.width,
            "height": cam0.height, "repeats": repeats, "tols": tuple(tols), "rows": rows,
            "raster": raster_rows(scene, cameras[:raster_frames], occluder=check.occluder, repeats=1, log=log)
            if raster_frames > 0 else []}


def raster_rows(scene: Scene, cameras: list[Camera], *, occluder=None, repeats: int = 1,
                supersamples: tuple = (1, 2, "default", 4, "rays default"), reference: int = 4, log=None) -> list[dict]:
    """The raster pass (strokekit.raster.render_raster with default RasterOptions: 3 bands, the
    shade image, plus their PNG bytes) drawn by the z-buffer at supersample K = 1, 2, 4 and at the
    setup `strokekit render` uses by default ("default": K = 1, the pixels at band, material or
    object edges resampled R x R, R = 4, see options.QUALITY_PRESETS), and the same default cast
    with Embree rays ("rays default": the path the z-buffer replaced): ms per frame (median over
    repeats of the mean per frame) and IoU of the band coverages against the ray-cast reference
    at uniform K = `reference`. Each row: 'supersample' K, 'edge_supersample' R (0 = off), 'label'
    ('1+4' for K with R), 'sampler' ('zbuffer' or 'rays'), 'ms_per_frame', 'ms_repeats', 'iou'
    (pooled over the bands), 'iou_min' (the worst band of any frame), 'reference', 'frames'.

    IoU is the soft IoU, background excluded: sum of min(coverage, coverage_ref) over sum of max,
    per output pixel and band. The reference's cost grows with K^2: pass few cameras."""
    if not cameras:
        return []
    if occluder is None:
        occluder = Occluder(scene)
    warm_kernels()  # compiled or loaded before any timing
    work = thread_workspace()  # buffers reused frame after frame, as the run's frame tasks do
    render_raster(scene, cameras[0], occluder, RasterOptions(), work=work)  # per-scene tables, untimed
    ref_cov = []
    for cam in cameras:
        ref_cov.append(render_raster(scene, cam, occluder, RasterOptions(supersample=reference, edge_supersample=0),
                                     reference=True).coverage[..., 1:])
    preset = QUALITY_PRESETS["default"]
    configs = []
    for entry in supersamples:
        rays = isinstance(entry, str) and entry.startswith("rays")
        if isinstance(entry, str) and entry.endswith("default"):
            K, R = preset["supersample"], preset["edge_supersample"]
        else:
            K, R = int(entry), 0
        configs.append((K, R, rays))
    stats = [{"inter": 0.0, "union": 0.0, "min": 1.0, "ms": []} for _ in configs]
    # Round-robin over the rows, so the load of a shared machine falls on every row alike.
    for rep in range(max(1, repeats)):
        for (K, R, rays), st in zip(configs, stats):
            opts = RasterOptions(supersample=K, edge_supersample=R)
            spent = 0.0
            for cam, ref in zip(cameras, ref_cov):
                t0 = time.perf_counter()
                frame = render_raster(scene, cam, occluder, opts, reference=rays, work=work)
                png_files(frame.images())
                spent += time.perf_counter() - t0
                if rep == 0:  # (untimed)
                    cov = frame.coverage[..., 1:]
                    st["inter"] += float(np.minimum(cov, ref).sum())
                    st["union"] += float(np.maximum(cov, ref).sum())
                    for b in range(cov.shape[2]):
                        u = float(np.maximum(cov[..., b], ref[..., b]).sum())
                        if u > 0:
                            st["min"] = min(st["min"], float(np.minimum(cov[..., b], ref[..., b]).sum()) / u)
            st["ms"].append(1000.0 * spent / len(cameras))
    rows = []
    for (K, R, rays), st in zip(configs, stats):
        row = {"supersample": K, "edge_supersample": R, "label": f"{K}+{R}" if R else f"{K}",
               "sampler": "rays" if rays else "zbuffer", "ms_per_frame": float(np.median(st["ms"])),
               "ms_repeats": st["ms"], "iou": st["inter"] / st["union"] if st["union"] > 0 else 1.0,
               "iou_min": st["min"], "reference": reference, "frames": len(cameras)}
        rows.append(row)
        if log:
            log(f"raster {row['sampler']} K={row['label']}: {row['ms_per_frame']:.1f} ms/frame, IoU {row['iou']:.5f}")
    return rows


def default_cameras(scene: Scene, frames: int = 8, width: int = 1024, height: int = 1024) -> list[Camera]:
    """The bench's default camera path: an orbit of `frames` frames around the scene."""
    return list(orbit_path(scene.center, scene.radius, frames, width=width, height=height).cameras)


def format_table(result: dict) -> str:
    """The bench table as text: one line per row."""
    tols = result["tols"]
    head = f"{'knob':<18} {'value':>7} {'ms/frame':>9} {'cpu ms':>7} {'strokes':>8} " + " ".join(
        f"{'P@' + format(t, 'g'):>8} {'R@' + format(t, 'g'):>8}" for t in tols)
    lines = [f"scene {result['scene']} ({result['faces']} faces), {result['frames']} frames at "
             f"{result['width']}x{result['height']}, median of {result['repeats']} repeats (ms/frame: wall clock, "
             f"lines + SVG + JSON; cpu ms: process CPU time), accuracy against '{REFERENCE}'", head, "-" * len(head)]
    for r in result["rows"]:
        acc = r.accuracy
        cells = " ".join(f"{acc.precision[t]:>8.5f} {acc.recall[t]:>8.5f}" for t in tols) if acc else ""
        lines.append(f"{r.curve:<18} {r.label:>7} {r.ms_per_frame:>9.1f} {r.cpu_ms_per_frame:>7.1f} "
                     f"{r.strokes_per_frame:>8.1f} {cells}")
    if result.get("raster"):
        r0 = result["raster"][0]
        lines.append("")
        lines.append(f"raster pass (bands + shade, PNG bytes), {r0['frames']} frame(s), IoU of band coverage "
                     f"against Embree rays at supersample {r0['reference']} (pooled, and the worst band)")
        lines.append(f"{'supersample K(+R)':<18} {'sampler':>8} {'ms/frame':>9} {'IoU':>10} {'worst band':>10}")
        for r in result["raster"]:
            note = "  (render's default: K, edge pixels resampled R x R)" if r["edge_supersample"] else ""
            lines.append(f"{r['label']:<18} {r.get('sampler', 'rays'):>8} {r['ms_per_frame']:>9.1f} "
                         f"{r['iou']:>10.7f} {r.get('iou_min', float('nan')):>10.7f}{note}")
    return "\n".join(lines)


def result_json(result: dict) -> dict:
    out = dict(result)
    out["tols"] = list(result["tols"])
    out["rows"] = [r.to_json() for r in result["rows"]]
    return out


def plot_bench(result: dict, path, tol: float = 1.0) -> None:
    """Write bench_figure(result, tol) to `path` as a PNG (atomic)."""
    need("matplotlib", "the benchmark's plot")
    import matplotlib.pyplot as plt

    fig = bench_figure(result, tol)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    atomic_write_bytes(path, buf.getvalue())


def bench_figure(result: dict, tol: float = 1.0):
    """Accuracy against time, one curve per knob: the error 1 - min(precision, recall) at `tol`
    px (left) and at the next tol (right), log scale, against ms per frame (log scale); the
    raster pass beside them. Points are labelled with their preset or knob value; labels never
    overlap each other, the markers or the legend (points at the same place share one label,
    e.g. '8, 16'). Returns the matplotlib figure (Agg)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    tols = result["tols"]
    panels = [tol] + [t for t in tols if t != tol][:1]
    raster = result.get("raster") or []
    fig, axes = plt.subplots(1, len(panels) + bool(raster), figsize=(6 * (len(panels) + bool(raster)), 4.5),
                             squeeze=False)
    curves: dict[str, list[BenchRow]] = {}
    for r in result["rows"]:
        curves.setdefault(r.curve, []).append(r)
    floor = 1e-6  # log axis: perfect rows are drawn at this error
    labels: list[tuple] = []  # (axes, [(x, y, text, colour)])
    for ax, t in zip(axes[0], panels):
        points = []
        for name, rows in curves.items():
            # Along the knob: presets in their order, sweeps by value.
            if name != "quality":
                rows = sorted(rows, key=lambda r: float(r.label))
            x = [r.ms_per_frame for r in rows]
            y = [max(floor, 1.0 - min(r.accuracy.precision[t], r.accuracy.recall[t])) for r in rows]
            (line,) = ax.plot(x, y, "o-", label="--quality preset" if name == "quality"
                              else f"{name}: value in px (default preset otherwise)")
            points += [(xi, yi, r.label, line.get_color()) for xi, yi, r in zip(x, y, rows)]
        labels.append((ax, points))
        ax.axhline(1e-3, color="grey", ls="--", lw=1, label="bar: 0.999")
        _log_axes(ax, floor)
        ax.set_xlabel("ms per frame (lines + SVG + JSON, median)")
        ax.set_ylabel(f"1 - min(precision, recall) at {t:g} px vs {REFERENCE}  (lower is better)")
        ax.set_title(f"{Path(result['scene']).name}: error at {t:g} px against time")
        ax.legend(fontsize=8, loc="upper right")
    if raster:
        ax = axes[0][-1]
        points = []
        for sampler, colour, name in (("zbuffer", "C2", "z-buffer, supersample K"), ("rays", "C3", "Embree rays")):
            rs = [r for r in raster if r.get("sampler", "rays") == sampler]
            if not rs:
                continue
            x = [r["ms_per_frame"] for r in rs]
            y = [max(floor, 1.0 - r["iou"]) for r in rs]
            (line,) = ax.plot(x, y, "s-" if len(rs) > 1 else "s", color=colour, label=name)
            points += [(xi, yi, f"K={r['label']}", line.get_color()) for xi, yi, r in zip(x, y, rs)]
        labels.append((ax, points))
        _log_axes(ax, floor)
        ax.set_xlabel("ms per frame (raster pass + PNG, median)")
        ax.set_ylabel(f"1 - IoU of band coverage vs K={raster[0]['reference']}  (lower is better)")
        ax.set_title("raster pass: error against time")
        ax.legend(fontsize=8, loc="upper right")
    fig.tight_layout()
    for ax, points in labels:
        _label_points(ax, points)
    return fig


def _log_axes(ax, floor: float) -> None:
    """Log-log axes whose time ticks read as plain numbers (10, 20, 50, 100), not 2x10^1."""
    from matplotlib.ticker import FuncFormatter, LogLocator

    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_ylim(floor * 0.5, 1.0)
    ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    ax.xaxis.set_minor_locator(LogLocator(subs=(2.0, 5.0)))
    ax.xaxis.set_minor_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    ax.xaxis.set_tick_params(which="minor", labelsize=8)
    ax.grid(True, which="both", alpha=0.3)


def _label_points(ax, points: list[tuple], merge_px: float = 6.0) -> list:
    """Label each (x, y, text, colour) point of `ax` beside its marker, where the label covers no
    other label, no marker and not the legend: the first free place of a few around the point.
    Points closer than `merge_px` on screen (the same measure twice, e.g. two sweep values that
    cost the same) share one label 'a, b'. Returns the annotations."""
    fig = ax.figure
    renderer = fig.canvas.get_renderer()
    to_px = ax.transData.transform
    groups: list[list] = []  # points that fall on one spot: [px, py, texts, colour]
    for x, y, text, colour in points:
        px, py = to_px((x, y))
        for g in groups:
            if abs(g[0] - px) <= merge_px and abs(g[1] - py) <= merge_px:
                g[2].append(text)
                break
        else:
            groups.append([px, py, [text], colour])
    marker_r = 5.0  # px around a marker kept free
    obstacles = [(g[0] - marker_r, g[1] - marker_r, g[0] + marker_r, g[1] + marker_r) for g in groups]
    legend = ax.get_legend()
    if legend is not None:
        b = legend.get_window_extent(renderer)
        obstacles.append((b.x0, b.y0, b.x1, b.y1))
    frame = ax.get_window_extent(renderer)
    # (dx, dy) in points, horizontal and vertical alignment: beside, above, below, further out.
    places = [(5, 4, "left", "bottom"), (5, -4, "left", "top"), (-5, 4, "right", "bottom"),
              (-5, -4, "right", "top"), (0, 8, "center", "bottom"), (0, -8, "center", "top"),
              (12, 14, "left", "bottom"), (12, -14, "left", "top"), (-12, 14, "right", "bottom"),
              (-12, -14, "right", "top")]

    def free(b) -> bool:
        inside = b.x0 >= frame.x0 and b.x1 <= frame.x1 and b.y0 >= frame.y0 and b.y1 <= frame.y1
        return inside and not any(b.x0 < o[2] and b.x1 > o[0] and b.y0 < o[3] and b.y1 > o[1] for o in obstacles)

    label_box = dict(boxstyle="square,pad=0.1", fc="white", ec="none", alpha=0.75)  # readable over lines
    out = []
    for px, py, texts, colour in groups:
        xy = ax.transData.inverted().transform((px, py))
        best = None
        for dx, dy, ha, va in places:
            a = ax.annotate(", ".join(texts), xy, textcoords="offset points", xytext=(dx, dy), ha=ha, va=va,
                            fontsize=8, color=colour, bbox=label_box)
            b = a.get_window_extent(renderer)
            if free(b):
                best = (a, b)
                break
            a.remove()
        if best is None:  # nowhere free: the first place, as before
            dx, dy, ha, va = places[0]
            a = ax.annotate(", ".join(texts), xy, textcoords="offset points", xytext=(dx, dy), ha=ha, va=va,
                            fontsize=8, color=colour, bbox=label_box)
            best = (a, a.get_window_extent(renderer))
        b = best[1]
        obstacles.append((b.x0, b.y0, b.x1, b.y1))
        out.append(best[0])
    return out
