"""Whole strokes: M8 (path ends per 1000 px against the same frames drawn afresh, BRIEF 3) and
the `strokekit coherence --fresh` report of it."""

from __future__ import annotations

import json

import numpy as np
import pytest
from helpers import run_cli

from strokekit.camera.view import Camera
from strokekit.errors import InputError
from strokekit.metrics.coherence import LOOP_PX, ends_per_kpx, stroke_ends, wholeness
from strokekit.model import KIND_INDEX, Strokes
from strokekit.writers.strokes_json import strokes_json

SIZE = 512


def _camera(x: float = 0.0) -> Camera:
    return Camera(eye=(x, 0, 10), target=(x, 0, 0), width=SIZE, height=SIZE)


def _strokes(polylines, frame=1, cam=None) -> Strokes:
    """Strokes through the pixel polylines given (their surface points on the plane z = 0)."""
    cam = cam or _camera()
    pts = [np.asarray(p, float) for p in polylines]
    offs = np.r_[0, np.cumsum([len(p) for p in pts])]
    P = np.concatenate(pts) if pts else np.zeros((0, 2))
    X = np.c_[(P - SIZE / 2) * [1, -1] / cam.focal_px * 10, np.zeros(len(P))]
    return Strokes.build(P, X, np.zeros(len(P)), offs, [KIND_INDEX["silhouette"]] * len(pts), camera=cam,
                         frame=frame)


def _circle(n=64, r=100.0, gap=0.0):
    """A circle of radius r px through n points, its last point `gap` px short of its first."""
    a = np.linspace(0, 2 * np.pi - gap / r, n)
    return np.c_[256 + r * np.cos(a), 256 + r * np.sin(a)]


def _pieces(k: int, y: float = 200.0):
    """A 300 px line cut into k pieces that meet end to end."""
    x = np.linspace(100, 400, k + 1)
    return [np.c_[np.linspace(x[i], x[i + 1], 20), np.full(20, y)] for i in range(k)]


def test_a_loop_has_no_ends_and_an_open_stroke_two():
    st = _strokes([_circle(), _circle(gap=0.9 * LOOP_PX), _circle(gap=3 * LOOP_PX), _pieces(1)[0]])
    assert stroke_ends(st).tolist() == [0, 0, 2, 2]
    # 4 ends over the length drawn
    assert ends_per_kpx(st) == pytest.approx(4000.0 / st.lengths.sum())
    assert np.isnan(ends_per_kpx(_strokes([])))


def test_ratio_is_the_late_half_median_against_the_same_frames_drawn_afresh():
    """Six frames: the tracked line crumbles into 1, 1, 1, 2, 3, 3 pieces, the fresh one is whole:
    over the late half (frames 4-6) the ratio is the median of 2, 3, 3."""
    tracked = [_strokes(_pieces(k), frame=f + 1) for f, k in enumerate([1, 1, 1, 2, 3, 3])]
    fresh = [_strokes(_pieces(1), frame=f + 1) for f in range(6)]
    rows, m8 = wholeness(tracked, fresh)
    assert [r.ratio for r in rows] == pytest.approx([1, 1, 1, 2, 3, 3])
    assert m8["M8_ratio"] == pytest.approx(3.0) and m8["M8_frames"] == 3 and m8["M8_late_first"] == 4
    assert m8["M8"] == pytest.approx(3 * 2000 / 300, rel=1e-9) and m8["M8_fresh"] == pytest.approx(2000 / 300)
    # Loops only, in both: as whole as fresh.
    loops = [_strokes([_circle()], frame=f + 1) for f in range(2)]
    assert wholeness(loops, loops)[1]["M8_ratio"] == 1.0


def test_fresh_frames_of_another_view_are_refused():
    tracked = [_strokes(_pieces(1), frame=f + 1) for f in range(2)]
    moved = [_strokes(_pieces(1), frame=f + 1, cam=_camera(0.5)) for f in range(2)]
    with pytest.raises(InputError, match="another camera"):
        wholeness(tracked, moved)


def _write(folder, frames):
    folder.mkdir()
    for f in frames:
        (folder / f"frame_{f.frame:04d}.json").write_bytes(strokes_json(f, SIZE, SIZE, f.frame))


def test_coherence_reports_m8_against_a_fresh_folder(tmp_path, capsys):
    _write(tmp_path / "tracked", [_strokes(_pieces(k), frame=f + 1) for f, k in enumerate([1, 2, 4, 4])])
    _write(tmp_path / "fresh", [_strokes(_pieces(k), frame=f + 1) for f, k in enumerate([1, 1, 2, 2])])
    code, out, err = run_cli(["coherence", tmp_path / "tracked", "--fresh", tmp_path / "fresh", "--json"], capsys)
    assert code == 0, err
    doc = json.loads(out)
    assert doc["overall"]["M8_ratio"] == pytest.approx(2.0) and doc["overall"]["M8_frames"] == 2
    assert [p["M8_ratio"] for p in doc["pairs"]] == pytest.approx([2.0, 2.0, 2.0])
    code, out, err = run_cli(["coherence", tmp_path / "tracked", "--fresh", tmp_path / "fresh"], capsys)
    assert code == 0 and "2.00 x fresh" in out, err
    # Without --fresh: the ends alone.
    code, out, err = run_cli(["coherence", tmp_path / "tracked", "--json"], capsys)
    assert code == 0 and json.loads(out)["overall"]["M8"] == pytest.approx(8000 / 300) and "M8_fresh" not in out


def test_coherence_refuses_fresh_lines_against_brush_paths(tmp_path, capsys):
    """M8 compares the strokes of a folder with the same strokes drawn afresh: fresh lines (what
    --no-coherence alone renders) against brush paths are an input error that says how to render
    them, not a ratio of unlike things."""
    _write(tmp_path / "tracked", [_strokes(_pieces(2), frame=f + 1) for f in range(4)])
    for f in (tmp_path / "tracked").glob("*.json"):  # (brush paths: each stroke lists its covers)
        doc = json.loads(f.read_text())
        for st in doc["strokes"]:
            st["covers"] = []
        f.write_text(json.dumps(doc))
    _write(tmp_path / "lines", [_strokes(_pieces(1), frame=f + 1) for f in range(4)])
    code, _, err = run_cli(["coherence", tmp_path / "tracked", "--fresh", tmp_path / "lines"], capsys)
    assert code == 1 and len(err.strip().splitlines()) == 1
    assert "holds lines" in err and "--no-coherence --strokes brush" in err and str(tmp_path / "lines") in err
    code, _, err = run_cli(["coherence", tmp_path / "lines", "--fresh", tmp_path / "tracked"], capsys)
    assert code == 1 and "holds brush paths" in err


def test_coherence_fresh_folder_missing_frames_is_said(tmp_path, capsys):
    _write(tmp_path / "tracked", [_strokes(_pieces(2), frame=f + 1) for f in range(4)])
    _write(tmp_path / "part", [_strokes(_pieces(1), frame=4)])
    _write(tmp_path / "early", [_strokes(_pieces(1), frame=1)])
    code, out, err = run_cli(["coherence", tmp_path / "tracked", "--fresh", tmp_path / "part", "--json"], capsys)
    assert code == 0 and "1 of the frames 3-4 are not in" in err
    assert json.loads(out)["overall"]["M8_ratio"] == pytest.approx(2.0)
    code, _, err = run_cli(["coherence", tmp_path / "tracked", "--fresh", tmp_path / "early"], capsys)
    assert code == 1 and "holds none of the frames 3-4" in err and len(err.strip().splitlines()) == 1
    code, _, err = run_cli(["coherence", tmp_path / "tracked", "--fresh", tmp_path / "nowhere"], capsys)
    assert code == 1 and "nowhere" in err and len(err.strip().splitlines()) == 1
