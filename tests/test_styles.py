"""Line styles (strokekit.style): style files and their errors, widths per point by the
modifiers' formulas, the SVG's outlines and centrelines, the JSON's widths, the ribbons' and the
lines raster's widths, and the command line's shortcuts writing the same style."""

from __future__ import annotations

import io
import json
import math
from pathlib import Path

import numpy as np
import pytest
from helpers import MODELS, SAMPLES, run_cli

from strokekit.camera.view import Camera
from strokekit.errors import InputError, UsageError
from strokekit.metrics.svg_reader import read_svg
from strokekit.model import KIND_INDEX, Strokes
from strokekit.style import Along, Calligraphy, Curvature, Depth, LineSet, Noise, Style, apply_style, read_style
from strokekit.style.widths import value_noise
from strokekit.writers.outline import outline_path_data
from strokekit.writers.svg import svg_document

MINIMAL = """\
[[lineset]]
kinds = ["silhouette", "border"]
color = "#1a1a1a"
width = 2.0
thickness = [{ by = "depth", near = 3.0, far = 0.5 }, { by = "along", head = 8, tail = 12 }]
"""


def line(points, kind="silhouette", ids=None, offsets=None, camera=None, frame=1) -> Strokes:
    p = np.asarray(points, float)
    offsets = [0, len(p)] if offsets is None else offsets
    n = len(offsets) - 1
    return Strokes.build(p, np.c_[p, np.zeros(len(p))], np.full(len(p), -1), offsets,
                         np.full(n, KIND_INDEX[kind]), ids=ids, camera=camera, frame=frame)


@pytest.fixture
def cli(capsys):
    """`strokekit ARGS` in this process: an object with exit_code, stdout and stderr."""
    class Result:
        pass

    def run(args):
        r = Result()
        r.exit_code, r.stdout, r.stderr = run_cli(args, capsys)
        return r
    return run


def one_set(*mods, width=2.0) -> Style:
    return Style(sets=(LineSet("all", width=width, thickness=tuple(mods)),))


# --- style files -------------------------------------------------------------------------------------

def test_the_issues_minimal_style_file_reads(tmp_path):
    f = tmp_path / "s.toml"
    f.write_text(MINIMAL)
    st = read_style(f)
    (s,) = st.sets
    assert s.kinds == ("silhouette", "border") and s.color == "#1a1a1a" and s.width == 2.0
    assert s.thickness == (Depth(near=3.0, far=0.5), Along(head=8.0, tail=12.0))


@pytest.mark.parametrize("text, line_no, words", [
    (MINIMAL.replace('color = "#1a1a1a"', 'colour = "#1a1a1a"'), 3, ["'colour'", "unknown key", "lineset 1"]),
    (MINIMAL.replace("width = 2.0", 'width = "2"'), 4, ["'width'", "must be a number"]),
    (MINIMAL.replace('kinds = ["silhouette", "border"]', "kinds = []"), 2, ["'kinds'", "selects nothing"]),
    (MINIMAL.replace("far = 0.5", "far = -1"), 5, ["'far'", "thickness 1 'depth'", ">= 0"]),
    (MINIMAL.replace('by = "along"', 'by = "speed"'), 5, ["'by'", "unknown modifier 'speed'"]),
    (MINIMAL + '\n[[lineset]]\nname = "b"\nvisibility = "hiden"\n', 9, ["'visibility'", "lineset 2 'b'"]),
    ("width = 1\nlinesets = 3\n", 2, ["'linesets'", "unknown key"]),
    (MINIMAL.replace("thickness = [", "thickness = [\n  ").replace("{ by = \"along\", head = 8",
                                                                   "\n  { by = \"along\", head = -8"),
     7, ["'head'", "thickness 2 'along'"]),
    ("[[lineset]]\n[[lineset.thickness]]\nby = \"noise\"\nboil = 1.5\n", 4, ["'boil'", "whole number"]),
])
def test_a_bad_style_file_names_the_file_the_line_and_the_key(tmp_path, text, line_no, words):
    f = tmp_path / "bad.toml"
    f.write_text(text)
    with pytest.raises(InputError) as e:
        read_style(f)
    msg = str(e.value)
    assert msg.startswith(f"{f}: line {line_no}: "), msg
    for w in words:
        assert w in msg, msg


def test_a_toml_syntax_error_says_its_line(tmp_path):
    f = tmp_path / "bad.toml"
    f.write_text("[[lineset]]\nkinds = [\"silhouette\"\nwidth = 2\n")
    with pytest.raises(InputError, match=r"bad.toml: not a TOML style file: .*line"):
        read_style(f)


def test_the_command_line_refuses_a_bad_style_before_any_work(tmp_path, cli):
    f = tmp_path / "bad.toml"
    f.write_text(MINIMAL.replace("width = 2.0", "width = true"))
    out = tmp_path / "out"
    r = cli(["render", str(MODELS / "spot.obj"), "--orbit", "2", "--style", str(f), "--out", str(out)])
    assert r.exit_code == 1
    assert f"{f}: line 4: key 'width' (lineset 1): must be a number, got a boolean True" in r.stderr
    assert "Traceback" not in r.stderr and not out.exists()


def test_a_set_that_selects_nothing_drawn_is_an_input_error(tmp_path, cli):
    """A set of hidden lines without --hidden, an object the scene does not have: both select
    nothing; said with the file, the key's line, exit 1, nothing written."""
    f = tmp_path / "s.toml"
    f.write_text('[[lineset]]\nname = "back"\nvisibility = "hidden"\n')
    out = tmp_path / "out"
    r = cli(["render", str(MODELS / "spot.obj"), "--orbit", "2", "--style", str(f), "--out", str(out)])
    assert r.exit_code == 1
    assert f"{f}: line 3: key 'visibility' (lineset 1 'back'): line set 'back' selects nothing the run draws: it " \
        "takes every kind at occlusion 1-15" in r.stderr, r.stderr
    f.write_text('[[lineset]]\nname = "v"\nobjects = ["teapot"]\n')
    r = cli(["render", str(SAMPLES / "still_life.glb"), "--orbit", "2", "--style", str(f), "--out", str(out)])
    assert r.exit_code == 1
    assert f"{f}: line 3: key 'objects' (lineset 1 'v'): line set 'v' names object(s) 'teapot'" in r.stderr, r.stderr
    assert not any(out.glob("*.svg"))


# --- widths -----------------------------------------------------------------------------------------

def test_along_head_body_tail_only_the_body_stretches():
    """Seed 000's head, body and tail: the head and tail keep their lengths, the body between
    takes what the stroke adds; the width drawn (linear between the points) follows the profile
    within WIDTH_TOL_PX (and what the profile bends between samples at most SAMPLE_PX apart)."""
    from strokekit.style import widths as W

    style = one_set(Along(head=8, tail=12, tip=0.25))

    def ease(x):
        x = np.clip(x, 0, 1)
        return x * (2 - x)

    for length in (40.0, 100.0):
        st = apply_style(line([[0, 0], [length, 0]]), (), style)
        s, w = st.strokes.arc_length, st.width
        assert w[0] == pytest.approx(0.5) and w[-1] == pytest.approx(0.5)  # tip x width
        assert np.allclose(w, 2.0 * (0.25 + 0.75 * np.minimum(ease(s / 8), ease((length - s) / 12))))
        x = np.linspace(0, length, 4001)
        want = 2.0 * (0.25 + 0.75 * np.minimum(ease(x / 8), ease((length - x) / 12)))
        assert np.abs(np.interp(x, s, w) - want).max() <= W.WIDTH_TOL_PX + 0.003
        assert np.abs(np.interp(x, s, w)[(x >= 8) & (x <= length - 12)] - 2.0).max() <= W.WIDTH_TOL_PX
    short = apply_style(line([[0, 0], [10, 0]]), (), style)  # head + tail shrink together: 4 and 6 px
    assert np.interp(4.0, short.strokes.arc_length, short.width) == pytest.approx(2.0, abs=W.WIDTH_TOL_PX)


def test_no_head_or_tail_where_two_strokes_of_a_line_meet():
    """A line drawn as two strokes meeting end to end (joins): full width at the joint."""
    st = apply_style(line([[0, 0], [50, 0], [50, 0], [100, 0]], offsets=[0, 2, 4]), (), one_set(Along(head=8, tail=8)))
    w, o = st.width, st.strokes.offsets
    assert w[o[1] - 1] == pytest.approx(2.0) and w[o[1]] == pytest.approx(2.0)  # the joint
    assert w[0] == pytest.approx(0.5) and w[-1] == pytest.approx(0.5)  # the free ends


def test_the_close_ends_are_the_k_d_tree_s_pairs():
    """The joins' candidate pairs (joins.close_pairs, a sort on x) are scipy's cKDTree.query_pairs
    (distance <= r), clusters, coincident points and points exactly r apart included."""
    from scipy.spatial import cKDTree

    from strokekit.style.joins import close_pairs

    rng = np.random.default_rng(3)
    for n, spread in ((0, 10.0), (1, 10.0), (40, 5.0), (400, 300.0), (2000, 1000.0)):
        E = rng.uniform(0, spread, (n, 2))
        if n > 4:
            E[1] = E[0]  # coincident
            E[3] = E[2] + [2.5, 0.0]  # exactly r apart
            E[4] = E[2] + [0.0, 2.5]
        a, b = close_pairs(E, 2.5)
        want = cKDTree(E).query_pairs(2.5, output_type="ndarray") if n else np.zeros((0, 2), int)
        assert (a < b).all()
        assert sorted(zip(a.tolist(), b.tolist())) == sorted(map(tuple, want.tolist()))

def test_depth_width_between_near_and_far():
    cam = Camera(eye=(0, 0, 10), target=(0, 0, 0), up=(0, 1, 0), fov_y=40, width=200, height=200)
    p = np.array([[10.0, 100], [190, 100]])
    s = Strokes.build(p, np.array([[-1, 0, 2.0], [1, 0, -2.0]]), [-1, -1], [0, 2], [0], camera=cam)
    st = apply_style(s, (), one_set(Depth(near=3, far=0.5, near_depth=8, far_depth=12)))
    z = cam.depth(st.strokes.surface)
    want = 2.0 * (3 + (0.5 - 3) * np.clip((z - 8) / 4, 0, 1))
    assert np.allclose(st.width, want) and len(st.width) > 2  # (points every 16 px)


def test_curvature_thins_the_corners():
    st = apply_style(line([[0, 0], [30, 0], [30, 30]]), (), one_set(Curvature(flat=1, curved=0.25, radius=10, span=3)))
    s, w = st.strokes.arc_length, st.width
    assert w[np.isclose(s, 30)] == pytest.approx(0.5)  # the corner: 90 degrees over 3 px
    assert np.allclose(w[np.abs(s - 30) >= 3.0], 2.0)  # straight beyond the span


def test_calligraphy_is_thin_along_the_nib():
    st = apply_style(line([[0, 0], [20, 0], [20, 20]]), (), one_set(Calligraphy(angle=0, thin=0.2, span=1)))
    s, w = st.strokes.arc_length, st.width
    assert np.allclose(w[s < 19], 0.4)  # horizontal: along a 0-degree nib
    assert np.allclose(w[s > 21], 2.0)  # vertical: across it


def test_noise_is_a_function_of_u_and_the_id_and_boils_at_its_rate():
    pts = [[0, 0], [200, 0]]
    style = one_set(Noise(amplitude=0.4, wavelength=20))
    x = np.linspace(0, 200, 401)

    def width_along(st):  # the drawn width at fixed arc lengths (the points added depend on the noise)
        return np.interp(x, st.strokes.arc_length, st.width)

    a = apply_style(line(pts, ids=[7], frame=1), (), style)
    b = apply_style(line(pts, ids=[7], frame=2), (), style)
    c = apply_style(line(pts, ids=[8], frame=1), (), style)
    assert np.array_equal(a.width, b.width)  # no boil: the same from frame to frame
    assert not np.allclose(width_along(a), width_along(c), atol=0.05)  # another stroke, another noise
    assert a.width.min() >= 2.0 * 0.6 - 1e-9 and a.width.max() <= 2.0 * 1.4 + 1e-9
    boil = one_set(Noise(amplitude=0.4, wavelength=20, boil=2))
    w = [width_along(apply_style(line(pts, ids=[7], frame=f), (), boil)) for f in range(1, 9)]
    changed = [not np.array_equal(w[i], w[i + 1]) for i in range(7)]
    assert changed == [True, False, True, False, True, False, True]  # new at frames 2, 4, 6, 8
    x = np.linspace(-3, 3, 601)
    n = value_noise(x, np.full(len(x), 5), 0, 0)
    assert np.abs(np.diff(n)).max() < 0.02  # smooth


def test_selection_first_set_wins_and_unselected_strokes_are_not_drawn():
    s = line([[0, 0], [10, 0], [0, 5], [10, 5], [0, 9], [10, 9]], offsets=[0, 2, 4, 6])
    s = Strokes.build(s.points, s.surface, s.face, s.offsets, [KIND_INDEX["silhouette"], KIND_INDEX["crease"],
                                                               KIND_INDEX["border"]])
    style = Style(sets=(LineSet("a", kinds=("crease",), width=3.0), LineSet("b", kinds=("crease", "silhouette"))))
    st = apply_style(s, (), style)
    assert st.kept.tolist() == [True, True, False]
    assert st.lineset.tolist() == [1, 0] and st.width.tolist() == [1.5, 1.5, 3.0, 3.0]


def test_the_compiled_widths_are_the_numpy_formulas_and_hold_between_points():
    """The kernel's widths at every point (the strokes' own and those added) are numpy's
    modifier_factor product (the formulas' reference), on a perspective frame's curved, joined and
    short strokes under all five modifiers; and at every sample (each segment of the strokes given
    split evenly, at most SAMPLE_PX apart) the width drawn, linear between the points, is within
    WIDTH_TOL_PX of the formula; the points added are samples, on the strokes given."""
    from strokekit.style import widths as W

    cam = Camera(eye=(0, 0, 10), target=(0, 0, 0), up=(0, 1, 0), fov_y=40, width=200, height=200)
    t = np.linspace(0, 2 * np.pi, 40)
    a = np.c_[100 + 60 * np.cos(t), 100 + 40 * np.sin(3 * t)]
    b = np.array([[5.0, 5], [60, 8], [61, 30], [61.2, 30.1]])
    c = np.array([[150.0, 150], [151, 151.5]])
    p = np.r_[a, b, c]
    surface = np.c_[(p - 100) / 40, np.linspace(-2, 2, len(p))]
    s = Strokes.build(p, surface, np.full(len(p), -1), [0, len(a), len(a) + 4, len(p)], [0, 0, 0], ids=[3, 4, 5],
                      camera=cam, frame=3)
    mods = (Along(head=10, tail=16), Depth(near=1.6, far=0.6), Curvature(flat=1, curved=0.5, radius=8, span=3),
            Calligraphy(angle=30, thin=0.4, span=2), Noise(amplitude=0.25, wavelength=24))
    st = apply_style(s, (), one_set(*mods))
    assert len(st.strokes.points) > 2 * len(p)  # (points were added)
    base = np.array([2.0])
    ref = W._width_at(W.Sites.of_points(st.strokes), st.lineset, st.sets, base, st.free, st.depth_range)
    assert np.abs(st.width - ref).max() < 1e-9
    # the samples of the strokes given
    sop, arc = s.stroke_of_point, s.arc_length
    i = np.flatnonzero(sop[1:] == sop[:-1])
    d = arc[i + 1] - arc[i]
    n = np.where(d > W.SAMPLE_PX, np.ceil(d / W.SAMPLE_PX), 1).astype(int)
    i_of = np.repeat(i, n)
    j = np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)
    at = arc[i_of] + d[np.repeat(np.arange(len(i)), n)] * j / n[np.repeat(np.arange(len(i)), n)]
    k = sop[i_of]
    want = W._width_at(W.Sites.of_points(s).at(k, at), st.lineset, st.sets, base, st.free, st.depth_range)
    o, arc2 = st.strokes.offsets, st.strokes.arc_length
    drawn = np.concatenate([np.interp(at[k == q], arc2[o[q]:o[q + 1]], st.width[o[q]:o[q + 1]]) for q in range(3)])
    assert np.abs(drawn - want).max() <= W.WIDTH_TOL_PX + 1e-9
    # every point is a point given or one of the samples
    sample_xy = W.Sites.of_points(s).at(k, at).P
    gap = np.min(np.linalg.norm(st.strokes.points[:, None] - np.r_[sample_xy, p][None], axis=2), axis=1)
    assert gap.max() < 1e-9


def test_the_compiled_outline_text_is_the_numpy_writer_s():
    """writers.outline's compiled writer gives numpy's text to the byte: discs, coincident
    points, hairpins, turns past 90 degrees, negative and large coordinates, 0 to 4 decimals,
    and a subset of the strokes (members); numbers it does not take go to numpy's writer."""
    from strokekit.writers.outline import outline_path_data_numpy

    rng = np.random.default_rng(7)
    for trial in range(200):
        n = rng.integers(1, 8, rng.integers(1, 6))
        pts = rng.normal(0, 20, (n.sum(), 2)) * [1, 0.001, 300][trial % 3]
        if len(pts) > 2 and trial % 4 == 0:
            pts[1] = pts[0]  # a point twice
        if len(pts) > 2 and trial % 5 == 0:
            pts[2] = pts[0]  # back where it came from
        r = rng.uniform(0.01, 5, len(pts))
        off = np.r_[0, np.cumsum(n)]
        for dec in (0, 1, 2, 3, 4):
            assert outline_path_data(pts, off, r, dec) == outline_path_data_numpy(pts, off, r, dec)
        mem = np.sort(rng.choice(len(n), rng.integers(1, len(n) + 1), replace=False))
        full = outline_path_data_numpy(pts, off, r, 2)
        assert outline_path_data(pts, off, r, 2, members=mem) == [full[k] for k in mem]
    huge = np.array([[0.0, 0.0], [3e13, 1.0]])
    assert outline_path_data(huge, np.array([0, 2]), np.ones(2)) == outline_path_data_numpy(huge, np.array([0, 2]),
                                                                                         np.ones(2))


def test_the_nearest_visible_depth_is_the_nearest_vertex_when_it_is_in_view():
    """The depth modifier's default range: its near end is the scene's nearest vertex where that
    one is in the image (not the 16 px probes' nearest, which miss it), the probes' where the
    nearest vertex is out of the image."""
    from strokekit.raster.rays import surface_depth_at
    from strokekit.scene.load import build_scene
    from strokekit.scene.occluder import Occluder
    from strokekit.style.widths import style_context

    # a pyramid pointing at the camera: its apex (a vertex) is the nearest visible point
    V = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0], [0.13, 0.07, 1.0]], float)
    F = np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4], [0, 2, 1], [0, 3, 2]])
    scene = build_scene(V, F)
    occ = Occluder(scene)
    style = one_set(Depth(near=2, far=1))
    empty = line(np.zeros((0, 2)), offsets=[0])
    cam = Camera(eye=(0, 0, 5), target=(0, 0, 0), up=(0, 1, 0), fov_y=40, width=200, height=200)
    ctx = style_context(style, scene, cam, empty, surface_depth_at(occ))
    assert ctx.depth_range[0] == pytest.approx(4.0)  # the apex, exactly
    # the apex out of the image: the probes' nearest (farther than the apex)
    side = Camera(eye=(0, 0, 5), target=(3, 0, 0), up=(0, 1, 0), fov_y=40, width=200, height=200)
    z = style_context(style, scene, side, empty, surface_depth_at(occ)).depth_range
    assert z is None or z[0] > side.depth(V[4:5])[0]



def test_the_depth_probes_outside_the_scene_s_screen_box_are_skipped_without_changing_the_range():
    """style_context casts its 16 px probes only inside the image of the scene's bounding box (a
    probe outside it hits nothing): the probes it casts hit the same depths as the whole grid,
    and the range is the whole grid's; a box reaching behind the near plane casts them all."""
    from strokekit.raster.rays import surface_depth_at
    from strokekit.scene.load import build_scene
    from strokekit.scene.occluder import Occluder
    from strokekit.style.widths import DEPTH_GRID_PX, style_context

    # a bowl facing the camera (its deepest point inside, no line there), off the image centre
    g = np.linspace(-1, 1, 9)
    X, Y = np.meshgrid(g, g)
    V = np.c_[X.ravel() + 0.4, Y.ravel() - 0.2, 0.5 * (X.ravel() ** 2 + Y.ravel() ** 2)]
    F = []
    for r in range(8):
        for c in range(8):
            a = 9 * r + c
            F += [[a, a + 1, a + 10], [a, a + 10, a + 9]]
    scene = build_scene(V, np.array(F))
    occ = Occluder(scene)
    style = one_set(Depth(near=2, far=1))
    empty = line(np.zeros((0, 2)), offsets=[0])
    cast = []

    def probes(camera, px):
        cast.append(len(px))
        return surface_depth_at(occ)(camera, px)

    for cam, fewer in ((Camera(eye=(0, 0, 5), target=(0, 0, 0), up=(0, 1, 0), fov_y=40, width=200, height=160), True),
                       (Camera(eye=(0.4, -0.2, 0.3), target=(0.4, -0.2, 0), up=(0, 1, 0), fov_y=60, width=64,
                               height=64), False)):
        cast.clear()
        z = style_context(style, scene, cam, empty, probes).depth_range
        xs = np.arange(0.5 * DEPTH_GRID_PX, cam.width, DEPTH_GRID_PX)
        ys = np.arange(0.5 * DEPTH_GRID_PX, cam.height, DEPTH_GRID_PX)
        gx, gy = np.meshgrid(xs, ys)
        every = surface_depth_at(occ)(cam, np.stack([gx.ravel(), gy.ravel()], 1))
        every = every[np.isfinite(every)]
        assert len(every) and z[1] == float(every.max())
        assert (sum(cast) < gx.size) if fewer else (sum(cast) == gx.size)  # (the second eye is inside the box)


def test_the_nearest_vertex_leaves_out_vertices_of_no_face():
    """A vertex no face uses is no visible point: the nearest visible depth is the nearest vertex
    of a face."""
    from strokekit.scene.load import Scene
    from strokekit.style.widths import _nearest_vertex_depth

    V = np.array([[-1, -1, 0], [1, -1, 0], [0, 1, 0], [0, 0, 2.0], [0.2, 0.1, 0.5]], float)
    F = np.array([[0, 1, 4], [1, 2, 4], [2, 0, 4]])
    scene = Scene(V, F, np.zeros(3, np.int32), np.zeros(3, np.int32))
    cam = Camera(eye=(0, 0, 5), target=(0, 0, 0), up=(0, 1, 0), fov_y=40, width=200, height=200)
    assert list(scene.face_vertex_ids) == [0, 1, 2, 4]
    assert _nearest_vertex_depth(scene, cam) == pytest.approx(4.5)  # not the free vertex's 3.0

# --- SVG --------------------------------------------------------------------------------------------

def _ink(svg: str, scale: float = 4.0) -> np.ndarray:
    cairosvg = pytest.importorskip("cairosvg")
    from PIL import Image

    png = cairosvg.svg2png(bytestring=svg.encode(), scale=scale)
    return np.asarray(Image.open(io.BytesIO(png)).convert("RGBA"))[..., 3] / 255.0


def test_an_outline_is_the_union_of_its_segments_and_discs():
    """The filled outline (nonzero fill) covers what each segment's trapezoid and a disc at each
    point cover, drawn as separate shapes: no notch at a join, no hole at a sharp turn or a
    hairpin, nothing outside."""
    P = np.array([[10, 10], [50, 20], [20, 40], [80, 60], [80, 61], [30, 61.5], [100, 100], [101, 40]], float)
    R = np.array([1, 3, 2, 4, 4, 1, 2, 3], float)
    (d,) = outline_path_data(P, np.array([0, len(P)]), R)
    ref = []
    for i in range(len(P) - 1):
        t = (P[i + 1] - P[i]) / np.linalg.norm(P[i + 1] - P[i])
        n = np.array([-t[1], t[0]])
        q = [P[i] + n * R[i], P[i + 1] + n * R[i + 1], P[i + 1] - n * R[i + 1], P[i] - n * R[i]]
        ref.append('<polygon points="' + " ".join(f"{x:.4f},{y:.4f}" for x, y in q) + '"/>')
    ref += [f'<circle cx="{x}" cy="{y}" r="{r}"/>' for (x, y), r in zip(P, R)]
    head = '<svg xmlns="http://www.w3.org/2000/svg" width="120" height="120">'
    mine = _ink(head + f'<path d="{d}"/></svg>')
    union = _ink(head + '<g fill="black">' + "".join(ref) + "</g></svg>")
    assert np.abs(mine - union).max() < 0.5  # anti-aliasing differs along edges only
    assert abs(mine.sum() - union.sum()) / union.sum() < 0.01


def _styled_svg(style, strokes, **kw) -> str:
    return svg_document(strokes, 120, 60, ("silhouette",), styled=apply_style(strokes, ("silhouette",), style), **kw)


def test_the_svg_draws_a_varying_width_as_an_outline_with_its_centreline(tmp_path):
    s = line([[10, 30], [60, 10], [110, 30]])
    svg = _styled_svg(one_set(Along(head=20, tail=20), width=6.0), s)
    assert 'fill="#000000" stroke="none" data-centreline="M10.00 30.00' in svg
    (tmp_path / "o.svg").write_text(svg)
    (tmp_path / "c.svg").write_text(_styled_svg(one_set(Along(head=20, tail=20), width=6.0), s, lines="centreline"))
    a, b = read_svg(tmp_path / "o.svg"), read_svg(tmp_path / "c.svg")
    assert np.allclose(a.layers["silhouette"].points[[0, -1]], [[10, 30], [110, 30]])
    assert a.layers["silhouette"].length == pytest.approx(b.layers["silhouette"].length)
    ink = _ink(svg, 4.0).sum() / 16.0
    st = apply_style(s, (), one_set(Along(head=20, tail=20), width=6.0))
    seg = st.strokes.segment_lengths[1:]
    want = (0.5 * (st.width[1:] + st.width[:-1]) * seg).sum()
    assert ink == pytest.approx(want, rel=0.03)


def test_a_constant_width_stroke_stays_a_centreline_and_the_default_svg_is_unchanged():
    s = line([[10, 30], [60, 10], [110, 30]])
    default = svg_document(s, 120, 60, ("silhouette",))
    assert default == svg_document(s, 120, 60, ("silhouette",), styled=apply_style(s, ("silhouette",), Style()))
    assert 'stroke="#000000" stroke-linecap="round" stroke-linejoin="round" stroke-width="1.5"><path d="M10.00 30.00' \
        in default
    wide = _styled_svg(Style(sets=(LineSet("all", width=4.0, color="#123456"),)), s)
    assert 'stroke="#123456"' in wide and 'stroke-width="4"' in wide and "fill=\"#123456\"" not in wide


def test_a_set_without_a_colour_draws_each_kind_in_its_own():
    """A line set with no `color` draws its silhouettes, creases and borders in their kinds'
    colours (as without a style), in the SVG and the ribbons' materials; its JSON colour is null."""
    from strokekit.style.linesets import KIND_COLORS
    from strokekit.writers.strokes_json import strokes_json

    s = line([[10, 10], [100, 10], [10, 40], [100, 40]], ids=[1, 2], offsets=[0, 2, 4])
    s = s.replace(kind=np.array([KIND_INDEX["silhouette"], KIND_INDEX["crease"]], s.kind.dtype))
    styled = apply_style(s, ("silhouette", "crease"), Style(sets=(LineSet("all", width=2.0),)))
    svg = svg_document(s, 120, 60, ("silhouette", "crease"), styled=styled)
    sil, crease = svg.index('id="layer-silhouette"'), svg.index('id="layer-crease"')
    assert f'stroke="{KIND_COLORS["silhouette"]}"' in svg[sil:sil + 200]
    assert f'stroke="{KIND_COLORS["crease"]}"' in svg[crease:crease + 200]
    assert json.loads(strokes_json(s, 120, 60, 1, styled=styled))["linesets"][0]["color"] is None
    assert styled.color(0, "border") == KIND_COLORS["border"]
    own = apply_style(s, ("silhouette", "crease"), Style(sets=(LineSet("all", color="#123456"),)))
    assert own.color(0, "crease") == "#123456"


def test_the_default_json_has_no_widths_and_a_style_file_s_has():
    """Without a style file the frame JSON keeps the keys it always had (its bytes: same_bytes)."""
    from strokekit.writers.strokes_json import strokes_json

    s = line([[10, 30], [60, 10], [110, 30]])
    default = json.loads(strokes_json(s, 120, 60, 1, layers=("silhouette",)))
    assert "linesets" not in default and {"width", "lineset"}.isdisjoint(default["strokes"][0])
    assert strokes_json(s, 120, 60, 1, styled=apply_style(s, (), Style(width=3.0))) == strokes_json(s, 120, 60, 1)
    styled = json.loads(strokes_json(s, 120, 60, 1, styled=apply_style(s, (), one_set(width=3.0))))
    assert styled["linesets"][0]["name"] == "all" and styled["strokes"][0]["width"] == [3.0, 3.0, 3.0]


def test_several_sets_in_a_layer_get_a_group_each(tmp_path):
    """Hidden strokes one surface deep in one set, deeper ones in another: one Inkscape layer
    (hidden-silhouette), a group per set in it."""
    s = line([[10, 10], [100, 10], [10, 40], [100, 40]], ids=[1, 2], offsets=[0, 2, 4])
    k = KIND_INDEX["silhouette"]
    s = Strokes.build(s.points, s.surface, s.face, s.offsets, [k + 8, k + 16], ids=s.ids)
    style = Style(sets=(LineSet("behind1", occlusion=(1, 1), width=3.0, color="#ff0000"),
                        LineSet("deeper", occlusion=(2, 15), color="#0000ff", dashes=())))
    svg = svg_document(s, 120, 60, ("hidden-silhouette",), styled=apply_style(s, (), style))
    assert 'id="hidden-silhouette--behind1" inkscape:label="behind1" stroke="#ff0000" stroke-dasharray="36 9"' in svg
    assert 'id="hidden-silhouette--deeper" inkscape:label="deeper" stroke="#0000ff" stroke-width="1.5">' in svg
    (tmp_path / "a.svg").write_text(svg)
    assert set(read_svg(tmp_path / "a.svg").layers) == {"hidden-silhouette"}  # the sets' groups are no layers


def test_dashed_outlines_are_one_outline_per_dash(tmp_path):
    s = line([[0, 30], [100, 30]])
    style = Style(sets=(LineSet("d", width=4.0, dashes=(10.0, 10.0), thickness=(Along(head=30, tail=30),)),))
    svg = _styled_svg(style, s)
    d = svg.split('<path d="')[1].split('"')[0]
    assert d.count("M") == 5 and d.count("Z") == 5
    (tmp_path / "a.svg").write_text(svg)
    assert read_svg(tmp_path / "a.svg").layers["silhouette"].length == pytest.approx(100.0)  # the centreline


# --- the run: JSON, SVG, ribbons, shortcuts --------------------------------------------------------

def test_the_run_writes_widths_in_the_json_svg_and_ribbons(tmp_path, cli, models_dir):
    f = tmp_path / "s.toml"
    f.write_text(MINIMAL)
    out = tmp_path / "out"
    r = cli(["render", str(models_dir / "spot.obj"), "--orbit", "4", "--frames", "1", "--size", "256x256",
                 "--style", str(f), "--gltf", "--ribbon-space", "image", "--lines-png", "--out", str(out), "-q"])
    assert r.exit_code == 0, r.stderr
    doc = json.loads((out / "frame_0001.json").read_text())
    assert [s["name"] for s in doc["linesets"]] == ["lineset1"] and len(doc["depth_range"]) == 2
    for s in doc["strokes"]:
        assert s["lineset"] == "lineset1" and s["kind"] in ("silhouette", "border")
        assert len(s["width"]) == len(s["points"])
    widths = np.concatenate([s["width"] for s in doc["strokes"]])
    assert widths.min() < 1.5 and widths.max() > 3.0  # depth x along: not one width
    assert "data-centreline" in (out / "frame_0001.svg").read_text()


def test_the_shortcuts_write_the_same_style_as_a_file(tmp_path, cli, models_dir):
    f = tmp_path / "s.toml"
    f.write_text("width = 2.5\n")
    a, b = tmp_path / "a", tmp_path / "b"
    common = ["render", str(models_dir / "spot.obj"), "--orbit", "2", "--size", "200x200", "-q"]
    assert cli([*common, "--stroke-width", "2.5", "--out", str(a)]).exit_code == 0
    assert cli([*common, "--style", str(f), "--out", str(b)]).exit_code == 0
    for name in ("frame_0001.svg", "frame_0002.json", ".strokekit-run.json"):
        assert (a / name).read_bytes() == (b / name).read_bytes()
    assert 'stroke-width="2.5"' in (a / "frame_0001.svg").read_text()


def test_ribbon_flags_with_a_style_of_line_sets_are_a_usage_error(tmp_path, cli):
    f = tmp_path / "s.toml"
    f.write_text(MINIMAL)
    r = cli(["render", str(MODELS / "spot.obj"), "--orbit", "2", "--style", str(f), "--gltf", "--taper", "0",
                 "--out", str(tmp_path / "o")])
    assert r.exit_code == 2 and "--taper" in r.stderr


def test_lines_raster_draws_the_widths():
    from strokekit.raster.strokes import stroke_coverage

    s = line([[10, 20], [90, 20]])
    st = apply_style(s, (), one_set(Along(head=40, tail=40, tip=0.1), width=8.0))
    pytest.importorskip("numba")
    cov = stroke_coverage(st.strokes, 100, 40, st.width)["silhouette"]
    area = cov.sum()
    seg = st.strokes.segment_lengths[1:]
    want = (0.5 * (st.width[1:] + st.width[:-1]) * seg).sum()
    assert area == pytest.approx(want, rel=0.05)
    assert cov[:, 50].sum() == pytest.approx(8.0, abs=0.2) and cov[:, 15].sum() < 4.0


def test_style_validation():
    with pytest.raises(UsageError):
        LineSet("x", kinds=("silhouettes",))
    with pytest.raises(UsageError):
        Depth(near_depth=2.0)
    with pytest.raises(UsageError):
        Style(sets=(LineSet("a"), LineSet("a")))
    assert math.isclose(Style().width, 1.5)


def test_gallery_styles_read():
    """The docs' gallery style files are valid."""
    gallery = Path(__file__).resolve().parents[1] / "docs" / "gallery"
    files = sorted(gallery.glob("*.toml"))
    for f in files:
        read_style(f)


def test_a_style_file_draws_a_moving_scene_with_its_objects_points(tmp_path, cli):
    """A style on a scene that moves (a turntable): every stroke of the frame JSON has its line
    set, one width per point, and each point's object and object point, which the frame's
    object matrices map back onto its surface point; the SVG and the GLB are written."""
    import trimesh
    from animated import turntable_glb

    ball = trimesh.creation.icosphere(subdivisions=3)
    turn = turntable_glb(tmp_path / "turn.glb", ball.vertices, ball.faces, frames=3)
    style = tmp_path / "s.toml"
    style.write_text(MINIMAL)
    r = cli(["render", str(turn), "--orbit", "3", "--size", "96x96", "--style", str(style), "--strokes", "lines",
             "--gltf", "--out", str(tmp_path / "o"), "-q"])
    assert r.exit_code == 0, r.stderr
    for n in (1, 2, 3):
        d = json.loads((tmp_path / "o" / f"frame_{n:04d}.json").read_text())
        assert d["time"] == pytest.approx((n - 1) / 24) and d["linesets"][0]["name"]
        M = np.array([o["matrix"] for o in d["objects"]])
        assert d["strokes"]
        for st in d["strokes"]:
            k = len(st["points"])
            assert len(st["width"]) == len(st["object"]) == len(st["local"]) == k and st["lineset"]
            obj, local = np.array(st["object"]), np.array(st["local"])
            back = np.einsum("nij,nj->ni", M[obj][:, :3, :3], local) + M[obj][:, :3, 3]
            assert np.allclose(back, np.array(st["surface"]), atol=1e-6)
            assert min(st["width"]) > 0
        assert (tmp_path / "o" / f"frame_{n:04d}.svg").exists() and (tmp_path / "o" / f"frame_{n:04d}.glb").exists()
