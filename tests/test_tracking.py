"""Coherent strokes along a camera path: persistent ids, u that does not slide, self-similar levels,
and the BRIEF 3 metrics that measure them."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from dataclasses import replace
import pytest
import trimesh

from strokekit.camera import Camera, dolly_path, orbit_path
from strokekit.coherence import folder_metrics, pair_metrics, resample_strokes, sequence_metrics
from strokekit.errors import InputError, UsageError
from strokekit.lines import LineRenderer
from strokekit.model import KIND_INDEX, Strokes
from strokekit.options import LineOptions
from strokekit.scene import build_scene, load_scene
from strokekit.tracking import TrackingOptions, cut_pieces, levels_from_slope, track_frames
from strokekit.writers.strokes_json import strokes_json

MODELS = Path(__file__).resolve().parents[2] / "shared" / "models"
SIZE = 512


def _render(scene, path):
    r = LineRenderer(scene, LineOptions())
    return [r.render(c, k + 1) for k, c in enumerate(path.cameras)]


@pytest.fixture(scope="module")
def cube_frames():
    m = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    sc = build_scene(m.vertices, m.faces)
    return _render(sc, orbit_path(sc.center, sc.radius, 12, degrees_per_frame=3, elevation=25,
                                  start_azimuth=20, width=SIZE, height=SIZE))


@pytest.fixture(scope="module")
def sphere_dolly_frames():
    m = trimesh.creation.icosphere(subdivisions=3)
    sc = build_scene(m.vertices, m.faces)
    return _render(sc, dolly_path(sc.center, sc.radius, 24, start=1.0, end=8.0, width=SIZE, height=SIZE))


@pytest.fixture(scope="module")
def torus_frames():
    if (MODELS / "torus.STL").exists():
        sc = load_scene(MODELS / "torus.STL")
    else:  # same shape, generated: a torus around z
        m = trimesh.creation.torus(major_radius=1.0, minor_radius=0.5, major_sections=60, minor_sections=30)
        sc = build_scene(m.vertices, m.faces)
    return _render(sc, orbit_path(sc.center, sc.radius, 24, degrees_per_frame=6, elevation=15, up_axis="z",
                                  width=SIZE, height=SIZE))


# --- metrics ---------------------------------------------------------------------------------

def _line(u0=0.0, ids=(5,), frame=1, x0=100.0):
    cam = Camera(eye=(0, 0, 10), target=(0, 0, 0), width=SIZE, height=SIZE)
    X = np.stack([np.linspace(-1, 1, 41), np.zeros(41), np.zeros(41)], axis=1)
    p, _ = cam.project(X)
    s = Strokes.build(p, X, np.zeros(41), [0, 41], [KIND_INDEX["crease"]], ids=list(ids), camera=cam, frame=frame)
    return s.__class__(**{**s.__dict__, "u": s.u + u0}) if u0 else s


def test_metrics_of_a_still_line_are_perfect_and_sliding_is_measured_in_px():
    a, b = _line(), _line(frame=2)
    m = pair_metrics(a, b)
    assert m.m1 == 1.0 and m.m2 == pytest.approx(0.0, abs=1e-9)
    assert np.max(m.sliding_px) == pytest.approx(0.0, abs=1e-9)
    # Shifting u by 0.1 period slides the texture by 0.1 P = 3 px; 1.1 periods is the same texture.
    for shift in (0.1, 1.1, -0.9):
        m = pair_metrics(a, _line(u0=shift, frame=2))
        assert np.median(m.sliding_px) == pytest.approx(3.0, abs=1e-6)
    m = pair_metrics(a, _line(ids=(6,), frame=2))
    assert m.m1 == 0.0 and m.growth_px.size == 0
    # A line 20 px away has no match: everything pops.
    far = _line(frame=2)
    far = far.__class__(**{**far.__dict__, "surface": far.surface + [0, 20 * 10 / far.camera.focal_px, 0],
                           "points": far.points - [0, 20]})
    assert pair_metrics(a, far).m2 == pytest.approx(1.0)


def test_resample_is_one_px_and_keeps_length():
    s = _line()
    smp = resample_strokes(s, 1.0)
    assert smp.w.sum() == pytest.approx(s.lengths.sum())
    assert np.all(smp.w <= 1.0 + 1e-9)
    assert np.allclose(np.diff(smp.u), smp.w[0] / s.period_px)


def test_flatness_counts_levels():
    s = _line()
    stretched = replace(s, u=s.u * 4.0)  # texture squeezed 4 times
    _, ov = sequence_metrics([s, stretched])
    assert ov["M5_raw"] == pytest.approx(2.0, abs=1e-6)
    level, weight = levels_from_slope(np.array([4.0 / s.period_px]), s.period_px)
    assert level[0] == 2 and weight[0] == pytest.approx(1.0)
    leveled = replace(stretched, level=level, level_weight=weight)
    _, ov = sequence_metrics([s, leveled])
    assert ov["M5"] == pytest.approx(0.0, abs=1e-6)


def test_cut_pieces_keeps_the_polyline():
    s = _line()
    L = s.lengths[0]
    out = cut_pieces(s, np.array([0, 0]), np.array([0.0, L / 3]), np.array([L / 3, L]), np.array([False, True]))
    assert out.lengths == pytest.approx([L / 3, 2 * L / 3])
    assert np.allclose(out.points[out.offsets[1]], s.points[-1])  # reversed piece starts at the old end
    assert np.allclose(out.points[-1], out.points[out.offsets[1] - 1])  # and ends where the first piece ends


def test_options_are_checked():
    with pytest.raises(UsageError):
        TrackingOptions(method="magic")
    with pytest.raises(UsageError):
        TrackingOptions(period_px=0)


# --- tracking --------------------------------------------------------------------------------

def _total_length(frames):
    return np.array([f.lengths.sum() for f in frames])


def test_cube_orbit_keeps_ids_and_does_not_slide(cube_frames):
    tracked = track_frames(cube_frames)
    pairs, ov = sequence_metrics(tracked)
    assert ov["M1"] >= 0.95
    assert ov["M4_median"] <= 0.5 and ov["M4_p95"] <= 1.5
    # Nothing is drawn twice or lost: same lines, same length.
    assert np.allclose(_total_length(tracked), _total_length(cube_frames), rtol=1e-9)
    for f in tracked:
        assert len(np.unique(f.ids)) == len(f.ids)
    # Without coherence the same lines renumber and slide much more.
    _, none = sequence_metrics(track_frames(cube_frames, TrackingOptions(method="none")))
    assert none["M4_median"] > 2 * max(ov["M4_median"], 0.1)


def test_sphere_dolly_keeps_marks_at_screen_size(sphere_dolly_frames):
    tracked = track_frames(sphere_dolly_frames)
    _, ov = sequence_metrics(tracked)
    # The silhouette shrinks 8 times: u stays attached (little sliding), the raw texture is
    # squeezed, and the self-similar levels bring the marks back to their size.
    assert ov["M1"] >= 0.95
    assert ov["M4_median"] <= 1.0
    assert ov["M5"] <= 0.35
    last = tracked[-1]
    assert np.max(last.level) >= 1  # coarser octaves are in use at the far end
    assert np.all((last.level_weight >= 0) & (last.level_weight <= 1))


def test_torus_split_merge_ids_deterministic_and_no_stroke_lost(torus_frames):
    sil = [int((f.kind == KIND_INDEX["silhouette"]).sum()) for f in torus_frames]
    assert len(set(sil)) > 1, "the orbit must make the silhouette split and merge"
    for method in ("kalnins", "seed"):
        a = track_frames(torus_frames, TrackingOptions(method=method))
        b = track_frames(torus_frames, TrackingOptions(method=method))
        for fa, fb in zip(a, b):
            assert np.array_equal(fa.ids, fb.ids) and np.array_equal(fa.points, fb.points)
            assert np.array_equal(fa.u, fb.u)
            assert len(np.unique(fa.ids)) == len(fa.ids)
        # No stroke lost: every frame draws the same length as its input lines.
        assert np.allclose(_total_length(a), _total_length(torus_frames), rtol=1e-9)
        # Every input point is still drawn (within rounding) after re-cutting.
        for fi, fo in zip(torus_frames, a):
            from scipy.spatial import cKDTree

            d, _ = cKDTree(resample_strokes(fo, 0.5).p).query(fi.points)
            assert d.max() < 0.5
    _, ov = sequence_metrics(track_frames(torus_frames))
    _, none = sequence_metrics(track_frames(torus_frames, TrackingOptions(method="none")))
    assert ov["M1"] > none["M1"] and ov["M4_median"] < none["M4_median"]


def test_no_coherence_renumbers_and_uses_arc_length(cube_frames):
    out = track_frames(cube_frames[:3], TrackingOptions(method="none"))
    for f in out:
        assert np.array_equal(f.ids, np.arange(len(f)))
        assert np.allclose(f.u, f.arc_length / f.period_px)


def test_seed_baseline_limits_growth(torus_frames):
    o = TrackingOptions(method="seed", max_growth_px=5.0)
    out = track_frames(torus_frames, o)
    for a, b in zip(out, out[1:]):
        common, ia, ib = np.intersect1d(a.ids, b.ids, return_indices=True)
        assert np.all(b.lengths[ib] <= a.lengths[ia] + 5.0 + 1e-6)


def test_folder_metrics_reads_frame_json(tmp_path, cube_frames):
    tracked = track_frames(cube_frames[:4])
    for f in tracked:
        (tmp_path / f"frame_{f.frame:04d}.json").write_bytes(strokes_json(f, SIZE, SIZE, f.frame))
    pairs, ov = folder_metrics(tmp_path)
    _, direct = sequence_metrics(tracked)
    assert len(pairs) == 3
    assert ov["M1"] == pytest.approx(direct["M1"], abs=1e-3)
    assert ov["M4_median"] == pytest.approx(direct["M4_median"], abs=0.05)
    with pytest.raises(InputError):
        folder_metrics(tmp_path / "missing")


def test_coherence_command_prints_table_and_json(tmp_path, cube_frames):
    import orjson
    from click.testing import CliRunner

    from cli.commands.coherence import command

    tracked = track_frames(cube_frames[:3])
    for f in tracked:
        (tmp_path / f"frame_{f.frame:04d}.json").write_bytes(strokes_json(f, SIZE, SIZE, f.frame))
    res = CliRunner().invoke(command, [str(tmp_path), "--json"])
    assert res.exit_code == 0, res.output
    doc = orjson.loads(res.output)
    assert [p["frame"] for p in doc["pairs"]] == [2, 3]
    assert doc["overall"]["M1"] >= 0.95 and doc["overall"]["M4_p95"] <= 1.5
    res = CliRunner().invoke(command, [str(tmp_path)])
    assert res.exit_code == 0 and "M1" in res.output and "overall" in res.output
    empty = tmp_path / "empty"
    empty.mkdir()
    res = CliRunner().invoke(command, [str(empty)])
    assert isinstance(res.exception, InputError)
