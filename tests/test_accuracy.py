"""Accuracy (BRIEF 2): the metric itself, and the issue-2 bar: the `default` preset keeps precision
and recall >= 0.999 at 1 px against `exact`, 8-frame orbit at 1024 x 1024."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from strokekit import LineOptions, LineRenderer, Strokes, load_scene, orbit_path
from strokekit.metrics.accuracy import accuracy, frame_accuracy
from strokekit.sampling import segment_samples

MODELS = Path(__file__).resolve().parents[1].parent / "shared" / "models"


def polyline_strokes(*lines) -> Strokes:
    pts = np.concatenate([np.asarray(l, float) for l in lines])
    offsets = np.r_[0, np.cumsum([len(l) for l in lines])]
    return Strokes.build(pts, np.zeros((len(pts), 3)), np.full(len(pts), -1), offsets, np.zeros(len(lines)))


def test_piece_middles_weigh_the_drawn_length():
    """The middles of pieces of at most the step, each weighing its piece's length."""
    s = polyline_strokes([[0, 0], [10, 0], [10, 7.3]], [[50, 50], [50.05, 50]])
    mid, _, w = segment_samples(s.points, s.offsets, 0.1, middles=True)
    assert w.sum() == pytest.approx(17.3 + 0.05)
    assert w.max() <= 0.1 + 1e-12
    assert np.all((mid[:, 0] >= 0) & (mid[:, 0] <= 50.05))


def test_identical_drawings_are_perfect():
    s = polyline_strokes([[0, 0], [100, 0], [100, 100]])
    fa = frame_accuracy(s, s)
    assert fa.precision == {0.5: 1.0, 1.0: 1.0, 2.0: 1.0}
    assert fa.recall == {0.5: 1.0, 1.0: 1.0, 2.0: 1.0}


def test_offset_line_counts_only_within_tolerance():
    # A line drawn 0.7 px beside the reference is wrong at 0.5 px and right at 1 px. The 0.7 px
    # shift also overhangs the reference's ends by nothing (horizontal shift is vertical here).
    ref = polyline_strokes([[0, 0], [200, 0]])
    drawn = polyline_strokes([[0, 0.7], [200, 0.7]])
    fa = frame_accuracy(drawn, ref, tols=(0.5, 1.0))
    assert fa.precision[0.5] == 0.0 and fa.recall[0.5] == 0.0
    assert fa.precision[1.0] == 1.0 and fa.recall[1.0] == 1.0


def test_extra_and_missing_lengths_are_length_weighted():
    ref = polyline_strokes([[0, 0], [300, 0]], [[0, 100], [100, 100]])
    drawn = polyline_strokes([[0, 0], [300, 0]], [[0, 500], [50, 500]])  # misses 100, adds 50
    fa = frame_accuracy(drawn, ref, tols=(1.0,))
    assert fa.precision[1.0] == pytest.approx(300 / 350, abs=1e-3)
    assert fa.recall[1.0] == pytest.approx(300 / 400, abs=1e-3)


def test_aggregate_weights_frames_by_length_and_handles_empty_frames():
    ref = [polyline_strokes([[0, 0], [100, 0]]), polyline_strokes([[0, 0], [300, 0]]), Strokes.empty()]
    drawn = [polyline_strokes([[0, 50], [100, 50]]), polyline_strokes([[0, 0], [300, 0]]), Strokes.empty()]
    a = accuracy(drawn, ref, tols=(1.0,))
    assert a.precision[1.0] == pytest.approx(0.75, abs=1e-3)
    assert a.recall[1.0] == pytest.approx(0.75, abs=1e-3)
    empty_vs_line = frame_accuracy(Strokes.empty(), ref[0], tols=(1.0,))
    assert empty_vs_line.recall[1.0] == 0.0 and empty_vs_line.precision[1.0] == 0.0


def _preset_against_exact(path, quality: str):
    """Accuracy at 1 px of `quality` against `exact` over an 8-frame orbit at 1024 x 1024 (BRIEF 2)."""
    scene = load_scene(path)
    cams = orbit_path(scene.center, scene.radius, 8, width=1024, height=1024).cameras
    exact = LineRenderer(scene, LineOptions.preset("exact"))
    drawn = LineRenderer(scene, LineOptions.preset(quality))
    return accuracy([drawn.render(c, k + 1) for k, c in enumerate(cams)],
                    [exact.render(c, k + 1) for k, c in enumerate(cams)], tols=(1.0,))


@pytest.mark.parametrize("name", ["suzanne.obj", "spot.obj", "fandisk.obj", "teapot.obj", "beetle.obj",
                                  "CesiumMilkTruck.glb"])
def test_default_preset_matches_exact_at_1px(name):
    path = MODELS / name
    if not path.exists():
        pytest.skip(f"shared model {path} not present")
    a = _preset_against_exact(path, "default")
    assert a.ref_length > 1000.0  # the orbit really draws lines
    assert a.precision[1.0] >= 0.999, a.to_json()
    assert a.recall[1.0] >= 0.999, a.to_json()


@pytest.mark.parametrize("name", ["suzanne.obj", "beetle.obj", "CesiumMilkTruck.glb", "wallhole.obj"])
def test_draft_preset_stays_a_useful_preview(name):
    """What the draft preset promises: at least 0.99 precision and recall at 1 px against exact.
    beetle.obj is its worst shared model (recall 0.9948 at 1 px: nearly edge-on lines in concave
    corners that the skipped front-side re-test hides); CesiumMilkTruck and wallhole have parts
    resting on others (the back-side re-test draft keeps)."""
    path = MODELS / name
    if not path.exists():
        pytest.skip(f"shared model {path} not present")
    a = _preset_against_exact(path, "draft")
    assert a.ref_length > 500.0
    assert a.precision[1.0] >= 0.99, a.to_json()
    assert a.recall[1.0] >= 0.99, a.to_json()


def _small_scene():
    import trimesh

    from strokekit import build_scene

    m = trimesh.creation.torus(1.0, 0.35, major_sections=32, minor_sections=16)
    return build_scene(m.vertices, m.faces)


def test_bench_rows_table_json_and_plot(tmp_path):
    import json

    from strokekit.metrics.bench import default_cameras, format_table, plot_bench, result_json, run_bench

    sc = _small_scene()
    cams = default_cameras(sc, 2, 256, 256)
    res = run_bench(sc, cams, repeats=1, sweep=(1.0, 8.0), raster_frames=1)
    labels = [(r.curve, r.label) for r in res["rows"]]
    assert labels == [("quality", "draft"), ("quality", "default"), ("quality", "exact"),
                      ("sample_spacing_px", "1"), ("sample_spacing_px", "8")]
    exact = res["rows"][2]
    # The reference measured against itself is perfect; every row drew strokes and took time.
    assert exact.accuracy.precision[1.0] == 1.0 and exact.accuracy.recall[1.0] == 1.0
    assert all(r.strokes_per_frame > 0 and r.ms_per_frame > 0 for r in res["rows"])
    assert res["rows"][3].options.sample_spacing_px == 1.0
    table = format_table(res)
    assert "exact" in table and "P@0.5" in table and len(table.splitlines()) == 3 + len(res["rows"]) + 3 + len(res["raster"])
    doc = json.loads(json.dumps(result_json(res)))
    assert doc["rows"][1]["knobs"]["sample_spacing_px"] == 4.0
    # Raster section: the z-buffer at supersample 1, 2, 4 and at render's default (1 with the edge
    # pixels resampled 4 x 4), and that default cast with rays, against Embree rays at 4 x 4. The
    # z-buffer at 4 x 4 finds the reference's hits (but for samples within rounding of an edge), a
    # coarser raster is close but not equal on a curved object, and the edge resampling brings
    # K = 1 to the README's figure (>= 0.999; its edge pixels use the reference's 4 x 4 grid).
    iou = {(r["sampler"], r["label"]): r["iou"] for r in doc["raster"]}
    assert list(iou) == [("zbuffer", "1"), ("zbuffer", "2"), ("zbuffer", "1+4"), ("zbuffer", "4"), ("rays", "1+4")]
    assert iou["zbuffer", "4"] > 0.9999 and all(r["iou_min"] <= r["iou"] for r in doc["raster"])
    assert 0.8 < iou["zbuffer", "1"] < 1.0 and 0.8 < iou["zbuffer", "2"] < 0.999
    assert iou["zbuffer", "1+4"] >= 0.999 and iou["rays", "1+4"] >= 0.999
    assert "1+4" in table and "render's default" in table and "zbuffer" in table
    assert "raster pass" in table
    png = tmp_path / "bench.png"
    plot_bench(res, png)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 5000


def test_bench_plot_labels_do_not_overlap():
    """The bunny bench as measured: sweep values 8 and 16 cost the same and miss the same lines
    (one spot on the plot), 4 sits beside 'default' and 2 beside both. Every label must be
    readable: one label '8, 16' for the shared spot, no two labels overlapping, none under the
    legend, and time ticks that do not run into each other."""
    import matplotlib.pyplot as plt

    from strokekit.metrics.accuracy import Accuracy
    from strokekit.metrics.bench import BenchRow, bench_figure
    from strokekit.options import LineOptions

    tols = (0.5, 1.0, 2.0)

    def row(curve, label, ms, err05, err1):
        r = BenchRow(curve, label, LineOptions(), ms)
        r.accuracy = Accuracy(tols, {0.5: 1 - err05, 1.0: 1 - err1, 2.0: 1.0}, {0.5: 1 - err05, 1.0: 1 - err1, 2.0: 1.0},
                              1.0, 1.0, 1)
        return r

    rows = [row("quality", "draft", 9.07, 4.2e-2, 3.2e-3), row("quality", "default", 17.8, 8.4e-4, 6.4e-5),
            row("quality", "exact", 74.3, 0.0, 0.0)]
    rows += [row("sample_spacing_px", v, ms, e05, e1) for v, ms, e05, e1 in
             (("0.5", 32.5, 9.3e-5, 4.7e-5), ("1", 19.6, 9.3e-5, 4.7e-5), ("2", 16.2, 4.8e-4, 6.4e-5),
              ("4", 15.0, 8.4e-4, 6.4e-5), ("8", 14.2, 1.5e-3, 4.1e-4), ("16", 14.1, 1.6e-3, 4.1e-4))]
    raster = [{"supersample": k, "edge_supersample": r, "label": f"{k}+{r}" if r else f"{k}", "ms_per_frame": ms,
               "iou": iou, "reference": 4, "frames": 2}
              for k, r, ms, iou in ((1, 0, 189.0, 0.97910), (2, 0, 520.0, 0.99280), (2, 4, 697.0, 0.9999987),
                                    (4, 0, 2742.0, 1.0))]
    fig = bench_figure({"scene": "bunny.obj", "tols": tols, "rows": rows, "raster": raster})
    try:
        fig.canvas.draw()
        renderer = fig.canvas.get_renderer()

        def overlap(a, b):
            return a.x0 < b.x1 and b.x0 < a.x1 and a.y0 < b.y1 and b.y0 < a.y1

        for ax in fig.axes:
            texts = [t for t in ax.texts if t.get_text()]
            boxes = [t.get_window_extent(renderer) for t in texts]
            legend = ax.get_legend().get_window_extent(renderer)
            for i, a in enumerate(boxes):
                assert not overlap(a, legend), texts[i].get_text()
                for j in range(i):
                    assert not overlap(a, boxes[j]), (texts[i].get_text(), texts[j].get_text())
            ticks = [t.get_window_extent(renderer) for t in ax.get_xticklabels(which="both")
                     if t.get_visible() and t.get_text()]
            ticks = [b for b in ticks if ax.get_window_extent(renderer).x0 - 1 <= b.x0]
            assert all(not overlap(a, b) for i, a in enumerate(ticks) for b in ticks[:i])
        names = sorted(t.get_text() for t in fig.axes[0].texts)
        assert names == sorted(["draft", "default", "exact", "0.5", "1", "2", "4", "8, 16"])
    finally:
        plt.close(fig)


def test_bench_cli_json(tmp_path, capsys):
    import json

    from strokekit_cli.main import main

    sc = _small_scene()
    obj = tmp_path / "torus.obj"
    obj.write_text("".join(f"v {x} {y} {z}\n" for x, y, z in sc.vertices)
                   + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in sc.faces))
    cam = tmp_path / "cam.json"
    cam.write_text(json.dumps({"width": 200, "height": 150, "frames": [
        {"eye": [0, 1, 4], "target": [0, 0, 0]}, {"eye": [4, 1, 0], "target": [0, 0, 0]}]}))
    try:
        main(["bench", str(obj), "--camera", str(cam), "--frames", "1", "--repeats", "1", "--sweep", "4",
              "--raster-frames", "0", "--json"])
    except SystemExit as e:
        assert e.code in (0, None)
    doc = json.loads(capsys.readouterr().out)
    assert doc["frames"] == 1 and doc["width"] == 200 and doc["height"] == 150
    assert [r["label"] for r in doc["rows"]] == ["draft", "default", "exact", "4"]
    assert doc["rows"][2]["accuracy"]["precision"]["1"] == 1.0 and doc["raster"] == []
    # Piped (not a terminal): the table is the whole output, no progress lines on stderr.
    try:
        main(["bench", str(obj), "--camera", str(cam), "--frames", "1", "--repeats", "1", "--sweep", "4",
              "--raster-frames", "0"])
    except SystemExit as e:
        assert e.code in (0, None)
    out = capsys.readouterr()
    assert "P@1" in out.out and out.err == ""


def test_segment_samples_hold_every_point_at_most_a_step_apart():
    """The samples of each polyline run in order along it, at most the step apart, through every
    one of its points (a distance to them is exact to half the step at the vertices too)."""
    s = polyline_strokes([[0, 0.1], [10, 0.1], [10, 7.4]], [[50, 50], [50.05, 50], [50.05, 50]])
    pos, line, w = segment_samples(s.points, s.offsets, 0.4)
    for k in range(2):
        p = pos[line == k]
        assert np.all(np.linalg.norm(np.diff(p, axis=0), axis=1) <= 0.4 + 1e-12)
        assert all((p == q).all(axis=1).any() for q in s.points[s.offsets[k]:s.offsets[k + 1]])
    assert np.all(pos[:, 1][(line == 0) & (pos[:, 0] < 10)] == 0.1)  # exact along the horizontal leg
    assert w.sum() == pytest.approx(17.3 + 0.05)
