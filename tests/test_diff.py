"""Golden diffs (issue 7, part 6): `strokekit diff` compares stroke geometry by kind within a pixel
tolerance, ignores stroke ids, reports what changed and where, and draws the difference."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image

from strokekit.errors import InputError, UsageError
from strokekit.metrics.diff import (
    A_ONLY_COLOR,
    B_ONLY_COLOR,
    COMMON_COLOR,
    _NearestStroke,
    assert_same_drawing,
    diff_dirs,
    diff_polylines,
    diff_svgs,
)
from strokekit.metrics.svg_reader import Polylines, parse_path_data, read_svg
from strokekit.model import KIND_INDEX, KINDS, Strokes
from strokekit.writers.svg import svg_document
from strokekit_cli.commands.diff import command as diff_command

W, H = 200, 100
L_SHAPE = np.array([[10.0, 10.0], [100.0, 10.0], [100.0, 50.0]])  # 130 px
DIAGONAL = np.array([[20.0, 80.0], [150.0, 60.0]])
CREASE = np.array([[160.0, 20.0], [160.0, 90.0]])  # 70 px


def svg_text(strokes: list[tuple[str, np.ndarray]], ids=None, size=(W, H), decimals=2) -> str:
    """An SVG written by strokekit's own writer from hand-made strokes [(kind, (n, 2) points)]."""
    pts = np.concatenate([p for _, p in strokes]) if strokes else np.zeros((0, 2))
    off = np.r_[0, np.cumsum([len(p) for _, p in strokes])]
    s = Strokes.build(pts, np.zeros((len(pts), 3)), np.zeros(len(pts)), off, [KIND_INDEX[k] for k, _ in strokes],
                      ids=ids)
    return svg_document(s, size[0], size[1], KINDS[:3], decimals=decimals)


def write(path, strokes, **kw):
    path.write_text(svg_text(strokes, **kw))
    return path


BASE = [("silhouette", L_SHAPE), ("silhouette", DIAGONAL), ("crease", CREASE)]


def test_identical_files_are_equal_with_zero_deviation(tmp_path):
    a = write(tmp_path / "a.svg", BASE)
    b = write(tmp_path / "b.svg", BASE)
    r = diff_svgs(a, b, 0.05)
    assert r.equal
    assert set(r.kinds) == {"silhouette", "border", "crease"}
    sil = r.kinds["silhouette"]
    assert sil.identical and sil.max_deviation == 0.0
    assert sil.length_a == pytest.approx(130 + np.hypot(130, 20))
    assert r.regions == [] and r.renamed == []


@pytest.mark.parametrize("shift", [(0.04, 0.0), (0.0, -0.04), (0.028, 0.028)])
def test_shift_within_tol_is_equal_and_beyond_is_not(tmp_path, shift):
    a = write(tmp_path / "a.svg", BASE)
    b = write(tmp_path / "b.svg", [(k, p + shift) for k, p in BASE])
    d = float(np.hypot(*np.round(shift, 2)))
    r = diff_svgs(a, b, 0.05)
    assert r.equal
    # every stroke has an end point that moved by the full shift: that is the largest distance
    assert r.kinds["silhouette"].max_deviation == pytest.approx(d, abs=1e-6)
    strict = diff_svgs(a, b, 0.01)
    assert not strict.equal
    assert strict.kinds["silhouette"].max_deviation == pytest.approx(d, abs=1e-6)
    # the shift is reported where it is: inside the bounding box of the drawing
    for reg in strict.regions:
        x0, y0, x1, y1 = reg.bbox
        assert 9.9 <= x0 <= x1 <= 160.1 and 9.9 <= y0 <= y1 <= 90.1


def test_renumbered_reordered_reversed_strokes_are_equal_and_renames_reported(tmp_path):
    a = write(tmp_path / "a.svg", BASE)  # ids s0, s1, s2
    b = write(tmp_path / "b.svg", [("crease", CREASE), ("silhouette", DIAGONAL[::-1]), ("silhouette", L_SHAPE)],
              ids=[12, 11, 10])
    r = diff_svgs(a, b, 0.05)
    assert r.equal and r.kinds["silhouette"].identical
    assert sorted(r.renamed) == [("crease", "s2", "s12"), ("silhouette", "s0", "s10"), ("silhouette", "s1", "s11")]
    assert any("new ids" in n for n in r.notes)


def test_renames_found_on_nearly_equal_geometry_too(tmp_path):
    a = write(tmp_path / "a.svg", BASE)
    b = write(tmp_path / "b.svg", [(k, p + 0.03) for k, p in BASE], ids=[5, 6, 7])
    r = diff_svgs(a, b, 0.05)
    assert r.equal and not r.kinds["silhouette"].identical
    assert sorted(r.renamed) == [("crease", "s2", "s7"), ("silhouette", "s0", "s5"), ("silhouette", "s1", "s6")]


def test_same_ids_on_same_geometry_are_not_reported_as_renamed(tmp_path):
    a = write(tmp_path / "a.svg", BASE)
    b = write(tmp_path / "b.svg", [(k, p + 0.03) for k, p in BASE])
    assert diff_svgs(a, b, 0.05).renamed == []


def test_removed_stroke_is_found_with_its_kind_and_place(tmp_path):
    a = write(tmp_path / "a.svg", BASE)
    b = write(tmp_path / "b.svg", [BASE[0], BASE[2]], ids=[0, 2])
    r = diff_svgs(a, b, 0.05)
    assert not r.equal
    sil = r.kinds["silhouette"]
    assert not sil.equal and r.kinds["crease"].equal
    assert sil.b_only_length == 0.0
    assert sil.a_only_length == pytest.approx(np.hypot(130, 20), abs=0.01)
    [reg] = sil.regions
    assert reg.kind == "silhouette" and reg.side == "a" and reg.stroke_ids == ("s1",)
    assert reg.bbox == pytest.approx((20, 60, 150, 80), abs=1e-9)
    # the diagonal's farthest point from what is left (the L) is its end at (20, 80), 70 px below the L
    assert reg.max_deviation == pytest.approx(70.0, abs=1e-6)
    text = r.summary()
    assert "DIFFERENT" in text and "silhouette" in text and "x 20.0..150.0, y 60.0..80.0" in text


def test_added_stroke_is_only_in_b(tmp_path):
    a = write(tmp_path / "a.svg", [BASE[0], BASE[2]])
    b = write(tmp_path / "b.svg", BASE)
    sil = diff_svgs(a, b, 0.05).kinds["silhouette"]
    assert sil.a_only_length == 0.0 and [g.side for g in sil.regions] == ["b"]


def test_same_geometry_in_another_kind_is_a_difference(tmp_path):
    a = write(tmp_path / "a.svg", [("silhouette", L_SHAPE)])
    b = write(tmp_path / "b.svg", [("crease", L_SHAPE)])
    r = diff_svgs(a, b, 0.05)
    assert not r.equal
    assert r.kinds["silhouette"].a_only_length == pytest.approx(130)
    assert r.kinds["crease"].b_only_length == pytest.approx(130)
    assert r.kinds["silhouette"].max_deviation is None  # nothing of that kind on the other side


def test_splitting_a_stroke_differently_is_not_a_difference(tmp_path):
    a = write(tmp_path / "a.svg", [("silhouette", L_SHAPE)])
    b = write(tmp_path / "b.svg", [("silhouette", L_SHAPE[1:]), ("silhouette", L_SHAPE[:2])])
    assert diff_svgs(a, b, 0.01).equal


def test_deviation_between_vertices_is_found_both_ways():
    """A bump in the middle of B's straight segment: B's tip is 0.3 px from A, and the stretch of A
    under the bump is farther than tol from B too. Nothing else differs."""
    line = Polylines.from_list([np.array([[0.0, 0.0], [100.0, 0.0]])], ["s0"])
    bump = Polylines.from_list([np.array([[0.0, 0.0], [50.0, 0.0], [50.5, 0.3], [51.0, 0.0], [100.0, 0.0]])], ["s0"])
    kd = diff_polylines("silhouette", line, bump, 0.05)
    assert not kd.equal
    assert kd.max_deviation == pytest.approx(0.3, abs=1e-9)
    assert sorted(g.side for g in kd.regions) == ["a", "b"]
    for g in kd.regions:
        assert 50.0 < g.bbox[0] < g.bbox[2] < 51.0
    [rb] = [g for g in kd.regions if g.side == "b"]
    assert rb.bbox[3] == pytest.approx(0.3) and rb.max_deviation == pytest.approx(0.3, abs=1e-9)
    # A's stretch under the bump (x 50..51) is the only part of A off B; less than 1 px of it
    assert 0.5 < kd.a_only_length < 1.0
    assert diff_polylines("silhouette", line, bump, 0.31).equal


def _brute_hausdorff(pa: Polylines, pb: Polylines, step: float = 0.01) -> float:
    """Reference: distance from points every `step` px along each side to every segment of the
    other (a lower bound of the true value, short of it by at most step / 2)."""
    def segs(pl):
        keep = np.ones(len(pl.points) - 1, bool)
        keep[pl.offsets[1:-1] - 1] = False
        return pl.points[:-1][keep], pl.points[1:][keep]

    def dense(pl):
        a, b = segs(pl)
        n = np.ceil(np.linalg.norm(b - a, axis=1) / step).astype(int) + 1
        seg = np.repeat(np.arange(len(a)), n)
        t = (np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)) / np.repeat(n - 1, n)
        return a[seg] + (b - a)[seg] * t[:, None]

    def one_way(q, a, b):
        ab = b - a
        den = np.maximum((ab * ab).sum(-1), 1e-300)
        best = np.empty(len(q))
        for s0 in range(0, len(q), 2048):
            qq = q[s0:s0 + 2048, None, :]
            t = np.clip(((qq - a) * ab).sum(-1) / den, 0, 1)
            best[s0:s0 + 2048] = np.linalg.norm(qq - (a + t[..., None] * ab), axis=-1).min(1)
        return best.max()

    return max(one_way(dense(pa), *segs(pb)), one_way(dense(pb), *segs(pa)))


@pytest.mark.parametrize("seed", [0, 1])
def test_max_deviation_matches_brute_force_on_crowded_strokes(seed):
    """Many strokes crossing near the same places (more candidates than the k-d tree query keeps)
    must still give the exact nearest distance; jittered copies compared against a brute force."""
    rng = np.random.default_rng(seed)
    center = np.array([50.0, 50.0])
    polys = []
    for ang in rng.uniform(0, np.pi, 20):  # a fan of strokes through almost the same point
        d = np.array([np.cos(ang), np.sin(ang)])
        polys.append(np.array([center - 10 * d, center + rng.normal(0, 0.05, 2), center + 10 * d]))
    for _ in range(4):  # wiggly strokes
        polys.append(np.cumsum(rng.normal(0, 3, (15, 2)), axis=0) + rng.uniform(0, 100, 2))
    pa = Polylines.from_list(polys, [f"s{i}" for i in range(len(polys))])
    pb = Polylines.from_list([p + rng.normal(0, 0.03, p.shape) for p in polys], pa.ids)
    ref = _brute_hausdorff(pa, pb)
    for tol in (0.02, 0.05, 0.2):
        kd = diff_polylines("silhouette", pa, pb, tol)
        # samples are tol/2 apart: the sampled maximum may miss the true one by at most tol/4
        assert ref - tol / 4 - 1e-9 <= kd.max_deviation <= ref + 0.005 + 1e-9
        assert kd.equal == (kd.max_deviation <= tol + 1e-6)
    assert diff_polylines("silhouette", pa, pb, ref * 1.3).equal
    assert not diff_polylines("silhouette", pa, pb, ref * 0.6).equal


def test_nearest_distance_is_exact_where_strokes_crowd():
    """Where more pieces crowd within reach than the k-d tree query keeps (a fan of 40 strokes
    through one point), every distance within tol is still the exact one, and farther ones are
    never below the truth nor above it by more than half a piece."""
    rng = np.random.default_rng(3)
    ang = rng.uniform(0, np.pi, 40)
    d = np.c_[np.cos(ang), np.sin(ang)]
    polys = [np.array([50 - 5 * di, 50 + 5 * di]) for di in d]
    pl = Polylines.from_list(polys, list(range(len(polys))))
    q = 50 + rng.uniform(-0.3, 0.3, (4000, 2))
    a, b = pl.points[0::2], pl.points[1::2]
    ab = b - a
    t = np.clip(((q[:, None] - a) * ab).sum(-1) / (ab * ab).sum(-1), 0, 1)
    truth = np.linalg.norm(q[:, None] - (a + t[..., None] * ab), axis=-1)
    for tol in (0.002, 0.01):
        nearest = _NearestStroke(pl, piece=0.5)
        dist, stroke = nearest.query(q, tol)
        near = truth.min(1) <= tol
        assert near.sum() > 100 and (~near).sum() > 100
        np.testing.assert_allclose(dist[near], truth.min(1)[near], atol=1e-12)
        assert np.all(truth[np.arange(len(q)), stroke][near] <= tol + 1e-12)  # the stroke named is that near
        far = ~near
        assert np.all(dist[far] >= truth.min(1)[far] - 1e-12) and np.all(dist[far] <= truth.min(1)[far] + 0.25)


def test_other_tools_path_syntax_is_read(tmp_path):
    """Absolute and relative commands, H/V/Z, commas, transforms, polylines: same geometry as
    strokekit's own writer gives an equal diff."""
    ink = 'xmlns:inkscape="http://www.inkscape.org/namespaces/inkscape"'
    other = f"""<?xml version="1.0"?>
<svg xmlns="http://www.w3.org/2000/svg" {ink} width="{W}" height="{H}" viewBox="0 0 {W} {H}">
  <g inkscape:groupmode="layer" inkscape:label="silhouette" transform="translate(5,0)">
    <path id="a1" d="M5,10 L95,10 L95,50"/>
    <path id="a2" d="m 15 80 l 130 -20"/>
  </g>
  <g id="layer-crease"><polyline points="160,20 160,90"/></g>
  <defs><path d="M0 0 L 50 50"/></defs>
</svg>"""
    a = write(tmp_path / "a.svg", BASE)
    (tmp_path / "b.svg").write_text(other)
    r = diff_svgs(a, tmp_path / "b.svg", 0.01)
    assert r.equal, r.summary()
    assert r.kinds["silhouette"].identical


def test_path_data_commands():
    [sq] = parse_path_data("M10 10 H20 V20 h-10 z")
    assert sq.tolist() == [[10, 10], [20, 10], [20, 20], [10, 20], [10, 10]]
    two = parse_path_data("M0,0 1,1 M5 5 l1-1 1e1 0")
    assert [p.tolist() for p in two] == [[[0, 0], [1, 1]], [[5, 5], [6, 4], [16, 4]]]
    for bad in ("M0 0 C1 1 2 2 3 3", "L 1 1", "M0 0 1", "M0 0 L1 x"):
        with pytest.raises(ValueError):
            parse_path_data(bad)


def test_bad_input_is_one_clear_input_error(tmp_path):
    good = write(tmp_path / "a.svg", BASE)
    (tmp_path / "notsvg.svg").write_text("<html><body/></html>")
    (tmp_path / "broken.svg").write_text("<svg")
    (tmp_path / "curve.svg").write_text('<svg xmlns="http://www.w3.org/2000/svg">'
                                        '<path id="s4" d="M0 0 Q1 1 2 0"/></svg>')
    cases = {"missing.svg": "no such file", "notsvg.svg": "not an SVG", "broken.svg": "not an SVG",
             "curve.svg": "s4"}
    for name, words in cases.items():
        with pytest.raises(InputError) as e:
            diff_svgs(good, tmp_path / name, 0.05)
        assert words in str(e.value) and name in str(e.value) and "\n" not in str(e.value)
    with pytest.raises(UsageError):
        diff_svgs(good, good, 0.0)


def _frames(folder, n, shift=0.0, skip=()):
    folder.mkdir()
    for f in range(1, n + 1):
        if f not in skip:
            write(folder / f"frame_{f:04d}.svg", [(k, p + [f + shift, 0]) for k, p in BASE])


def test_folder_comparison_pairs_by_name_and_reports_missing_and_extra(tmp_path):
    _frames(tmp_path / "golden", 4)
    _frames(tmp_path / "same", 4, shift=0.03)
    _frames(tmp_path / "out", 4, skip=(3,))
    (tmp_path / "out" / "frame_0009.svg").write_text(svg_text(BASE))
    assert diff_dirs(tmp_path / "golden", tmp_path / "same", 0.05).equal
    r = diff_dirs(tmp_path / "golden", tmp_path / "out", 0.05)
    assert not r.equal
    assert r.missing == ["frame_0003.svg"] and r.extra == ["frame_0009.svg"]
    assert sorted(r.files) == ["frame_0001.svg", "frame_0002.svg", "frame_0004.svg"]
    assert all(f.equal for f in r.files.values())
    assert "missing in B: frame_0003.svg" in r.summary()


def test_png_shows_a_only_red_b_only_blue_common_grey(tmp_path):
    a = write(tmp_path / "a.svg", [BASE[0], BASE[1]])
    b = write(tmp_path / "b.svg", [BASE[0], BASE[2]])
    r = diff_svgs(a, b, 0.05, png=tmp_path / "d.png")
    img = np.asarray(Image.open(tmp_path / "d.png").convert("RGB"))
    assert img.shape == (H, W, 3)
    px = lambda x, y: tuple(int(v) for v in img[y, x])  # noqa: E731
    assert px(55, 10) == COMMON_COLOR  # on the L, in both
    assert px(85, 70) == A_ONLY_COLOR  # on the diagonal (20,80)-(150,60) at x = 85: only in A
    assert px(160, 55) == B_ONLY_COLOR  # on the crease, only in B
    assert px(55, 40) == (255, 255, 255)
    # the colours are where the differences are and nowhere else
    red = np.all(img == A_ONLY_COLOR, axis=-1)
    ys, xs = np.nonzero(red)
    assert xs.min() >= 18 and xs.max() <= 152 and ys.min() >= 58 and ys.max() <= 82
    assert not np.all(img == B_ONLY_COLOR, axis=-1)[:, :150].any()
    assert not r.equal


def test_png_scale_sets_image_size(tmp_path):
    a = write(tmp_path / "a.svg", BASE)
    diff_svgs(a, a, 0.05, png=tmp_path / "d.png", png_scale=2.0)
    img = np.asarray(Image.open(tmp_path / "d.png").convert("RGB"))
    assert img.shape == (2 * H, 2 * W, 3)
    assert not np.all(img == A_ONLY_COLOR, axis=-1).any()
    assert np.all(img == COMMON_COLOR, axis=-1).sum() > 2 * 330  # the strokes, at least one px wide


def test_cli_exit_codes_and_output(tmp_path):
    run = CliRunner().invoke
    a = write(tmp_path / "a.svg", BASE)
    b = write(tmp_path / "b.svg", [(k, p + [0.04, 0.0]) for k, p in BASE])
    c = write(tmp_path / "c.svg", [BASE[0], BASE[2]])
    (tmp_path / "dir").mkdir()

    res = run(diff_command, [str(a), str(b), "--tol", "0.05"])
    assert res.exit_code == 0, res.output
    assert "equal within 0.05 px" in res.output
    assert run(diff_command, [str(a), str(b), "--tol", "0.01"]).exit_code == 1

    res = run(diff_command, [str(a), str(c), "--json", "--png", str(tmp_path / "d.png")])
    assert res.exit_code == 1
    d = json.loads(res.output)
    assert d["equal"] is False and d["kinds"]["crease"]["equal"] is True
    [reg] = d["kinds"]["silhouette"]["regions"]
    assert reg["side"] == "a" and reg["stroke_ids"] == ["s1"] and reg["bbox"] == [20, 60, 150, 80]
    assert Image.open(tmp_path / "d.png").size == (W, H)

    res = run(diff_command, [str(a), str(tmp_path / "dir")])
    assert res.exit_code == 2 and "folder" in res.output
    res = run(diff_command, [str(a), str(tmp_path / "nope.svg")])
    assert res.exit_code == 2 and "nope.svg: no such file" in res.output
    assert len(res.output.strip().splitlines()) == 1
    assert run(diff_command, [str(a), str(a), "--tol", "-1"]).exit_code == 2
    assert run(diff_command, [str(a), str(a), "--tol", "nan"]).exit_code == 2
    assert run(diff_command, [str(a), str(c), "-q"]).output == ""


def test_cli_folders_and_png_folder(tmp_path):
    _frames(tmp_path / "golden", 3)
    _frames(tmp_path / "out", 3)
    run = CliRunner().invoke
    assert run(diff_command, [str(tmp_path / "golden"), str(tmp_path / "out")]).exit_code == 0
    write(tmp_path / "out" / "frame_0002.svg", [BASE[0]])
    res = run(diff_command, [str(tmp_path / "golden"), str(tmp_path / "out"), "--png", str(tmp_path / "pngs")])
    assert res.exit_code == 1
    assert "frame_0002.svg" in res.output
    assert sorted(p.name for p in (tmp_path / "pngs").iterdir()) == ["frame_0002.png"]


def test_cli_a_missing_golden_folder_is_told_apart_from_a_difference(tmp_path):
    """Exit 1 means the drawings differ: a golden folder (or output folder) that is not there,
    or two folders without any SVG, exit 2 (they exited 1, like a real difference, so a CI job
    could not tell a moved golden folder from a changed drawing)."""
    _frames(tmp_path / "out", 2)
    (tmp_path / "empty_a").mkdir()
    (tmp_path / "empty_b").mkdir()
    run = CliRunner().invoke
    for a, b, words in (("golden", "out", "golden: no such file or folder"),
                        ("out", "golden", "golden: no such file or folder"),
                        ("empty_a", "empty_b", "no SVG files in either folder")):
        res = run(diff_command, [str(tmp_path / a), str(tmp_path / b)])
        assert res.exit_code == 2 and words in res.output and len(res.output.strip().splitlines()) == 1, res.output
    res = run(diff_command, [str(tmp_path / "empty_a"), str(tmp_path / "out")])
    assert res.exit_code == 1 and "2 extra in B" in res.output  # a golden folder emptied: a difference


def test_cli_folders_show_style_changes(tmp_path):
    """Folders of the same geometry drawn with another stroke width are equal (exit 0), and the
    summary says so once, with the files (the note appeared only for single files or --json)."""
    _frames(tmp_path / "golden", 3)
    (tmp_path / "out").mkdir()
    for p in sorted((tmp_path / "golden").iterdir()):
        (tmp_path / "out" / p.name).write_text(p.read_text().replace('stroke-width="1.5"', 'stroke-width="4"'))
    res = CliRunner().invoke(diff_command, [str(tmp_path / "golden"), str(tmp_path / "out")])
    assert res.exit_code == 0, res.output
    notes = [line for line in res.output.splitlines() if "style differs" in line]
    assert len(notes) == 2 and all("stroke-width 1.5" in n and "stroke-width 4" in n for n in notes), res.output
    assert all(n.endswith("[frame_0001.svg, frame_0002.svg, frame_0003.svg]") for n in notes), res.output


def test_read_svg_keeps_empty_layers_and_viewbox(tmp_path):
    a = write(tmp_path / "a.svg", [("silhouette", L_SHAPE)])
    d = read_svg(a)
    assert d.viewbox == (0, 0, W, H)
    assert set(d.layers) == {"silhouette", "border", "crease"}
    assert len(d.layers["border"]) == 0 and d.layers["silhouette"].ids == ("s0",)
    np.testing.assert_array_equal(d.layers["silhouette"].points, L_SHAPE)


def test_assert_same_drawing_for_golden_tests(tmp_path):
    a = write(tmp_path / "a.svg", BASE)
    b = write(tmp_path / "b.svg", [(k, p + [0.04, 0.0]) for k, p in BASE])
    assert assert_same_drawing(a, b, 0.05).equal
    with pytest.raises(AssertionError, match=r"silhouette: .* only in A"):
        assert_same_drawing(a, b, 0.01)


def test_the_same_strokes_on_another_canvas_are_different(tmp_path):
    """A golden at another size (another viewBox) is another picture: `diff` said "equal" (exit 0)
    and only --json mentioned the viewBox. A viewBox within tol, or a file without one, is not a
    difference."""
    a = write(tmp_path / "a.svg", BASE)
    b = write(tmp_path / "b.svg", BASE, size=(2 * W, 2 * H))
    r = diff_svgs(a, b, 0.05)
    assert all(k.equal for k in r.kinds.values()) and not r.same_canvas and not r.equal
    assert f"canvas: viewBox A 0 0 {W} {H}, B 0 0 {2 * W} {2 * H}" in r.summary()
    assert r.to_dict()["equal"] is False
    text = svg_text(BASE)
    box = f'viewBox="0 0 {W} {H}"'
    assert box in text
    near = tmp_path / "c.svg"
    near.write_text(text.replace(box, f'viewBox="0 0 {W} {H + 0.01}"'))
    assert diff_svgs(a, near, 0.05).equal
    bare = tmp_path / "d.svg"
    bare.write_text(re.sub(r' (width|height|viewBox)="[^"]*"', "", text, count=3))
    assert read_svg(bare).viewbox is None and diff_svgs(a, bare, 0.05).equal


def test_style_changes_are_noted_not_counted(tmp_path):
    """diff compares geometry: the same strokes drawn 4 px wide are equal, and a note says the
    style differs (it said nothing: a golden whose colours or widths changed passed silently).
    The same style written as `style=` declarations instead of attributes (as Inkscape re-saves
    it) is the same style: no note."""
    text = svg_text(BASE)
    assert 'stroke-width="1.5"' in text
    a = write(tmp_path / "a.svg", BASE)
    wide = tmp_path / "wide.svg"
    wide.write_text(text.replace('stroke-width="1.5"', 'stroke-width="4"'))
    r = diff_svgs(a, wide, 0.05)
    assert r.equal
    assert any(n.startswith("silhouette: style differs") and "stroke-width 1.5" in n and "stroke-width 4" in n
               for n in r.notes), r.notes
    restyled = tmp_path / "restyled.svg"
    restyled.write_text(text.replace('stroke-width="1.5"', 'style="stroke-width:1.5px"'))
    assert text != restyled.read_text()
    assert not [n for n in diff_svgs(a, restyled, 0.05).notes if "style" in n]
