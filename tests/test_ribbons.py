"""Ribbon geometry (strokekit.ribbons): area, joins without overlap, no NaN or flipped triangles on
degenerate input, uv along the stroke, width in pixels from the frame's camera."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from shapely.geometry import Polygon
from shapely.ops import unary_union

from strokekit.camera.view import Camera
from strokekit.model import Strokes
from strokekit.ribbons.mesh import RibbonOptions, build_ribbons

CAM = Camera(eye=(0.0, 0.0, 5.0), target=(0.0, 0.0, 0.0), width=1024, height=1024)
FLAT = RibbonOptions(space="image", taper_head_px=0.0, taper_tail_px=0.0, width_px=4.0)


def strokes_of(polys, u=None, camera=CAM, surface=None):
    pts = np.concatenate([np.asarray(p, float).reshape(-1, 2) for p in polys])
    off = np.r_[0, np.cumsum([len(p) for p in polys])]
    surf = np.zeros((len(pts), 3)) if surface is None else surface
    return Strokes.build(pts, surf, np.zeros(len(pts)), off, np.zeros(len(polys)), u=u, camera=camera)


def tri_xy(mesh, s=None):
    """(T, 3, 2) triangle corners in the image-space positions (x, H - y), for stroke s or all."""
    idx = mesh.indices if s is None else mesh.indices[mesh.triangle_offsets[s]:mesh.triangle_offsets[s + 1]]
    return mesh.positions[:, :2][idx]


def signed_areas(t):
    a, b, c = t[:, 0], t[:, 1], t[:, 2]
    return 0.5 * ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))


def union_and_sum(mesh, s):
    t = tri_xy(mesh, s)
    return unary_union([Polygon(x) for x in t]).area, signed_areas(t).sum()


def arc(t0, t1, n, r=150.0, c=(512.0, 512.0)):
    th = np.linspace(t0, t1, n)
    return np.stack([c[0] + r * np.cos(th), c[1] + r * np.sin(th)], 1)


CURVES = {
    "straight": np.array([[100.0, 100.0], [700.0, 180.0]]),
    "straight_many_points": np.stack([np.linspace(50, 900, 40), np.linspace(900, 60, 40)], 1),
    "arc": arc(0, 1.5 * np.pi, 80),
    "coarse_arc": arc(0.3, 2.8, 12, r=200),
    "sine": np.stack([np.linspace(50, 950, 200), 500 + 80 * np.sin(np.linspace(0, 4 * np.pi, 200))], 1),
    "spiral": np.stack([500 + np.linspace(60, 300, 150) * np.cos(np.linspace(0, 5 * np.pi, 150)),
                        500 + np.linspace(60, 300, 150) * np.sin(np.linspace(0, 5 * np.pi, 150))], 1),
}


@pytest.mark.parametrize("name", sorted(CURVES))
def test_area_is_length_times_width_and_joins_do_not_overlap(name):
    """Image-space ribbon without taper: area = length x width (1%), and the triangles do not
    overlap (union area = sum of areas, 0.5%): the joins fill gaps and remove inner overlaps."""
    s = strokes_of([CURVES[name]])
    m = build_ribbons(s, CAM, FLAT)
    union, total = union_and_sum(m, 0)
    expect = s.lengths[0] * FLAT.width_px
    assert union == pytest.approx(expect, rel=0.01)
    assert total == pytest.approx(union, rel=0.005)


@pytest.mark.parametrize("turn_deg", [30.0, 90.0, 120.0, 150.0])
def test_corner_join_fills_the_outer_gap_without_inner_overlap(turn_deg):
    """One sharp corner between two long segments: no overlap (union = sum) and no gap: the
    ribbon covers every point within width/2 of the centreline except beyond the bevel
    (miter limit 4 keeps turns up to ~151 degrees mitred)."""
    th = np.radians(turn_deg)
    p = np.array([[200.0, 500.0], [500.0, 500.0], [500.0 + 300.0 * np.cos(th), 500.0 + 300.0 * np.sin(th)]])
    m = build_ribbons(strokes_of([p]), CAM, FLAT)
    union, total = union_and_sum(m, 0)
    assert total == pytest.approx(union, rel=0.005)
    # the ribbon contains the centreline buffered by w/2 with flat ends, minus nothing at the joint
    # (a mitred outer corner contains the round one)
    from shapely.geometry import LineString

    pix = np.c_[p[:, 0], CAM.height - p[:, 1]]
    band = LineString(pix).buffer(FLAT.width_px / 2 * 0.999, cap_style=2, join_style=1)
    shape = unary_union([Polygon(x) for x in tri_xy(m, 0)])
    assert band.difference(shape).area < 1e-3 * band.area


def test_flat_and_square_caps_match_shapely_for_mitred_polyline():
    """A zig-zag with moderate turns equals shapely's mitred buffer of the same polyline: with square
    caps by default (free ends run on by half the width, as the SVG's round caps reach), with flat
    caps at cap 0."""
    from shapely.geometry import LineString

    p = np.array([[100, 100], [300, 160], [420, 100], [600, 220], [800, 200]], float)
    pix = np.c_[p[:, 0], CAM.height - p[:, 1]]
    for o, cap_style in ((FLAT, 3), (replace(FLAT, cap=0.0), 2)):
        m = build_ribbons(strokes_of([p]), CAM, o)
        ref = LineString(pix).buffer(o.width_px / 2, cap_style=cap_style, join_style=2, mitre_limit=o.miter_limit)
        shape = unary_union([Polygon(x) for x in tri_xy(m, 0)])
        assert shape.symmetric_difference(ref).area < 1e-6 * ref.area


DEGENERATE = {
    "duplicate_points": [[100, 100], [100, 100], [200, 100], [200, 100], [200, 100], [300, 150]],
    "hairpin": [[100, 100], [300, 100], [100, 100.0]],
    "near_hairpin": [[100, 100], [300, 100], [100, 100.3]],
    "back_and_forth": [[100, 100], [110, 100], [100, 100], [110, 100], [100, 100.5], [120, 101]],
    "tiny_segments": [[100, 100], [100 + 1e-9, 100], [100 + 1e-7, 100 + 1e-7], [100.5, 100.2], [130, 140]],
    "all_same": [[50, 50], [50, 50], [50, 50]],
    "single_point": [[10, 10]],
    "short_vs_width": [[100, 100], [100.5, 100], [100.6, 100.5], [100.2, 100.9], [100.3, 101]],
}


@pytest.mark.parametrize("space", ["image", "world"])
def test_degenerate_strokes_give_finite_unflipped_triangles(space):
    """Zero-length segments, hairpins and back-and-forth turns: no NaN, every triangle keeps the
    ribbon's orientation (counter-clockwise seen from the camera), strokes with no length have
    empty ranges and the others keep their triangles."""
    names = sorted(DEGENERATE)
    s = strokes_of([DEGENERATE[n] for n in names])
    opts = RibbonOptions(space=space, width_px=4.0)
    m = build_ribbons(s, CAM, opts)
    assert np.all(np.isfinite(m.positions)) and np.all(np.isfinite(m.uv))
    xy = m.pixels * [1, -1]  # y up, as seen from the camera
    assert np.all(signed_areas(xy[m.indices]) > 0)
    counts = np.diff(m.triangle_offsets)
    for i, n in enumerate(names):
        assert (counts[i] == 0) == (n in ("all_same", "single_point")), n
    # triangles of a stroke only use that stroke's vertices
    sv = m.stroke_of_vertex
    assert np.all(sv[m.indices] == m.stroke_of_triangle[:, None])


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 40), st.integers(0, 40)), min_size=2, max_size=25),
       st.floats(0.5, 12.0))
def test_random_polylines_never_flip_or_nan(pts, width):
    """Any polyline on a coarse grid (many repeats, reversals, collinear runs): finite vertices,
    all triangles counter-clockwise, none with zero area."""
    p = np.array(pts, float) * 2.5
    m = build_ribbons(strokes_of([p]), CAM, RibbonOptions(space="image", width_px=width))
    assert np.all(np.isfinite(m.positions))
    if len(m.indices):
        assert np.all(signed_areas(tri_xy(m)) > 0)


def _segment_uv(m, s):
    """Per quad of stroke s, texture u at its start and end (vertices come in rows of three)."""
    sl = slice(m.vertex_offsets[s], m.vertex_offsets[s + 1])
    return m.uv[sl], m.arc[sl], m.u_raw[sl]


def test_uv_monotone_along_each_stroke_and_v_across():
    """u never runs backwards inside a texture piece, it only jumps back from the end of the body
    (1 - tex_tail) to its start (tex_head) where the stroke's u crosses an integer; arc length and
    the stroke parameter are monotone; v takes the values 0, 0.5, 1."""
    o = RibbonOptions(space="image", width_px=4.0)
    s = strokes_of([CURVES["sine"], CURVES["arc"], CURVES["straight"]])
    m = build_ribbons(s, CAM, o)
    assert set(np.unique(m.uv[:, 1])) <= {0.0, 0.5, 1.0}
    lo, hi = o.tex_head, 1 - o.tex_tail
    for k in range(len(s)):
        uv, a, ur = _segment_uv(m, k)
        centre = uv[:, 1] == 0.5  # one centre vertex per quad end, in order along the stroke
        uc, ac, urc = uv[centre, 0], a[centre], ur[centre]
        assert np.all(np.diff(ac) >= -1e-9) and np.all(np.diff(urc) >= -1e-9)
        du = np.diff(uc)
        back = du < -1e-9
        # going back is only the body wrapping around, from its end to its start, at an integer u
        assert np.allclose(uc[:-1][back], hi) and np.allclose(uc[1:][back], lo)
        assert np.allclose(urc[1:][back], np.round(urc[1:][back]))
        assert uc[0] == 0.0 and uc[-1] == pytest.approx(1.0)


def test_brush_top_row_is_on_the_left_of_the_direction_of_travel():
    """v = 0 (a brush image's top row) lies on the left of the direction the stroke is drawn in:
    above a stroke running left to right on screen, below one running right to left, and on
    the outer side of a turn it keeps its side. An asymmetric brush (ink, dry, a user's PNG)
    was mirrored across every ribbon."""
    o = RibbonOptions(space="image", width_px=4.0, taper_head_px=0.0, taper_tail_px=0.0)
    for pts, above in (([[100.0, 300.0], [400.0, 300.0]], True), ([[400.0, 300.0], [100.0, 300.0]], False),
                       ([[100.0, 300.0], [250.0, 300.0], [250.0, 150.0]], True)):
        m = build_ribbons(strokes_of([pts]), CAM, o)
        first = m.pixels[:3]  # the first segment's start row (it runs along y = 300)
        y0, y1 = first[m.uv[:3, 1] == 0.0, 1], first[m.uv[:3, 1] == 1.0, 1]
        assert (y0 < 300.0).all() == above and (y1 > 300.0).all() == above  # pixels: y down
        if len(pts) == 3:  # a left turn: its outer join corner (252, 302) is on the right side
            corner = np.linalg.norm(m.pixels - [252.0, 302.0], axis=1) < 1e-9
            assert corner.any() and (m.uv[corner, 1] == 1.0).all()


def test_head_and_tail_keep_their_size_while_the_body_repeats_with_u():
    """The head region covers the same pixels on a short and a long stroke; in the body the
    texture u is tex_head + body * frac(strokes.u), whatever the offset of u."""
    o = RibbonOptions(space="image", width_px=4.0, head_px=8.0, tail_px=12.0, cap=0.0)  # (the head at point 0)
    short = np.array([[100.0, 100.0], [180.0, 100.0]])
    long_ = np.array([[100.0, 300.0], [700.0, 300.0]])
    s = strokes_of([short, long_])
    u = np.r_[0.37 + s.arc_length[:2] / 17.0, 5.81 + s.arc_length[2:] / 23.0]
    s = strokes_of([short, long_], u=u)
    m = build_ribbons(s, CAM, o)
    bw = 1 - o.tex_head - o.tex_tail
    for k, L in ((0, 80.0), (1, 600.0)):
        uv, a, ur = _segment_uv(m, k)
        head = a < o.head_px - 1e-9
        assert np.allclose(uv[head, 0], o.tex_head * a[head] / o.head_px)
        tail = a > L - o.tail_px + 1e-9
        assert np.allclose(uv[tail, 0], 1 - o.tex_tail + o.tex_tail * (a[tail] - (L - o.tail_px)) / o.tail_px)
        body = ~head & ~tail & (np.abs(a - (L - o.tail_px)) > 1e-9) & (np.abs(a - o.head_px) > 1e-9)
        frac = (uv[body, 0] - o.tex_head) / bw
        # frac(u), compared on the circle (at the period seam a vertex holds 1 or 0)
        d = (frac - ur[body]) % 1.0
        assert np.allclose(np.minimum(d, 1 - d), 0, atol=1e-9)
        assert np.all((frac >= -1e-12) & (frac <= 1 + 1e-12))


def test_taper_narrows_the_ends_only():
    """Tapered ribbon: full width in the middle, taper_min x width at both tips."""
    o = RibbonOptions(space="image", width_px=6.0, taper_head_px=20.0, taper_tail_px=30.0, taper_min=0.2)
    s = strokes_of([np.array([[100.0, 100.0], [500.0, 100.0]])])
    m = build_ribbons(s, CAM, o)
    ys = m.pixels[:, 1]
    a = m.arc
    width_at = {}
    for x in np.unique(np.round(a, 9)):
        sel = np.isclose(a, x)
        width_at[x] = ys[sel].max() - ys[sel].min()
    assert width_at[0.0] == pytest.approx(0.2 * 6.0)
    assert width_at[max(width_at)] == pytest.approx(0.2 * 6.0)
    mids = [w for x, w in width_at.items() if 20.0 <= x <= 370.0]
    assert np.allclose(mids, 6.0)
    assert np.all(np.diff([width_at[x] for x in sorted(width_at) if x <= 20.0]) > 0)


@pytest.mark.parametrize("projection", ["perspective", "orthographic"])
def test_world_ribbons_have_the_requested_pixel_width_from_the_frame_camera(projection):
    """World placement: each vertex projects back onto its pixel outline (so the ribbon is
    width_px wide on screen), lies nearer to the camera than the surface point it hangs on, and
    the offset stays in the plane facing the camera (same depth as its centre vertex)."""
    cam = Camera(eye=(3.0, 2.0, 6.0), target=(0.0, 0.0, 0.0), fov_y=35.0, width=800, height=600,
                 projection=projection, ortho_height=4.0)
    t = np.linspace(0, 2 * np.pi, 60, endpoint=False)
    surf = np.stack([np.cos(t), 0.5 * np.sin(2 * t), np.sin(t)], 1)
    px, _ = cam.project(surf)
    s = strokes_of([px], camera=cam, surface=surf)
    o = RibbonOptions(space="world", width_px=5.0, taper_head_px=0, taper_tail_px=0, pull=0.01, cap=0.0)
    m = build_ribbons(s, cam, o)
    back, z = cam.project(m.positions)
    assert np.abs(back - m.pixels).max() < 1e-6
    zs = cam.depth(surf)
    assert np.all(z < zs.max())
    # the outline on screen is a band of width_px around the stroke: area = length x width
    shape = unary_union([Polygon(x) for x in m.pixels[m.indices]])
    assert shape.area == pytest.approx(s.lengths[0] * 5.0, rel=0.01)
    # every vertex sits at the depth of the stroke point it hangs on, pulled toward the camera;
    # points inserted inside a segment lie on the 3D segment (1/z is linear on screen)
    # (orthographic too: by the fraction pull of its depth, so a vertex never crosses the eye plane)
    if projection == "perspective":
        on_stroke = 1.0 / np.interp(m.arc, s.arc_length, 1.0 / zs)
    else:
        on_stroke = np.interp(m.arc, s.arc_length, zs)
    assert np.allclose(z, on_stroke * (1 - o.pull), rtol=1e-6)


def test_options_are_checked():
    from strokekit.errors import UsageError

    with pytest.raises(UsageError):
        RibbonOptions(width_px=0)
    with pytest.raises(UsageError):
        RibbonOptions(space="screen")
    with pytest.raises(UsageError):
        RibbonOptions(tex_head=0.6, tex_tail=0.5)


def test_real_strokes_overlap_less_than_half_a_percent():
    """Strokes of a shared model (spot, orbit camera): summed over all strokes, triangle area
    exceeds the union area by < 0.5% (overlaps only where a jagged silhouette turns sharply over
    segments shorter than the width), and union area = length x width within 1%."""
    from pathlib import Path

    model = Path(__file__).resolve().parents[2] / "shared" / "models" / "spot.obj"
    if not model.exists():
        pytest.skip(f"shared model not found: {model}")
    from strokekit.camera.paths import orbit_path
    from strokekit.lines.renderer import LineRenderer
    from strokekit.options import LineOptions
    from strokekit.scene.load import load_scene

    sc = load_scene(model)
    cam = orbit_path(sc.center, sc.radius, 8).cameras[1]
    s = LineRenderer(sc, LineOptions()).render(cam, 2)
    assert len(s) > 10
    m = build_ribbons(s, cam, RibbonOptions(space="image", width_px=3.0, taper_head_px=0, taper_tail_px=0, cap=0.0))
    total = union = 0.0
    for k in range(len(s)):
        t = tri_xy(m, k)
        if len(t):
            total += signed_areas(t).sum()
            union += unary_union([Polygon(x) for x in t]).area
    assert (total - union) / total < 0.005
    assert union == pytest.approx(s.lengths.sum() * 3.0, rel=0.01)


def test_world_ribbons_are_not_hidden_by_the_surface_they_outline():
    """A sphere's silhouette ribbon, composited with the sphere: every ribbon triangle must be in
    front of the surface (the first hit along its eye ray is not nearer). At the stroke's own
    depth the half of the ribbon inside the rim was behind the bulging surface."""
    import trimesh

    from strokekit.lines.renderer import LineRenderer
    from strokekit.options import LineOptions
    from strokekit.raster.rays import surface_depth_at
    from strokekit.scene.load import build_scene

    ico = trimesh.creation.icosphere(subdivisions=4)
    scene = build_scene(ico.vertices, ico.faces)
    cam = Camera(eye=(0.0, 0.0, 5.0), target=(0.0, 0.0, 0.0), width=400, height=300)
    r = LineRenderer(scene, LineOptions())
    strokes = r.render(cam, 1)
    o = RibbonOptions(width_px=3.0)

    def hidden_share(mesh):
        c = mesh.positions[mesh.indices].mean(axis=1)
        d = c - cam.eye
        dist = np.linalg.norm(d, axis=1)
        loc, ray, _ = ico.ray.intersects_location(np.repeat([cam.eye], len(c), 0), d / dist[:, None],
                                                  multiple_hits=False)
        first = np.full(len(c), np.inf)
        first[ray] = np.linalg.norm(loc - cam.eye, axis=1)
        return float(np.mean(first < dist * (1 - 1e-6)))

    assert hidden_share(build_ribbons(strokes, cam, o)) > 0.3  # the inner half
    assert hidden_share(build_ribbons(strokes, cam, o, surface_depth_at(r.occluder))) == 0.0


@pytest.mark.parametrize("projection", ["perspective", "orthographic"])
def test_a_section_view_keeps_its_near_plane_in_the_glb(projection):
    """A camera with `near` cutting into the model (a section view): the ribbons lie beyond the
    near plane (pulled a little toward the eye), orthographic too, and the glTF camera's znear
    stays at the section, so a viewer hides what the drawing cut away. Surface rays from the
    camera plane put 29% of an orthographic section's vertices in front of it, and znear went
    down to half the nearest ribbon depth."""
    import json
    import struct

    from helpers import model_path

    from strokekit.lines.renderer import LineRenderer
    from strokekit.options import LineOptions
    from strokekit.raster.rays import surface_depth_at
    from strokekit.scene.load import load_scene
    from strokekit.writers.gltf import GltfOptions, glb_for_frame

    s = load_scene(model_path("spot.obj"))
    c, R = np.asarray(s.center), s.radius
    near = 2.7 * R
    cam = Camera(eye=tuple(c + [0.0, 0.0, 3 * R]), target=tuple(c), width=300, height=300, fov_y=40.0,
                 projection=projection, ortho_height=2.5 * R, near=near)
    r = LineRenderer(s, LineOptions())
    st = r.render(cam, 1)
    o = RibbonOptions(width_px=3.0)
    m = build_ribbons(st, cam, o, surface_depth_at(r.occluder))
    assert cam.depth(m.positions).min() >= near * (1 - o.pull) * (1 - 1e-6)
    glb = glb_for_frame(st, cam, GltfOptions(), surface_depth_at(r.occluder))
    n = struct.unpack_from("<I", glb, 12)[0]
    assert json.loads(glb[20:20 + n])["cameras"][0][projection]["znear"] > 0.99 * near


# --- joins: one line drawn as two strokes ---------------------------------------------------------

TAPERED = RibbonOptions(space="image", width_px=4.0, taper_head_px=8.0, taper_tail_px=12.0, head_px=4.0,
                        tail_px=8.0, taper_min=0.25)


def _ends_width(m, k):
    """(width at the start, width at the end) of stroke k's ribbon, and the pixels of its two end rows."""
    v = slice(m.vertex_offsets[k], m.vertex_offsets[k + 1])
    P, A = m.pixels[v], m.arc[v]
    rows = [P[np.isclose(A, A.min())], P[np.isclose(A, A.max())]]
    return [np.linalg.norm(r[:, None] - r[None], axis=2).max() for r in rows], rows


def _two_pieces(turn_deg=10.0, gap=0.0, kinds=(0, 0), sideways=0.0):
    """A line cut into two strokes at (300, 500): the second turns by turn_deg there and starts
    `gap` px further along (and `sideways` px beside it)."""
    a = np.c_[np.linspace(100, 300, 21), np.full(21, 500.0)]
    th = np.radians(turn_deg)
    start = np.array([300.0 + gap, 500.0 + sideways])
    b = start + np.c_[np.cos(th), np.sin(th)] * np.linspace(0, 200, 21)[:, None]
    pts = np.concatenate([a, b])
    return Strokes.build(pts, np.zeros((42, 3)), np.zeros(42), [0, 21, 42], list(kinds), camera=CAM)


@pytest.mark.parametrize("gap, sideways", [(0.0, 0.0), (0.8, 0.0), (0.5, 1.0)])
def test_a_join_has_no_tapered_vertices_at_the_joined_ends(gap, sideways):
    """Two strokes of one line meeting end to end (or a stair-step, the second a pixel beside the
    first): full width and the brush's body at the joint, one end edge shared by both ribbons (no
    pinch, no hole, no overlap); the free ends keep their taper."""
    s = _two_pieces(gap=gap, sideways=sideways)
    m = build_ribbons(s, CAM, TAPERED)
    (w0, w1), rows0 = _ends_width(m, 0)
    (v0, v1), rows1 = _ends_width(m, 1)
    assert w1 >= 4.0 - 1e-9 and v0 >= 4.0 - 1e-9  # the joined ends: full width (the miter a little more)
    assert w0 == pytest.approx(1.0) and v1 == pytest.approx(1.0)  # the free ends: taper_min x width
    assert np.allclose(np.sort(rows0[1], axis=0), np.sort(rows1[0], axis=0))  # one shared end edge
    # the texture at the joint is the body's, neither the head's nor the tail's
    for k, end in ((0, "max"), (1, "min")):
        v = slice(m.vertex_offsets[k], m.vertex_offsets[k + 1])
        at = np.isclose(m.arc[v], getattr(m.arc[v], end)())
        assert np.all((m.uv[v][at, 0] >= TAPERED.tex_head) & (m.uv[v][at, 0] <= 1 - TAPERED.tex_tail))
    # no hole and no overlap at the joint
    from shapely.geometry import LineString, box

    both = unary_union([Polygon(x) for x in tri_xy(m)])
    near = box(280, 1024 - 530, 320, 1024 - 470)
    joint = [300 + gap / 2, 500 + sideways / 2]  # (both ends moved to the middle of the two)
    line = np.array([s.points[19], joint, s.points[22], s.points[23]])
    band = LineString(np.c_[line[:, 0], 1024 - line[:, 1]]).buffer(1.9, cap_style=2).intersection(near)
    assert band.difference(both).area < 1e-3 * band.area
    total = signed_areas(tri_xy(m)).sum()
    assert total == pytest.approx(both.area, rel=1e-3)


def test_ends_that_do_not_continue_one_line_stay_free():
    """A corner (the line turns 80 degrees), two kinds, an end too far: every end tapers."""
    for s in (_two_pieces(turn_deg=80.0), _two_pieces(kinds=(0, 2)), _two_pieces(gap=3.0)):
        m = build_ribbons(s, CAM, TAPERED)
        for k in range(2):
            assert _ends_width(m, k)[0] == pytest.approx([1.0, 1.0])


def test_a_closed_loop_has_no_taper():
    """A circle whose last point repeats its first: one line without ends, full width all round
    and the start and end rows the same edge."""
    t = np.linspace(0, 2 * np.pi, 90)
    p = np.c_[512 + 200 * np.cos(t), 512 + 200 * np.sin(t)]
    p[-1] = p[0]
    m = build_ribbons(strokes_of([p]), CAM, TAPERED)
    (w0, w1), rows = _ends_width(m, 0)
    assert w0 == pytest.approx(w1) and w0 >= 4.0 - 1e-9
    assert np.allclose(np.sort(rows[0], axis=0), np.sort(rows[1], axis=0))
    ends = RibbonOptions(space="image", width_px=4.0, taper_head_px=8.0, taper_tail_px=12.0, join_px=0.0)
    assert _ends_width(build_ribbons(strokes_of([p]), CAM, ends), 0)[0] == pytest.approx([1.0, 1.0])


def test_the_default_brush_reads_as_ink_with_its_texture():
    """The default brush's body covers nearly all of the ribbon's width at nearly full density
    (a ribbon 3 px wide, mipmapped down to a few texels across, must read as ink, not mid-grey),
    and still varies along the stroke (its streaks and edges are its texture)."""
    from strokekit.ribbons.brushes import brush_rgba, get_brush
    from strokekit.writers.gltf import GltfOptions

    a = brush_rgba(get_brush(GltfOptions().brush).png)[..., 3].astype(float) / 255
    body = a[:, 64:192]  # (texture u 0.25 to 0.75)
    assert body.mean() >= 0.93
    across = body.mean(axis=1)  # the mipmap's view: its rows averaged along the stroke
    assert across[2:-2].min() >= 0.9
    assert np.ptp(body[8:24], axis=1).min() >= 0.03  # its density varies along the stroke (streaks)
