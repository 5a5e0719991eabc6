"""Brush paths (issue 19): strokes that persist, drawn over the exact lines."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy.spatial import cKDTree

from strokekit.camera.paths import orbit_path
from strokekit.lines.renderer import LineRenderer
from strokekit.lines.strokeops import drop_doubled
from strokekit.metrics.coherence import sequence_metrics, wholeness
from strokekit.model import KIND_INDEX, N_KINDS, Strokes
from strokekit.options import LineOptions
from strokekit.paths import PathOptions, PathTracker, brush_frames
from strokekit.paths.cover import held_back, on_drawing
from strokekit.paths.pieces import LinkPairs, interior_paths, link_pieces, one_label_per_path
from strokekit.sampling import resample_strokes, segment_samples
from strokekit.scene.load import build_scene

SIZE = 512


def _render(scene, path):
    r = LineRenderer(scene, LineOptions(doubled_px=0.0))  # every visible contour edge: the exact lines
    return [r.render(c, k + 1) for k, c in enumerate(path.cameras)]


@pytest.fixture(scope="module")
def sphere_frames():
    m = trimesh.creation.icosphere(subdivisions=3)
    sc = build_scene(m.vertices, m.faces)
    return _render(sc, orbit_path(sc.center, sc.radius, 120, degrees_per_frame=3, elevation=15,
                                  width=SIZE, height=SIZE))


@pytest.fixture(scope="module")
def noisy_sphere_frames():
    """A sphere whose vertices are jittered by 0.2% of its radius: its mesh contour comes out as
    parallel shingles that change from frame to frame, as a scanned mesh's do."""
    m = trimesh.creation.icosphere(subdivisions=4)
    rng = np.random.default_rng(19)
    v = m.vertices * (1.0 + rng.normal(0.0, 0.002, (len(m.vertices), 1)))
    sc = build_scene(v, m.faces)
    return _render(sc, orbit_path(sc.center, sc.radius, 120, degrees_per_frame=3, elevation=15,
                                  width=1024, height=1024))


@pytest.fixture(scope="module")
def torus_frames():
    """A torus around z orbited around y: from face on (two loops) to edge on (one outline and
    the inner contours), so its silhouette splits and merges."""
    m = trimesh.creation.torus(major_radius=1.0, minor_radius=0.4, major_sections=64, minor_sections=32)
    sc = build_scene(m.vertices, m.faces)
    return _render(sc, orbit_path(sc.center, sc.radius, 30, degrees_per_frame=6, elevation=10, up_axis="y",
                                  width=SIZE, height=SIZE))


def _near(a: Strokes, b: Strokes, step: float = 0.1) -> np.ndarray:
    """Distance (px) from points every `step` px along the strokes `a` to the strokes `b`."""
    pa, _, _ = segment_samples(a.points, a.offsets, step)
    pb, _, _ = segment_samples(b.points, b.offsets, step)
    return cKDTree(pb).query(pa)[0]


def _assert_on_the_drawing(out):
    """Paths lie within 1 px of the frame's lines (nothing invented: BRIEF 2's precision at 1 px,
    0.999 of the length; a bridge of 2 px between two line ends, a dropped hairpin point, reach
    a little further) and the lines within 2 px of a path (the cover radius; a strand covered
    beside a covered strand may lie a little further)."""
    for b in out:
        if len(b.lines) == 0:
            assert len(b.strokes) == 0
            continue
        d = _near(b.strokes, b.lines)
        assert np.mean(d <= 1.0) >= 0.999 and d.max() <= 1.5
        d = _near(b.lines, b.strokes)
        assert np.mean(d <= 2.0) >= 0.995 and d.max() <= 3.0


def test_sphere_orbit_keeps_one_contour_path_with_one_id(sphere_frames):
    out = brush_frames(sphere_frames)
    assert all(len(b.strokes) == 1 for b in out)
    assert len({int(b.strokes.ids[0]) for b in out}) == 1
    for b in out:
        st = b.strokes
        assert st.kind[0] == KIND_INDEX["silhouette"]
        assert np.allclose(st.points[0], st.points[-1])  # a closed loop
    _assert_on_the_drawing(out[::10])
    _, ov = sequence_metrics([b.strokes for b in out])
    assert ov["M1"] == 1.0 and ov["M4_median"] < 0.3


def test_torus_paths_split_and_merge_deterministically(torus_frames):
    sil = [int((f.kind == KIND_INDEX["silhouette"]).sum()) for f in torus_frames]
    assert len(set(sil)) > 1, "the orbit must make the silhouette split and merge"
    a = brush_frames(torus_frames)
    b = brush_frames(torus_frames)
    for fa, fb in zip(a, b):
        for name in ("points", "ids", "u", "level", "offsets", "surface"):
            assert np.array_equal(getattr(fa.strokes, name), getattr(fb.strokes, name))
        assert np.array_equal(fa.cover_line, fb.cover_line) and np.array_equal(fa.cover_s0, fb.cover_s0)
        assert len(np.unique(fa.strokes.ids)) == len(fa.strokes)
    _assert_on_the_drawing(a)
    _, ov = sequence_metrics([f.strokes for f in a])
    assert ov["M1"] > 0.97


def test_noisy_sphere_keeps_ids_while_its_lines_have_shingles(noisy_sphere_frames):
    out = brush_frames(noisy_sphere_frames)
    # Shingles: several strands where one contour is (5% of the line length runs beside a longer
    # line within 3 px), in about twice as many strokes as paths.
    lines_len = sum(f.lengths.sum() for f in noisy_sphere_frames)
    assert sum(drop_doubled(f, 3.0).lengths.sum() for f in noisy_sphere_frames) < 0.95 * lines_len
    assert np.mean([len(f) for f in noisy_sphere_frames]) > 1.5 * np.mean([len(b) for b in out])
    _, ov = sequence_metrics([b.strokes for b in out])
    assert ov["M1"] >= 0.97
    _assert_on_the_drawing(out[::8])
    # Fewer paths than lines late in the orbit too (how whole: the next test).
    assert np.mean([len(b) for b in out[-10:]]) < np.mean([len(f) for f in noisy_sphere_frames[-10:]])


def test_a_noisy_sphere_stays_as_whole_as_drawn_afresh(noisy_sphere_frames):
    """Over 120 frames the tracked paths have at most 1.25 times the ends of the same frames drawn
    afresh (BRIEF 3, M8: one loop, its shingles apart) while keeping their ids (M1 >= 0.97): the
    strands the contour moves onto and the parts gaps cut off join the loop again."""
    out = [b.strokes for b in brush_frames(noisy_sphere_frames)]
    fresh = [b.strokes for b in brush_frames(noisy_sphere_frames, PathOptions(history=False))]
    _, m8 = wholeness(out, fresh)
    _, ov = sequence_metrics(out)
    assert m8["M8_ratio"] <= 1.25 and ov["M1"] >= 0.97


def test_covers_list_the_line_pieces_of_each_path(torus_frames):
    b = brush_frames(torus_frames[:3])[-1]
    assert b.cover_offsets[0] == 0 and b.cover_offsets[-1] == len(b.cover_line)
    assert np.all(np.diff(b.cover_offsets) >= 1)
    L = b.lines.lengths
    assert np.all(b.cover_s0 < b.cover_s1)
    assert np.all(b.cover_s0 >= -1e-9) and np.all(b.cover_s1 <= L[b.cover_line] + 1e-9)
    # The drawn covers add up to the path's length, less the bridges.
    drawn = np.bincount(np.repeat(np.arange(len(b)), np.diff(b.cover_offsets)),
                        weights=np.where(b.cover_drawn, b.cover_s1 - b.cover_s0, 0.0), minlength=len(b))
    assert np.all(drawn <= b.strokes.lengths + 1e-6) and np.all(drawn >= 0.9 * b.strokes.lengths)
    assert b.covers(0)[0][3] in (True, False)


def test_without_history_ids_are_fresh_every_frame(torus_frames):
    tr = PathTracker(PathOptions(history=False))
    for f in torus_frames[:3]:
        b = tr.step(f)
        assert np.array_equal(b.strokes.ids, np.arange(len(b)))
        assert np.allclose(b.strokes.u, b.strokes.arc_length / b.strokes.period_px)


def test_empty_frame_gives_no_paths():
    tr = PathTracker()
    b = tr.step(Strokes.empty())
    assert len(b) == 0 and len(b.cover_line) == 0 and list(b.cover_offsets) == [0]


def test_a_bridge_is_drawn_only_on_the_drawing():
    # Lines along y = 0 and y = 1.5 (samples every 0.5 px): a bridge across them stays within 1 px
    # of a line; one that leaves them by 3 px does not.
    x = np.arange(0.0, 20.0, 0.5)
    tree = cKDTree(np.r_[np.c_[x, np.zeros_like(x)], np.c_[x, np.full_like(x, 1.5)]])
    ok = on_drawing(tree, np.array([[5.0, 0.0], [5.0, 0.0]]), np.array([[9.0, 1.5], [9.0, 6.0]]))
    assert ok.tolist() == [True, False]


def test_a_bridge_is_measured_against_the_lines_not_their_samples():
    # A line along y = 0 sampled every px: a bridge 0.95 px beside it lies within 1 px of the line
    # but up to 1.07 px from its samples; one 1.2 px beside it is off the drawing either way.
    line = Strokes.build([[0.0, 0.0], [20.0, 0.0]], np.zeros((2, 3)), [0, 0], [0, 2], [0])
    D = resample_strokes(line, 1.0, with_surface=False)
    tree = cKDTree(D.p)
    pa, pb = np.array([[3.0, 0.95], [3.0, 1.2]]), np.array([[8.0, 0.95], [8.0, 1.2]])
    assert on_drawing(tree, pa, pb, D=D).tolist() == [True, False]
    assert on_drawing(tree, pa, pb).tolist() == [False, False]


def test_new_short_paths_beside_the_drawing_are_held_back():
    # Path 0 (id 3, carried) along y = 0; new ids from 5: a 5 px strand 2 px beside it is held, one
    # 10 px away is drawn (it would leave the line it stands for far from any path), so is a long one.
    pts = [[0.0, 0.0], [100.0, 0.0], [40.0, 2.0], [45.0, 2.0], [40.0, 10.0], [45.0, 10.0], [0.0, 2.5], [30.0, 2.5]]
    paths = Strokes.build(pts, np.zeros((8, 3)), np.zeros(8), [0, 2, 4, 6, 8], np.zeros(4), ids=[3, 5, 6, 7])
    D = resample_strokes(paths, 1.0, with_surface=False)  # (the paths draw their own samples)
    tree = cKDTree(D.p)

    def held(first_fresh, o=PathOptions()):
        return held_back(paths, first_fresh, o, D.p, D.stroke, tree).tolist()

    assert held(5) == [False, True, False, False]
    assert held(6) == [False, False, False, False]  # id 5 is carried: drawn
    assert not any(held(5, PathOptions(hold_px=0.0)))


def _pieces_along_x(cuts):
    """Pieces of kind 0 along y = 0, piece i from x = cuts[i] to cuts[i + 1], a point every px."""
    pts = [np.c_[np.arange(a, b + 1.0), np.zeros(int(b - a) + 1)] for a, b in zip(cuts[:-1], cuts[1:])]
    n = [len(p) for p in pts]
    P = np.concatenate(pts)
    return Strokes(points=P, surface=np.c_[P, np.zeros(len(P))], face=np.zeros(len(P), np.int64),
                   offsets=np.r_[0, np.cumsum(n)].astype(np.int64), kind=np.zeros(len(n), np.int64),
                   ids=np.arange(len(n)), u=np.zeros(len(P)), level=np.zeros(len(n)), level_weight=np.ones(len(n)),
                   camera=None, frame=1, period_px=10.0)


def test_a_path_within_a_longer_paths_line_takes_its_label():
    """A path whose two ends meet ends of longer paths of one other label (a strand of shingles the
    contour moved onto, or the part a gap cut off a loop) gives way to that label: drawn apart, it
    would keep the line cut for good. Between two labels, or longer than a path it meets, it stays."""
    pieces = _pieces_along_x([0.0, 100.0, 120.0, 300.0])
    plen = pieces.lengths

    def gives_way(label):
        label = np.asarray(label)
        pairs = LinkPairs.of(pieces, 6.0, 70.0)
        group, rev, pos = link_pieces(pieces, 6.0, 70.0, label, 2.0, lambda a, b: np.ones(len(a), bool), pairs=pairs)
        return interior_paths(group, rev, pos, label, plen, pairs).tolist()

    assert gives_way([5, 7, 5]) == [-1, 5, -1]
    assert gives_way([5, 7, 9]) == [-1, -1, -1]  # (between two labels: a cut either way)
    pieces = _pieces_along_x([0.0, 100.0, 250.0, 300.0])  # (the middle path longer than one it meets)
    plen = pieces.lengths
    assert gives_way([5, 7, 5]) == [-1, -1, -1]


def test_one_label_per_path_cuts_where_the_label_changes():
    # One group of five pieces in order: labels 3, -1, -1, 4, 4 -> cut before the first 4.
    group = np.zeros(5, np.int64)
    pos = np.arange(5)
    label = np.array([3, -1, -1, 4, 4])
    g = one_label_per_path(group, pos, label)
    assert g.tolist() == [0, 0, 0, 1, 1]
    # Leading unlabelled pieces go with the first label; one label: unchanged.
    assert one_label_per_path(group, pos, np.array([-1, 2, 2, -1, 2])).tolist() == [0, 0, 0, 0, 0]


def test_options_are_checked():
    from strokekit.errors import UsageError

    for bad in (dict(sample_px=0), dict(cover_px=-1), dict(join_angle_deg=0), dict(min_run_px=float("nan"))):
        with pytest.raises(UsageError):
            PathOptions(**bad)


# --- the render command --------------------------------------------------------------------------

def _cli(args, capsys):
    from strokekit_cli.main import main

    with pytest.raises(SystemExit) as e:
        main([str(a) for a in args])
    out = capsys.readouterr()
    return e.value.code, out.out, out.err


def test_render_draws_brush_paths_for_a_sequence_and_lines_for_one_frame(tmp_path, capsys):
    import json

    from helpers import SAMPLES

    from strokekit.metrics.coherence import folder_metrics
    from strokekit.writers.strokes_json import read_strokes_json

    base = ["render", SAMPLES / "still_life.glb", "--camera", SAMPLES / "orbit.json", "-q"]
    assert _cli([*base, "--frames", "1-3", "--out", tmp_path / "seq"], capsys)[0] == 0
    d = json.loads((tmp_path / "seq" / "frame_0002.json").read_text())
    assert d["strokes_are"] == "brush" and d["tracking"] == "brush"
    lines = d["lines"]
    assert all(c[0] in {s["id"] for s in lines} for s in d["strokes"] for c in s["covers"])
    assert len(d["strokes"]) < len(lines)
    # The SVG draws the paths: one <path> per brush path.
    assert (tmp_path / "seq" / "frame_0002.svg").read_text().count("<path ") == len(d["strokes"])
    folder_metrics(tmp_path / "seq")  # the coherence metrics read brush frames
    # One frame: the exact lines, the JSON as it always was (no brush keys).
    assert _cli([*base, "--frames", "2", "--out", tmp_path / "one"], capsys)[0] == 0
    one = json.loads((tmp_path / "one" / "frame_0002.json").read_text())
    assert "lines" not in one and "strokes_are" not in one and one["tracking"] == "none"
    assert np.array_equal(read_strokes_json(tmp_path / "one" / "frame_0002.json").points,
                          read_strokes_json(tmp_path / "seq" / "frame_0002.json", which="lines").points)
    # --strokes brush on one frame: paths without history; --strokes lines on a sequence: tracked lines.
    assert _cli([*base, "--frames", "2", "--strokes", "brush", "--out", tmp_path / "b1"], capsys)[0] == 0
    assert json.loads((tmp_path / "b1" / "frame_0002.json").read_text())["tracking"] == "none"
    assert _cli([*base, "--frames", "1-3", "--strokes", "lines", "--out", tmp_path / "l3"], capsys)[0] == 0
    assert json.loads((tmp_path / "l3" / "frame_0002.json").read_text())["tracking"] == "kalnins"
    # Naming a method tracks lines; with --strokes brush it is a usage error.
    assert _cli([*base, "--frames", "1-3", "--coherence", "seed", "--out", tmp_path / "s3"], capsys)[0] == 0
    assert "lines" not in json.loads((tmp_path / "s3" / "frame_0002.json").read_text())
    code, _, err = _cli([*base, "--frames", "1-3", "--strokes", "brush", "--coherence", "seed", "--out",
                         tmp_path / "bad"], capsys)
    assert code == 2 and "--strokes lines" in err


def test_brush_run_resumes_to_the_same_bytes(tmp_path, capsys):
    from helpers import SAMPLES

    base = ["render", SAMPLES / "still_life.glb", "--camera", SAMPLES / "orbit.json", "-q", "--frames", "1-4"]
    assert _cli([*base, "--out", tmp_path / "a", "--gltf"], capsys)[0] == 0
    assert _cli([*base[:-1], "1-2", "--out", tmp_path / "b", "--gltf"], capsys)[0] == 0
    assert _cli([*base, "--out", tmp_path / "b", "--gltf", "--skip-existing"], capsys)[0] == 0
    for f in sorted((tmp_path / "a").glob("frame_*")):
        assert f.read_bytes() == (tmp_path / "b" / f.name).read_bytes(), f.name
    # Other strokes are other options: no resume over lines frames.
    code, _, err = _cli([*base, "--strokes", "lines", "--out", tmp_path / "b", "--gltf", "--skip-existing"], capsys)
    assert code == 2 and "other options" in err


def test_a_brush_resume_computes_only_up_to_its_last_missing_frame(tmp_path, capsys, monkeypatch):
    """A tracked resume needs the frames before the last one it writes, and none after it: with
    frame 2 of 4 missing, frames 1-2 are computed (same bytes as the uninterrupted run); with
    nothing missing, no frame is computed and the brush path kernels are not loaded."""
    from helpers import SAMPLES

    import strokekit.run.tasks as tasks

    base = ["render", SAMPLES / "still_life.glb", "--camera", SAMPLES / "orbit.json", "-q", "--frames", "1-4",
            "--workers", "1", "--out", tmp_path / "a"]
    assert _cli(base, capsys)[0] == 0
    ref = {f.name: f.read_bytes() for f in (tmp_path / "a").glob("frame_*")}
    for f in (tmp_path / "a").glob("frame_0002*"):
        f.unlink()
    seen, real = [], tasks.frame_task

    def counting(task):
        seen.append(task.number)
        return real(task)

    monkeypatch.setattr(tasks, "frame_task", counting)
    assert _cli([*base, "--skip-existing"], capsys)[0] == 0
    assert sorted(seen) == [1, 2]
    assert {f.name: f.read_bytes() for f in (tmp_path / "a").glob("frame_*")} == ref

    from strokekit.paths.kernels import BRUSH_PATHS

    warmed = []
    monkeypatch.setattr(BRUSH_PATHS, "warm", lambda *a, **k: warmed.append(a) or (0.0, False))
    seen.clear()
    assert _cli([*base, "--skip-existing"], capsys)[0] == 0
    assert seen == [] and warmed == []
    assert {f.name: f.read_bytes() for f in (tmp_path / "a").glob("frame_*")} == ref


def test_the_still_life_handle_contour_is_one_path():
    """Frame 1 of the sample: the inner contour of the box's handle comes out of the line pass as
    five strokes (chain ends where a chord meets it, a sub-pixel stub); it is drawn as one path."""
    from helpers import SAMPLES

    from strokekit.camera.paths import load_camera_path
    from strokekit.scene.load import load_scene

    sc = load_scene(SAMPLES / "still_life.glb")
    lines = LineRenderer(sc, LineOptions()).render(load_camera_path(SAMPLES / "orbit.json").cameras[0], 1)
    inner = []
    for i in range(len(lines)):
        p = lines.points[lines.stroke(i)]
        box = (p[:, 0] > 430) & (p[:, 0] < 505) & (p[:, 1] > 262) & (p[:, 1] < 293)
        if lines.kind[i] == KIND_INDEX["silhouette"] and box.all() and len(p) > 2:  # (the chord is one segment)
            inner.append(i)
    assert len(inner) >= 4
    b = PathTracker().step(lines)
    owners = {s for s in range(len(b)) for line, _, _, drawn in b.covers(s) if drawn and line in inner}
    assert len(owners) == 1


def test_a_held_strand_is_drawn_with_its_id_from_the_next_frame():
    """Through PathTracker: a 5 px crease strand 2 px beside a long crease appears in frame 2. It is
    held back there (not drawn, in BrushPaths.held with a fresh id), and from frame 3 on it is drawn
    with that id; the long line keeps its id throughout; nothing is held in the first frame."""
    from strokekit.camera.view import Camera

    cam = Camera(eye=(0.0, 0.0, 10.0), target=(0.0, 0.0, 0.0), fov_y=40, width=400, height=300)
    px_per_unit = cam.focal_px / 10.0

    def segment(x0, x1, y):
        n = int(np.ceil((x1 - x0) * px_per_unit)) + 1
        world = np.column_stack([np.linspace(x0, x1, n), np.full(n, y), np.zeros(n)])
        return cam.project(world)[0], world

    def frame(k, strand):
        parts = [segment(-2.0, 2.0, 0.0)] + ([segment(0.0, 5.0 / px_per_unit, 2.0 / px_per_unit)] if strand else [])
        offsets = np.cumsum([0] + [len(p) for p, _ in parts])
        return Strokes.build(np.vstack([p for p, _ in parts]), np.vstack([w for _, w in parts]),
                             np.zeros(offsets[-1]), offsets, [KIND_INDEX["crease"]] * len(parts), camera=cam, frame=k)

    tracker = PathTracker()
    out = [tracker.step(frame(k, strand=k >= 2)) for k in (1, 2, 3, 4)]
    assert out[0].held is None or len(out[0].held) == 0
    assert [len(b.strokes) for b in out] == [1, 1, 2, 2]
    assert len({int(b.strokes.ids[np.argmax(b.strokes.lengths)]) for b in out}) == 1, "the long line keeps its id"
    held_id = out[1].held.ids.tolist()
    assert len(held_id) == 1
    for b in out[2:]:
        short = b.strokes.ids[np.argmin(b.strokes.lengths)]
        assert short == held_id[0]


@pytest.mark.parametrize("kinds", [("crease", "silhouette"), ("silhouette", "crease")])
def test_a_path_keeps_its_id_when_its_line_changes_kind(kinds):
    """A sharp edge drawn as a crease until the outline runs along it, then as silhouette (or the
    other way round): the same line, another kind class, so it carries no label of the previous
    frame's path; its votes of the other class still claim that path's id, so the path keeps it.
    A second line that stays a crease keeps its own id."""
    from strokekit.camera.view import Camera

    cam = Camera(eye=(0.0, 0.0, 10.0), target=(0.0, 0.0, 0.0), fov_y=40, width=400, height=300)

    def segment(y):
        world = np.column_stack([np.linspace(-2.0, 2.0, 200), np.full(200, y), np.zeros(200)])
        return cam.project(world)[0], world

    def frame(k, kind):
        parts = [segment(0.0), segment(1.0)]
        offsets = np.cumsum([0] + [len(p) for p, _ in parts])
        return Strokes.build(np.vstack([p for p, _ in parts]), np.vstack([w for _, w in parts]),
                             np.zeros(offsets[-1]), offsets, [KIND_INDEX[kind], KIND_INDEX["crease"]], camera=cam,
                             frame=k)

    tracker = PathTracker()
    out = [tracker.step(frame(k, kinds[k >= 2])) for k in (1, 2, 3)]
    y0 = out[0].strokes.surface[out[0].strokes.offsets[:-1], 1]  # (world y of each path: which line it is)
    changed, kept = int(out[0].strokes.ids[np.argmin(y0)]), int(out[0].strokes.ids[np.argmax(y0)])
    for b in out[1:]:
        s = b.strokes
        assert len(s) == 2
        y = s.surface[s.offsets[:-1], 1]
        assert int(s.ids[np.argmin(y)]) == changed, "the line that changed kind keeps its path's id"
        assert int(s.ids[np.argmax(y)]) == kept
        assert s.kind[np.argmin(y)] == KIND_INDEX[kinds[1]]


def test_a_silhouette_covers_a_crease_beside_it():
    """A sharp edge 1 px beside the outline (the face between them edge on) is one line drawn
    twice: a crease run of CREASE_COVER_MIN_PX or more beside a silhouette is covered by it (one
    path, the crease listed among its covered pieces); two creases side by side stay two lines,
    and a crease never covers a silhouette."""
    from strokekit.camera.view import Camera

    cam = Camera(eye=(0.0, 0.0, 10.0), target=(0.0, 0.0, 0.0), fov_y=40, width=400, height=300)
    px = cam.focal_px / 10.0

    def frame(kinds, lengths_px):
        parts = []
        for k, L in enumerate(lengths_px):
            world = np.column_stack([np.linspace(-L / (2 * px), L / (2 * px), 100), np.full(100, k / px),
                                     np.zeros(100)])
            parts.append((cam.project(world)[0], world))
        offsets = np.cumsum([0] + [len(p) for p, _ in parts])
        return Strokes.build(np.vstack([p for p, _ in parts]), np.vstack([w for _, w in parts]),
                             np.zeros(offsets[-1]), offsets, [KIND_INDEX[k] for k in kinds], camera=cam, frame=1)

    b = PathTracker().step(frame(["silhouette", "crease"], [100.0, 100.0]))
    assert len(b.strokes) == 1 and b.strokes.kind[0] == KIND_INDEX["silhouette"]
    assert {(line, drawn) for line, _, _, drawn in b.covers(0)} == {(0, True), (1, False)}
    # The crease is the longer line: still covered where it runs beside the silhouette, and it
    # covers nothing.
    b = PathTracker().step(frame(["crease", "silhouette"], [100.0, 40.0]))
    sil = np.flatnonzero(b.strokes.kind == KIND_INDEX["silhouette"])
    assert len(sil) == 1 and b.strokes.lengths[sil[0]] == pytest.approx(40.0, abs=1.0)
    assert sum(b.strokes.lengths) < 110.0
    assert len(PathTracker().step(frame(["crease", "crease"], [100.0, 100.0])).strokes) == 2


def test_a_path_runs_on_into_the_piece_it_continued_last_frame():
    """Three crease pieces of one path meet at a junction J: the one the path ended with (A, along
    +x), the one it ran on into from J last frame (B, turning 70 degrees up) and one turning 55
    degrees down (C, where the path's tail ran last frame, towards J: its u far from A's). The
    link A-C turns less and is the cheaper one; the path still runs on from A into B, as it did,
    and C is a path of its own."""
    from strokekit.camera.view import Camera

    cam = Camera(eye=(0.0, 0.0, 10.0), target=(0.0, 0.0, 0.0), fov_y=40, width=400, height=300)

    def polyline(corners):
        corners = np.asarray(corners, float)
        pts = [np.linspace(corners[i], corners[i + 1], 60, endpoint=False) for i in range(len(corners) - 1)]
        world = np.column_stack([np.vstack(pts + [corners[-1:]]), np.zeros(60 * (len(corners) - 1) + 1)])
        return cam.project(world)[0], world

    def frame(k, parts):
        parts = [polyline(p) for p in parts]
        offsets = np.cumsum([0] + [len(p) for p, _ in parts])
        return Strokes.build(np.vstack([p for p, _ in parts]), np.vstack([w for _, w in parts]),
                             np.zeros(offsets[-1]), offsets, [KIND_INDEX["crease"]] * len(parts), camera=cam, frame=k)

    def towards(deg, r):
        return (r * np.cos(np.radians(deg)), r * np.sin(np.radians(deg)))

    J, b1, c1 = (0.0, 0.0), towards(70.0, 1.0), towards(-55.0, 2.0)
    # (A path may turn 100 degrees here: frame 1's line rounds corners of 90.)
    tracker = PathTracker(PathOptions(join_angle_deg=100.0))
    first = tracker.step(frame(1, [[(-2.0, 0.0), J, b1, (2.2, b1[1]), (2.2, c1[1]), c1, towards(-55.0, 0.3)]]))
    assert len(first.strokes) == 1
    out = tracker.step(frame(2, [[(-2.0, 0.0), J], [J, b1, (2.2, b1[1]), (2.2, -1.0)], [J, c1]]))
    S = out.strokes
    assert len(S) == 2
    on = [towards(0.0, -1.0), (1.0, b1[1]), towards(-55.0, 1.0)]  # (points of A, B and C)
    which = [S.stroke_of_point[cKDTree(S.surface[:, :2]).query(p)[1]] for p in on]
    assert which[0] == which[1] != which[2], "A runs on into B; C is a path of its own"
    assert S.ids[which[0]] == first.strokes.ids[0]



def _polyline_frame(cam, k, lines):
    """A frame of silhouette lines, each a list of straight segments (a, b) in the z = 0 plane
    (world units), 60 points a segment."""
    pts = []
    for segs in lines:
        w = np.vstack([np.linspace(a, b, 60, endpoint=False) for a, b in segs] + [np.asarray(segs[-1][1])[None]])
        pts.append(np.column_stack([w, np.zeros(len(w))]))
    offsets = np.cumsum([0] + [len(w) for w in pts])
    world = np.vstack(pts)
    return Strokes.build(cam.project(world)[0], world, np.zeros(len(world)), offsets,
                         [KIND_INDEX["silhouette"]] * len(pts), camera=cam, frame=k)


def test_a_path_ends_at_a_corner_whether_one_line_or_two_meet_there():
    """A line turning past join_angle_deg (70) at one vertex is cut there, as two lines meeting at
    that angle are not joined: an outline that rounds an 80 degree corner as one line in frame 1
    and comes as two lines meeting at the corner in frame 2 is two paths in both frames, and both
    keep their ids. A corner of 60 degrees is one path either way."""
    from strokekit.camera.view import Camera

    cam = Camera(eye=(0.0, 0.0, 10.0), target=(0.0, 0.0, 0.0), fov_y=40, width=400, height=300)
    J = np.zeros(2)
    for turn, n_paths in ((80.0, 2), (60.0, 1)):
        a = (np.array([-1.5, 0.0]), J)
        b = (J, 1.5 * np.array([np.cos(np.radians(turn)), np.sin(np.radians(turn))]))
        tracker = PathTracker()
        first = tracker.step(_polyline_frame(cam, 1, [[a, b]])).strokes
        second = tracker.step(_polyline_frame(cam, 2, [[a], [b]])).strokes
        assert len(first) == len(second) == n_paths, turn
        assert sorted(first.ids) == sorted(second.ids), turn


def test_a_line_that_breaks_for_one_frame_heals_with_the_longer_pieces_id():
    """A 160 px outline breaks in frame 2 (a gap of 10 px, past join_px, cuts a 12 px piece off
    its end: that piece takes a fresh id) and is whole again from frame 3 on. The two paths meet
    end to end on the whole line in frame 3 (a touch that must last: still two paths) and heal in
    frame 4 into one path with the long path's id, which stays (heal_px 0: two paths for good;
    the default heals only pieces under 6 px)."""
    from strokekit.camera.view import Camera

    cam = Camera(eye=(0.0, 0.0, 10.0), target=(0.0, 0.0, 0.0), fov_y=40, width=400, height=300)
    whole = [[(np.array([-2.0, 0.0]), np.array([2.0, 0.0]))]]
    broken = [[(np.array([-2.0, 0.0]), np.array([1.45, 0.0]))], [(np.array([1.7, 0.0]), np.array([2.0, 0.0]))]]
    frames = [_polyline_frame(cam, k, broken if k == 2 else whole) for k in range(1, 7)]
    for heal_px, counts in ((20.0, [1, 2, 2, 1, 1, 1]), (0.0, [1, 2, 2, 2, 2, 2])):
        out = [b.strokes for b in brush_frames(frames, PathOptions(heal_px=heal_px))]
        assert [len(s) for s in out] == counts, heal_px
        long_id = int(out[0].ids[0])
        assert all(int(s.ids[np.argmax(s.lengths)]) == long_id for s in out), heal_px


def test_a_healed_piece_keeps_its_texture_shifted_by_whole_periods():
    """heal_paths: a 12 px path (born this frame) meeting a carried 100 px path end to end joins it
    with the carried id; the long path's u stays, the short one's u is its own plus a whole number
    of periods (matched samples do not slide), the healed path's u increasing along it."""
    from strokekit.paths.heal import heal_paths

    x = np.arange(0.0, 101.0)
    xs = np.arange(101.0, 113.0)
    pts = np.vstack([np.column_stack([xs[::-1], 0 * xs]), np.column_stack([x, 0 * x])])
    u_short, u_long = 0.37 + xs[::-1] / 10.0, 5.0 + x / 10.0
    u_short = u_short[::-1].copy()  # (increasing along its own points, which run towards the long path)
    pts[:12] = pts[:12][::-1]
    N = len(pts)
    paths = Strokes(points=pts, surface=np.zeros((N, 3)), face=np.zeros(N, np.int64), offsets=np.array([0, 12, N]),
                    kind=np.zeros(2, np.int8), ids=np.array([9, 4]), u=np.concatenate([u_short, u_long]),
                    level=np.zeros(2), level_weight=np.ones(2), period_px=10.0)
    out, new_of = heal_paths(paths, np.array([4]), np.zeros(0, np.int64), 20.0, np.zeros(2, bool))
    assert len(out) == 1 and out.ids.tolist() == [4] and new_of.tolist() == [0, 0]
    assert np.all(np.diff(out.u) > 0)
    on_long = out.points[:, 0] <= 100.0
    np.testing.assert_allclose(out.u[on_long], u_long)
    k = out.u[~on_long] - (0.37 + out.points[~on_long, 0] / 10.0)
    np.testing.assert_allclose(k, np.round(k))


def test_a_line_cut_for_two_frames_keeps_one_id_and_comes_back_whole():
    """A 160 px outline is cut by a 10 px gap in frames 2 and 3 (past join_px), where a crease
    runs along it: the 50 px piece beyond the gap, too long to heal, would take a fresh id and
    keep it (two paths for good). With bridge_px 20 it is held joined to its parent across the gap
    (the bridge lies on the drawing), so the outline is one path with frame 1's id in every
    frame, whole again from frame 4 on."""
    from strokekit.camera.view import Camera

    cam = Camera(eye=(0.0, 0.0, 10.0), target=(0.0, 0.0, 0.0), fov_y=40, width=400, height=300)
    whole = [[(np.array([-2.0, 0.0]), np.array([2.0, 0.0]))]]
    cut = [[(np.array([-2.0, 0.0]), np.array([0.55, 0.0]))], [(np.array([0.8, 0.0]), np.array([2.0, 0.0]))]]

    def frame(k):
        if k not in (2, 3):
            return _polyline_frame(cam, k, whole)
        crease = _polyline_frame(cam, k, [[(np.array([0.5, 0.0]), np.array([0.85, 0.0]))]])
        crease = crease.replace(kind=np.full(1, KIND_INDEX["crease"], crease.kind.dtype))
        return Strokes.concat([_polyline_frame(cam, k, cut), crease])

    frames = [frame(k) for k in range(1, 7)]
    for bridge_px in (20.0, 0.0):
        out = [b.strokes for b in brush_frames(frames, PathOptions(bridge_px=bridge_px))]
        outline = [s.kind % N_KINDS == KIND_INDEX["silhouette"] for s in out]
        ids = [s.ids[o].tolist() for s, o in zip(out, outline)]
        if bridge_px:
            assert ids == [ids[0]] * 6
            assert all(abs(s.lengths[o][0] - out[0].lengths[0]) < 2.0 for s, o in zip(out, outline))
        else:
            assert [len(i) for i in ids] == [1, 2, 2, 2, 2, 2]


def test_orphans_are_the_short_paths_of_a_label_that_do_not_get_its_id():
    from strokekit.paths.stage import orphans

    # Five pieces in four paths (groups): label 7 on paths 0 (30 px) and 2 (10 px), label 9 on
    # path 3 (12 px) alone, one unclaimed piece (path 4).
    group = np.array([0, 0, 2, 3, 4])
    label = np.array([7, 7, 7, 9, -1])
    plen = np.array([20.0, 10.0, 10.0, 12.0, 5.0])
    # Path 2 is the orphan: label 7's id goes to path 0, the longer; path 3 is 9's only path.
    assert orphans(group, label, plen, 15.0).tolist() == [False, False, True, False, False]
    # Longer than the limit, or no limit: no orphan.
    assert not orphans(group, label, plen, 9.0).any()
    assert not orphans(group, label, plen, 0.0).any()


@pytest.mark.parametrize("size", [512])
def test_orphans_keep_spot_whole_without_costing_ids(models_dir, size):
    """Over a 40-frame orbit of spot, paths whose votes came from a path that runs elsewhere join
    the path they touch instead of taking fresh ids: the late frames hold fewer paths than with
    orphan_px 0, and the ids persist as well (M1 not lower)."""
    from strokekit.scene.load import load_scene

    sc = load_scene(models_dir / "spot.obj")
    orbit = orbit_path(sc.center, sc.radius, 40, degrees_per_frame=3.0, width=size, height=size)
    r = LineRenderer(sc, LineOptions())
    lines = [r.render(c, k + 1) for k, c in enumerate(orbit.cameras)]
    rows = {}
    for px in (0.0, PathOptions().orphan_px):
        out = [b.strokes for b in brush_frames(lines, PathOptions(orphan_px=px))]
        _, m = sequence_metrics(out)
        rows[px] = (np.mean([len(s) for s in out[20:]]), m["M1"])
    (n0, m0), (n1, m1) = rows[0.0], rows[PathOptions().orphan_px]
    assert n1 < 0.85 * n0, rows
    assert m1 >= m0 - 0.001, rows
