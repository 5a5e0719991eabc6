"""Coherent strokes along a camera path: persistent ids, u that does not slide, self-similar levels,
and the BRIEF 3 metrics that measure them."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import trimesh
from scipy.spatial import cKDTree

from strokekit.camera.paths import dolly_path, orbit_path
from strokekit.camera.view import Camera
from strokekit.errors import InputError, UsageError
from strokekit.lines.renderer import LineRenderer
from strokekit.lines.strokeops import cut_pieces, drop_doubled
from strokekit.metrics.coherence import MAX_STRETCH_OCTAVES, folder_metrics, pair_metrics, sequence_metrics
from strokekit.model import KIND_INDEX, Strokes
from strokekit.options import LineOptions
from strokekit.sampling import resample_strokes
from strokekit.scene.load import build_scene, load_scene
from strokekit.tracking.options import TrackingOptions
from strokekit.tracking.tracker import Tracker, track_frames
from strokekit.tracking.ufit import levels_from_slope
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
    # (A generated torus of the same size seen on this orbit keeps one outline: the shared model is
    # what makes its silhouette split and merge.)
    if not (MODELS / "torus.STL").exists():
        pytest.skip(f"shared model torus.STL not found at {MODELS}")
    sc = load_scene(MODELS / "torus.STL")
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
    # A frozen texture (constant u) is stretched without bound: it counts as the cap, not as 0.
    _, ov = sequence_metrics([s, replace(s, u=np.full_like(s.u, 0.3))])
    assert ov["M5_raw"] == pytest.approx(MAX_STRETCH_OCTAVES)


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
        TrackingOptions(search_radius_px=0)
    # Fields the command line does not expose: dense_spacing_px 0 raised a numpy ValueError on
    # frame 2, bend_weight -1 gave NaN u, negative spacings were quietly taken.
    for bad in ({"dense_spacing_px": 0}, {"dense_spacing_px": -1}, {"bend_weight": -1}, {"knot_spacing_px": -1},
                {"min_segment_px": -1}):
        with pytest.raises(UsageError, match=f"{next(iter(bad))} must be"):
            TrackingOptions(**bad)


# --- tracking --------------------------------------------------------------------------------

def _total_length(frames):
    return np.array([f.lengths.sum() for f in frames])


def _assert_draws_the_input(tracked, frames, o=TrackingOptions()):
    """The tracked frames draw their input lines: every input point is drawn; nothing is drawn
    farther than the join tolerance from an input line (bridges where strokes are healed); the
    length is the input's plus at most one bridge per stroke, less at most one join tolerance per
    stroke where two strands that overlap at their ends were joined (the joint point that turned
    back is dropped: the exact lines keep such doubled contour pieces)."""
    for fi, fo in zip(frames, tracked):
        if len(fi) == 0:
            continue
        d, _ = cKDTree(resample_strokes(fo, 0.25).p).query(resample_strokes(fi, 0.5).p)
        assert d.max() <= 0.3
        d, _ = cKDTree(resample_strokes(fi, 0.25).p).query(resample_strokes(fo, 0.5).p)
        assert d.max() <= o.join_tol_px + 0.3
        ref = fi.lengths.sum()
        assert ref - o.join_tol_px * len(fi) - 1e-6 <= fo.lengths.sum() <= ref + o.join_tol_px * len(fi) + 1e-6


def test_cube_orbit_keeps_ids_and_does_not_slide(cube_frames):
    tracked = track_frames(cube_frames)
    pairs, ov = sequence_metrics(tracked)
    assert ov["M1"] >= 0.95
    assert ov["M4_median"] <= 0.5 and ov["M4_p95"] <= 1.5
    # Nothing is lost: the same lines (plus joins' bridges).
    _assert_draws_the_input(tracked, cube_frames)
    exact = track_frames(cube_frames, TrackingOptions(join_tol_px=1e-6))
    assert np.allclose(_total_length(exact), _total_length(cube_frames), rtol=1e-9)
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
        # No stroke lost: every frame draws its input lines (plus bridges).
        _assert_draws_the_input(a, torus_frames)
        # Without bridges: exactly the same length, every input point drawn.
        exact = track_frames(torus_frames, TrackingOptions(method=method, join_tol_px=1e-6))
        assert np.allclose(_total_length(exact), _total_length(torus_frames), rtol=1e-9)
        for fi, fo in zip(torus_frames, exact):
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

    from strokekit_cli.commands.coherence import command

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


def test_coherence_command_reads_a_pattern_and_warns_about_missing_frames(tmp_path, cube_frames):
    """`coherence --pattern` reads frames written with render --pattern; a gap in the frame
    numbers is said (the pair compares two frames that are not neighbours)."""
    from click.testing import CliRunner

    from strokekit_cli.commands.coherence import command

    tracked = track_frames(cube_frames[:4])
    for f in tracked:
        if f.frame != 3:
            (tmp_path / f"shot_{f.frame:03d}.json").write_bytes(strokes_json(f, SIZE, SIZE, f.frame))
    res = CliRunner().invoke(command, [str(tmp_path), "--json", "--pattern", "shot_{frame:03d}"])
    assert res.exit_code == 0, res.output
    assert "frame 4 is compared with frame 2" in res.stderr and "frame 2 is compared" not in res.stderr
    res = CliRunner().invoke(command, [str(tmp_path)])  # the default pattern finds none of them
    assert isinstance(res.exception, InputError) and "frame_*.json" in str(res.exception)


# --- re-cutting, healing, doubled lines (small synthetic frames on the plane z = 0) -----------

def _plane_strokes(polylines, frame=1, eye=(0.0, 0.0, 10.0), n=60, kind="crease"):
    """Strokes along world polylines (lists of (x, y) corners on z = 0), seen from `eye`."""
    cam = Camera(eye=eye, target=(eye[0], eye[1], 0.0), width=SIZE, height=SIZE)
    pts, X, offs = [], [], [0]
    for pl in polylines:
        pl = np.asarray(pl, float)
        t = np.linspace(0, 1, n)
        # Corner to corner, n points per piece (straight pieces).
        xy = np.concatenate([pl[k] + (pl[k + 1] - pl[k]) * t[:, None] * 1.0 if k == 0 else
                             (pl[k] + (pl[k + 1] - pl[k]) * t[1:, None]) for k in range(len(pl) - 1)])
        Xk = np.c_[xy, np.zeros(len(xy))]
        pts.append(cam.project(Xk)[0])
        X.append(Xk)
        offs.append(offs[-1] + len(xy))
    return Strokes.build(np.concatenate(pts), np.concatenate(X), np.zeros(offs[-1]), offs,
                         [KIND_INDEX[kind]] * len(polylines), camera=cam, frame=frame)


def _px(s: Strokes) -> float:
    """World units per pixel on the plane z = 0 for this frame's camera."""
    return 10.0 / s.camera.focal_px


def test_chain_through_two_old_strokes_is_cut_where_the_old_boundary_projects():
    # Frame 1: two strokes meeting at x = 0.137; frame 2: one chain through both, camera moved.
    a = _plane_strokes([[(-1, 0), (0.137, 0)], [(0.137, 0), (1, 0)]], frame=1)
    b = _plane_strokes([[(-1, 0), (1, 0)]], frame=2, eye=(0.04, 0.02, 10.0))
    tr = Tracker(TrackingOptions(join_tol_px=1e-6))
    t1 = tr.step(a)
    t2 = tr.step(b)
    assert len(t2) == 2 and set(t2.ids.tolist()) == set(t1.ids.tolist())
    for sid, old in zip(t1.ids, range(2)):
        k = int(np.flatnonzero(t2.ids == sid)[0])
        xs = t2.surface[t2.stroke(k), 0]
        # Each id keeps its own part; the cut is where the old boundary projects (well under a
        # dense sample spacing of 3 px).
        lo, hi = (-1.0, 0.137) if old == 0 else (0.137, 1.0)
        assert xs.min() == pytest.approx(lo, abs=0.5 * _px(b)) and xs.max() == pytest.approx(hi, abs=0.5 * _px(b))
    assert pair_metrics(t1, t2).m1 >= 0.99


def test_split_keeps_the_id_on_the_larger_part():
    a = _plane_strokes([[(-1, 0), (1, 0)]], frame=1)
    b = _plane_strokes([[(-1, 0), (0.2, 0)], [(0.4, 0), (1, 0)]], frame=2)
    tr = Tracker()
    t1 = tr.step(a)
    t2 = tr.step(b)
    big = int(np.argmax(t2.lengths))
    assert t2.ids[big] == t1.ids[0]
    assert t2.ids[1 - big] != t1.ids[0]
    assert t2.surface[t2.stroke(big), 0].max() < 0.2 + 1e-6  # the larger part is the left one


def test_short_chain_between_two_is_healed_into_one_stroke():
    # The chaining broke one line into three touching pieces (the middle one ~2 px, no vote
    # lands on it): drawn as one stroke with the old id, u continuous.
    a = _plane_strokes([[(-1, 0), (1, 0)]], frame=1)
    b = _plane_strokes([[(-1, 0), (0.3, 0)], [(0.3, 0), (0.33, 0)], [(0.33, 0), (1, 0)]], frame=2)
    tr = Tracker()
    t1 = tr.step(a)
    t2 = tr.step(b)
    assert len(t2) == 1 and t2.ids[0] == t1.ids[0]
    assert t2.lengths[0] == pytest.approx(b.lengths.sum(), abs=1e-6)
    assert np.max(np.abs(np.diff(t2.u))) * t2.period_px < 3.0  # no jump in the texture


def test_drop_doubled_removes_only_the_part_beside_a_longer_stroke():
    # B runs 0.7 px beside A over x in [0.5, 1] then alone to 1.5; C continues A from its end.
    off = 0.7
    s = _plane_strokes([[(-1, 0), (1, 0)], [(0.5, 0), (1.5, 0)], [(1, 0), (1.25, 0.433)]])
    px = _px(s)
    s = _plane_strokes([[(-1, 0), (1, 0)], [(0.5, off * px), (1.5, off * px)], [(1, 0), (1.25, 0.433)]],
                       kind="silhouette")
    out = drop_doubled(s, 1.5)
    L = np.sort(out.lengths)
    # A and C whole; B only from x = 1 on (to within a sample).
    assert out.lengths.sum() == pytest.approx(s.lengths.sum() - 0.5 / px, abs=1.5)
    assert np.any(np.isclose(L, s.lengths[0], atol=1e-6)) and np.any(np.isclose(L, s.lengths[2], atol=1e-6))
    # Nothing drawn is lost by more than the doubling radius.
    d, _ = cKDTree(resample_strokes(out, 0.25).p).query(resample_strokes(s, 0.5).p)
    assert d.max() <= 1.5
    assert drop_doubled(s, 0.0) is s
    # A stroke of its own, however short, is not a leftover: kept.
    dot = _plane_strokes([[(0, 0.5), (0.005, 0.5)]], kind="silhouette")
    both = Strokes.concat([s, replace(dot, ids=dot.ids + 3)])
    assert drop_doubled(both, 1.5).lengths.sum() == pytest.approx(out.lengths.sum() + dot.lengths[0])
    # Two creases close together are two lines: kept.
    creases = replace(s, kind=np.full(len(s), KIND_INDEX["crease"], np.int8))
    assert drop_doubled(creases, 1.5).lengths.sum() == pytest.approx(s.lengths.sum())


def test_gap_below_join_tolerance_is_bridged_and_a_real_gap_is_not():
    a = _plane_strokes([[(-1, 0), (1, 0)]], frame=1)
    px = _px(a)
    o = TrackingOptions()
    for gap_px, joined in ((0.6 * o.join_tol_px, True), (3.0 * o.join_tol_px + 1.0, False)):
        g = gap_px * px
        b = _plane_strokes([[(-1, 0), (0.1, 0)], [(0.1 + g, 0), (1, 0)]], frame=2)
        tr = Tracker(o)
        t1 = tr.step(a)
        t2 = tr.step(b)
        assert (len(t2) == 1) == joined
        assert t2.ids[np.argmax(t2.lengths)] == t1.ids[0]
        # A bridge adds the gap and nothing more.
        assert t2.lengths.sum() == pytest.approx(b.lengths.sum() + (gap_px if joined else 0.0), abs=1e-6)


def test_id_boundary_stays_where_it_was_when_the_chain_ends_move():
    # Frame 1: ids meet at x = 0.137. Frame 2: the chaining stops at x = 0.2 instead (touching
    # chains; ~4.5 px away, under min_segment_px). The boundary between the two ids stays at
    # 0.137 (hysteresis), it does not follow this frame's chain end; without chain_touching the
    # 4.5 px piece is too short to be a segment of its own and the boundary follows the chain.
    a = _plane_strokes([[(-1, 0), (0.137, 0)], [(0.137, 0), (1, 0)]], frame=1)
    b = _plane_strokes([[(-1, 0), (0.2, 0)], [(0.2, 0), (1, 0)]], frame=2)
    assert (0.2 - 0.137) / _px(b) < TrackingOptions().min_segment_px
    for touching, cut in ((True, 0.137), (False, 0.2)):
        tr = Tracker(TrackingOptions(chain_touching=touching))
        t1 = tr.step(a)
        t2 = tr.step(b)
        assert len(t2) == 2 and set(t2.ids.tolist()) == set(t1.ids.tolist())
        k = int(np.flatnonzero(t2.ids == t1.ids[0])[0])
        assert t2.surface[t2.stroke(k), 0].max() == pytest.approx(cut, abs=0.5 * _px(b))
        assert np.isclose(t2.lengths.sum(), b.lengths.sum())
        if touching:
            assert pair_metrics(t1, t2).m1 >= 0.99


def test_votes_go_to_the_nearest_line_and_a_sample_to_the_most_vote_weight():
    # Shingled mesh contours (bunny): pieces of contour 1-3 px apart. The tracker's samples are
    # 3-4 px apart, so the nearest sample *centre* can be on the neighbour line while the line
    # itself passes nearer (the metric's 1 px samples find that line): votes must land on the
    # line whose piece passes nearest. Protects bunny M1 (0.922 -> 0.929 on the 120-frame orbit).
    from strokekit.sampling import Samples, match_samples
    from strokekit.tracking.votes import segment_by_votes

    cam = Camera(eye=(0.0, 0.0, 10.0), target=(0.0, 0.0, 0.0), width=SIZE, height=SIZE)
    # Line A along y = 0 with samples every 3 px at x = 0, 3; line B along y = 1.5 px, sample at x = 1.5.
    p = np.array([[0.0, 0.0], [3.0, 0.0], [1.5, 1.5]]) + SIZE / 2
    t = np.array([[1.0, 0.0], [1.0, 0.0], [1.0, 0.0]])
    dst = Samples(p=p, X=np.zeros((3, 3)), u=np.zeros(3), t=t, ids=np.array([1, 1, 2]),
                  stroke=np.array([0, 0, 1]), s=np.array([1.5, 4.5, 1.5]), w=np.full(3, 3.0))
    # A voter 0.5 px off line A, halfway between A's samples: 1.58 px from A's, 1.0 px from B's centre.
    q = np.array([[1.5 + SIZE / 2, 0.5 + SIZE / 2]])
    X = np.c_[(q - SIZE / 2) * np.array([1, -1]) * 10.0 / cam.focal_px, [0.0]]
    src = Samples(p=q, X=X, u=np.zeros(1), t=np.array([[1.0, 0.0]]), ids=np.array([7]), stroke=np.zeros(1, np.int64),
                  s=np.zeros(1), w=np.ones(1))
    assert match_samples(src, cam, dst, k=4)[0] == 2  # the metric's rule on these sparse samples: B
    assert match_samples(src, cam, dst, k=4, piece_distance=True)[0] in (0, 1)  # the tracker's: A
    # Two votes of id 3 (4 px each) and one stray heavier vote of id 9 (5 px) on one sample: id 3.
    one = Samples(p=np.zeros((2, 2)), X=np.zeros((2, 3)), u=np.zeros(2), t=np.tile([1.0, 0.0], (2, 1)),
                  ids=np.zeros(2, np.int64), stroke=np.zeros(2, np.int64), s=np.array([1.5, 4.5]), w=np.full(2, 3.0))
    run, r_stroke, r_s0, r_s1, r_label = segment_by_votes(one, np.array([6.0]), np.array([0, 0, 0]),
                                                          np.array([3, 3, 9]), np.array([4.0, 4.0, 5.0]), 6.0)
    assert r_label.tolist() == [3]


def test_metric_match_finds_the_nearest_agreeing_sample_behind_a_crowd():
    """BRIEF 3: the match is the nearest sample within 6 px whose tangent agrees. A line with a
    crowd of short crossing strokes between it and its next-frame copy 3 px away: more than k
    disagreeing samples are nearer than the copy, and the metric still finds the copy."""
    from strokekit.sampling import match_samples

    probe = _plane_strokes([[(-0.3, 0), (0.3, 0)]], frame=1)
    px = _px(probe)
    crossing = [[(i * px, -2.5 * px), (i * px, 2.5 * px)] for i in range(-400, 401) if abs(i * px) < 0.35]
    a = _plane_strokes([[(-0.3, 0), (0.3, 0)]], frame=1, n=40)
    b = _plane_strokes([[(-0.3, -3 * px), (0.3, -3 * px)]] + crossing, frame=2, n=6)
    sa, sb = resample_strokes(a, 1.0), resample_strokes(b, 1.0)
    tree = cKDTree(sb.p)
    plain = match_samples(sa, b.camera, sb, tree)
    exact = match_samples(sa, b.camera, sb, tree, exact=True)
    on_copy = sb.stroke == 0
    assert (plain >= 0).mean() < 0.5  # the k nearest are the crossing strokes: most samples missed
    assert (exact >= 0).all() and on_copy[exact].all()
    d = np.abs(sb.p[exact, 1] - sa.p[:, 1])
    assert np.allclose(d, 3.0, atol=0.05)
    # The metrics use it: the line is not counted as popping, only the crossing strokes are.
    m = pair_metrics(a, b)
    assert m.unmatched_px <= b.lengths[1:].sum() + 0.01 * a.lengths.sum()


def test_chain_touching_paths_and_pair_sweep_match_the_general_join():
    """chain_touching's specialized linking (touching_paths, _close_pairs) gives exactly what the
    general join_segments gives for its call, on random strokes with shared ends, rings, closed
    strokes and near-tolerance gaps."""
    from strokekit.tracking.joins import _close_pairs, join_segments, touching_paths

    rng = np.random.default_rng(1)
    linked = 0
    for _trial in range(200):
        S = int(rng.integers(2, 40))
        ends = rng.integers(0, 6, (S, 2, 2)).astype(float) * 3
        pts, off = [], [0]
        for k in range(S):
            n = int(rng.integers(2, 5))
            p = np.linspace(ends[k, 0], ends[k, 1], n) + rng.normal(0, 0.3, (n, 2)) * (rng.random() < 0.5)
            if rng.random() < 0.1:
                p[-1] = p[0]
            pts.append(p)
            off.append(off[-1] + n)
        P = np.concatenate(pts)
        f = Strokes.build(P, np.zeros((len(P), 3)), np.zeros(len(P)), off, rng.integers(0, 2, S))
        for tol, ang in ((2.0, 90.0), (1.0, 170.0)):
            want = join_segments(f, np.arange(S), np.zeros(S), f.lengths, np.zeros(S, np.int64), np.ones(S),
                                  tol, ang, straightest_first=True)
            got = touching_paths(f, tol, ang)
            for w, g in zip(want, got):
                assert g.dtype == w.dtype and np.array_equal(g, w)
            linked += int((want[0] != np.arange(S)).sum())
        # The sweep finds the k-d tree's pairs, boundary cases included (exactly r apart).
        q = np.round(P)
        q = np.concatenate([q, q + [2.0, 0.0], q + [1.2, 1.6]])
        want = {tuple(x) for x in cKDTree(q).query_pairs(2.0, output_type="ndarray").tolist()}
        assert {tuple(x) for x in _close_pairs(q, 2.0).tolist()} == want
    assert linked > 100  # the cases did join strokes


def test_unique_inverse_is_np_unique():
    from strokekit.tracking.votes import unique_inverse

    rng = np.random.default_rng(2)
    for n in (0, 1, 2, 7, 300, 2000):
        x = rng.integers(0, max(n // 3, 1) * 1000003, n)  # repeats, large keys
        x[: n // 4] = x[n // 4: 2 * (n // 4)]
        want_u, want_inv = np.unique(x, return_inverse=True)
        got_u, got_inv = unique_inverse(x)
        assert np.array_equal(got_u, want_u) and np.array_equal(got_inv, want_inv.ravel())
        assert np.array_equal(got_u[got_inv], x)


def test_max_length_splits_each_stroke_and_keeps_the_others_whole():
    """--max-length (seed 000 split criterion): a long stroke is cut into pieces of at most the
    limit that share their end points, and the strokes after it keep their own points and kind.
    The inserted end points were not counted in the later strokes' starts: after the first split
    every later stroke took points of the one before (silhouette points in a crease stroke, an
    empty path, jumps of 500 px drawn between strokes)."""
    from strokekit.lines.strokeops import split_max_length

    p = np.array([[0, 0], [10, 0], [20, 0], [30, 0], [0, 50], [5, 50], [0, 80], [10, 80], [20, 80]], float)
    st = Strokes.build(p, np.zeros((len(p), 3)), np.zeros(len(p)), [0, 4, 6, 9],
                       [KIND_INDEX["silhouette"], KIND_INDEX["crease"], KIND_INDEX["border"]])
    out = split_max_length(st, 15.0)
    pieces = [(int(out.kind[s]), out.points[out.stroke(s)].tolist()) for s in range(len(out))]
    sil, crease, border = KIND_INDEX["silhouette"], KIND_INDEX["crease"], KIND_INDEX["border"]
    assert pieces == [(sil, [[0, 0], [10, 0]]), (sil, [[10, 0], [20, 0]]), (sil, [[20, 0], [30, 0]]),
                      (crease, [[0, 50], [5, 50]]), (border, [[0, 80], [10, 80]]), (border, [[10, 80], [20, 80]])]
    assert out.lengths.sum() == pytest.approx(st.lengths.sum())


@pytest.mark.parametrize("method", ["seed", "kalnins"])
def test_a_line_the_camera_flew_past_hands_its_id_to_nobody(method):
    """Line A is in front of the camera in frame 1 and behind it in frame 2, where an unrelated
    line B is on screen. The seed baseline projected A's start anyway (mirrored to a finite pixel
    near B) and gave B A's id."""
    def line(cam, X, frame):
        n = len(X)
        p, _ = cam.project(X)
        return Strokes(points=p, surface=X, face=np.full(n, -1), offsets=np.array([0, n]), kind=np.zeros(1, np.int8),
                       ids=np.zeros(1, np.int64), u=np.zeros(n), level=np.zeros(1), level_weight=np.ones(1),
                       camera=cam, frame=frame)

    cam1 = Camera(eye=(0, 0, 10), target=(0, 0, 0), width=512, height=512)
    cam2 = Camera(eye=(0, 0, 5), target=(0, 0, 0), width=512, height=512)
    A = np.stack([np.full(50, 0.01), np.linspace(0.01, 0.5, 50), np.full(50, 5.5)], 1)
    B = np.stack([np.full(50, -0.1), np.linspace(-0.3, 0.1, 50), np.zeros(50)], 1)
    assert cam2.project(A[:1])[1][0] < 0
    tr = Tracker(TrackingOptions(method=method))
    a = tr.step(line(cam1, A, 1))
    b = tr.step(line(cam2, B, 2))
    assert a.ids[0] not in b.ids.tolist()


def test_a_line_turning_through_edge_on_keeps_u_increasing_along_it():
    """A straight line seen nearly end-on: as the camera swings past its axis, its image turns
    around. u sits on the surface, so the carried votes still increase from the same end; the
    tangents alone (old image direction against new) would reverse the stroke and u with it
    would run backwards along the drawn line."""
    X = np.stack([np.full(40, 0.05), np.zeros(40), np.linspace(-1.0, 1.0, 40)], 1)

    def frame(azimuth, k):
        cam = Camera(eye=(10 * np.sin(azimuth), 0.0, 10 * np.cos(azimuth)), target=(0, 0, 0), width=SIZE,
                     height=SIZE)
        p, _ = cam.project(X)
        return Strokes.build(p, X, np.zeros(40), [0, 40], [KIND_INDEX["crease"]], camera=cam, frame=k)

    a, b = frame(-0.2, 1), frame(0.2, 2)
    # The image direction of the line (first to last point) has turned around.
    da, db = a.points[-1] - a.points[0], b.points[-1] - b.points[0]
    assert np.dot(da, db) < 0 and min(a.lengths[0], b.lengths[0]) > 20
    tr = Tracker()
    t1, t2 = tr.step(a), tr.step(b)
    assert t2.ids.tolist() == t1.ids.tolist()
    assert np.all(np.diff(t2.u) > 0)  # u increases along the drawn stroke
    # from the same end of the line as before: u at each surface point is carried.
    end = np.argmin(t2.surface[:, 2])
    assert t2.u[end] == pytest.approx(t1.u[np.argmin(t1.surface[:, 2])], abs=0.1)


def test_an_open_piece_across_an_old_loop_seam_keeps_u_continuous():
    """Frame 1 draws a closed loop (u from u0 at its start to u0 + U back at the same point);
    in frame 2 only an arc across that start is left. The votes jump by U there: u must not
    fold back (nor leap) where the old seam was."""
    ang = np.radians(np.arange(0, 361, 3))
    loop = np.c_[0.6 * np.cos(ang), 0.6 * np.sin(ang)]
    arc = np.radians(np.arange(-120, 121, 3))
    piece = np.c_[0.6 * np.cos(arc), 0.6 * np.sin(arc)]
    a = _plane_strokes([loop], frame=1, n=2)
    b = _plane_strokes([piece], frame=2, n=2)
    tr = Tracker()
    t1, t2 = tr.step(a), tr.step(b)
    assert np.linalg.norm(t1.points[0] - t1.points[-1]) < 1e-6  # a closed stroke
    assert t2.ids.tolist() == t1.ids.tolist()
    du = np.diff(t2.u) / np.maximum(np.linalg.norm(np.diff(t2.points, axis=0), axis=1), 1e-9)
    # Every step's slope stays near 1 / P: no fold, no jump.
    assert np.all(du > 0) and np.all(du * t2.period_px < 1.5)


def _max_turn_deg(st: Strokes) -> float:
    worst = 0.0
    for i in range(len(st)):
        d = np.diff(st.points[st.stroke(i)], axis=0)
        d = d[np.linalg.norm(d, axis=1) > 1e-9]
        if len(d) > 1:
            c = np.einsum("ij,ij->i", d[1:], d[:-1]) / np.linalg.norm(d[1:], axis=1) / np.linalg.norm(d[:-1], axis=1)
            worst = max(worst, float(np.degrees(np.arccos(np.clip(c.min(), -1, 1)))))
    return worst


def test_touching_strands_are_joined_without_a_hairpin():
    """Two collinear strands: one ends 0.1 px past where the other begins (they overlap), or
    0.5 px short of it (a gap). Both are joined into one stroke (the id boundary can then go
    where the previous frame had it); the overlap must not leave a 180 degree hairpin at the
    joint (drawn as a folded ribbon), and the gap is bridged."""
    def strands(x_end, frame):
        p = np.array([[100.0, 50.0], [100.0 + x_end, 50.0], [110.0, 50.0], [140.0, 50.0]])
        X = np.c_[p, np.zeros(4)]
        cam = Camera(eye=(0, 0, 10), target=(0, 0, 0), width=SIZE, height=SIZE)
        return Strokes.build(p, X, np.zeros(4), [0, 2, 4], [KIND_INDEX["silhouette"]] * 2, camera=cam, frame=frame)

    for x_end in (10.1, 9.5):
        tr = Tracker()
        tr.step(strands(x_end, 1))
        out = tr.step(strands(x_end, 2))
        assert len(out) == 1 and _max_turn_deg(out) < 1e-6
        assert out.lengths[0] == pytest.approx(40.0, abs=0.11)


def test_a_hairpin_that_moves_back_a_point_when_the_joint_goes_is_dropped_too():
    """Strand A ends at x = 10.8 with a point at 10.6 before it; strand B begins at 10.2. The joint
    point (10.8) goes, and then the fold is at 10.6: the points next to a dropped one are looked
    at again."""
    from strokekit.tracking.joins import chain_touching

    p = np.array([[0.0, 50.0], [10.6, 50.0], [10.8, 50.0], [10.2, 50.0], [20.0, 50.0]]) + [100.0, 0.0]
    s = Strokes.build(p, np.c_[p, np.zeros(5)], np.zeros(5), [0, 3, 5], [KIND_INDEX["silhouette"]] * 2)
    out = chain_touching(s, 2.0, 90.0)
    assert len(out) == 1 and _max_turn_deg(out) < 1e-6
    assert out.points[:, 0].tolist() == [100.0, 110.2, 120.0]
