"""Raster pass, toon bands, band masks/polygons and self-similar fills (issue 5)."""

from __future__ import annotations

import io
import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import trimesh

from strokekit.camera.paths import dolly_path, orbit_path
from strokekit.camera.view import Camera
from strokekit.errors import UsageError
from strokekit.lines.renderer import LineRenderer
from strokekit.metrics.svg_reader import read_svg
from strokekit.model import KINDS
from strokekit.options import LineOptions
from strokekit.raster.bands import (
    RasterOptions,
    band_ramps,
    band_regions,
    label_polygons,
    quantize_bands,
    render_raster,
)
from strokekit.raster.fill import fill_field, octave_weights, self_similar_field
from strokekit.raster.rays import cast_pixels
from strokekit.run.tasks import raster_outputs
from strokekit.sampling import segment_samples
from strokekit.scene.load import Material, build_scene, load_scene
from strokekit.scene.occluder import Occluder
from strokekit.writers.png import png_files, read_png
from strokekit.writers.svg import bands_layer

MODELS = Path(__file__).resolve().parents[1].parent / "shared" / "models"


def _model(name):
    p = MODELS / name
    if not p.exists():
        pytest.skip(f"shared model {p} not available")
    return load_scene(p)


@pytest.fixture(scope="module")
def sphere():
    m = trimesh.creation.icosphere(subdivisions=4, radius=1.0)
    return build_scene(m.vertices + [3.0, -2.0, 1.0], m.faces, materials=(Material("red", (0.9, 0.2, 0.1, 1.0)),))


@pytest.fixture(scope="module")
def sphere_occ(sphere):
    return Occluder(sphere)


# --- rays -----------------------------------------------------------------------------------------

@pytest.mark.parametrize("projection", ["perspective", "orthographic"])
@pytest.mark.parametrize("K", [1, 2])
def test_rays_go_through_sample_centres_and_depth_is_view_z(sphere, sphere_occ, projection, K):
    """Each hit, projected back with the camera of BRIEF 1.1, lands on its sample's centre
    ((i + 0.5) / K output px), its depth is the view z, and the barycentrics rebuild the point."""
    cam = Camera(eye=(3.5, -1.0, 5.0), target=(3.0, -2.0, 1.0), fov_y=35, width=48, height=36,
                 projection=projection, ortho_height=2.6)
    h = cast_pixels(cam, sphere_occ, K)
    assert h.shape == (36 * K, 48 * K)
    rows, cols = np.nonzero(h.hit)
    assert len(rows) > 0.2 * h.face.size
    P = h.position[rows, cols]
    xy, z = cam.project(P)
    assert np.abs(xy[:, 0] - (cols + 0.5) / K).max() < 1e-6
    assert np.abs(xy[:, 1] - (rows + 0.5) / K).max() < 1e-6
    assert np.allclose(z, h.depth[rows, cols])
    tri = sphere.vertices[sphere.faces[h.face[rows, cols]]]
    u, v = h.bary[rows, cols].T.astype(float)
    Q = (1 - u - v)[:, None] * tri[:, 0] + u[:, None] * tri[:, 1] + v[:, None] * tri[:, 2]
    assert np.abs(Q - P).max() < 1e-4 * sphere.radius
    # On a unit sphere every hit is at distance 1 from its centre.
    assert np.abs(np.linalg.norm(P - [3.0, -2.0, 1.0], axis=1) - 1.0).max() < 2e-3
    assert np.isinf(h.depth[~h.hit]).all()


def _all_rays(h, cam, occ):
    right, up, fwd = cam.basis
    d = fwd + h.ray_dir_x[None, :, None] * right + h.ray_dir_y[:, None, None] * up
    near = cam.near_distance(occ.radius)
    o = np.asarray(cam.eye) + near * d
    return occ.first_hits(o.reshape(-1, 3), d.reshape(-1, 3))["primitive_ids"].reshape(h.shape)


def test_ray_culling_loses_no_hit(sphere, sphere_occ):
    """Rays are only cast in blocks touched by some triangle: casting every sample gives the same."""
    m = trimesh.creation.icosphere(subdivisions=2, radius=0.05)
    # A big sphere and a tiny far one: most blocks are skipped, thin parts must not be.
    scene = build_scene(np.concatenate([m.vertices * 20, m.vertices + [1.5, 0.3, 0]]),
                        np.concatenate([m.faces, m.faces + len(m.vertices)]))
    occ = Occluder(scene)
    cam = Camera(eye=(0.0, 0.0, 5.0), target=(0.0, 0.0, 0.0), fov_y=40, width=160, height=120)
    for K in (1, 2):
        h = cast_pixels(cam, occ, K)
        assert np.array_equal(_all_rays(h, cam, occ), h.face)
        assert 0 < h.hit.sum() < 0.5 * h.face.size
        assert (h.face >= len(m.faces)).sum() > 0  # the tiny sphere is seen


def test_triangles_crossing_the_near_plane_fall_back_to_all_rays():
    box = trimesh.creation.box(extents=(10.0, 10.0, 10.0))
    scene = build_scene(box.vertices, box.faces)
    occ = Occluder(scene)
    cam = Camera(eye=(1.0, 0.5, 2.0), target=(0.0, 0.0, -5.0), fov_y=60, width=40, height=30)
    h = cast_pixels(cam, occ, 1)
    assert h.hit.all()  # inside the room every ray meets a wall
    assert np.array_equal(_all_rays(h, cam, occ), h.face)


# --- bands ----------------------------------------------------------------------------------------

def test_quantize_follows_seed_formula_and_thresholds():
    ndl = np.array([np.nan, -0.5, 0.0, 0.33, 0.34, 0.5, 0.999, 1.0], np.float32)
    assert quantize_bands(ndl, 3).tolist() == [0, 1, 1, 1, 2, 2, 3, 3]
    assert quantize_bands(ndl, 1).tolist() == [0, 1, 1, 1, 1, 1, 1, 1]
    assert quantize_bands(ndl, 2, (0.2, 0.9)).tolist() == [0, 1, 1, 2, 2, 2, 3, 3]
    opts = RasterOptions(thresholds=(0.2, 0.9))
    assert opts.bands == 3


@pytest.mark.parametrize("bad", [dict(bands=0), dict(thresholds=(0.5, 0.3)), dict(shading="phong"),
                                 dict(supersample=3), dict(light=(0, 0, 0)), dict(light_space="screen"),
                                 dict(fill_pattern="plaid"), dict(fill_period_px=0)])
def test_bad_options_are_usage_errors(bad):
    with pytest.raises(UsageError):
        RasterOptions(**bad)


@pytest.mark.parametrize("angle", [0.0, 180.0])
def test_the_smooth_angle_is_the_raster_options_and_checked(angle):
    """Shading splits its normals at its own angle (RasterOptions.smooth_angle_deg), the lines
    at theirs (LineOptions.crease_angle_deg): a bad one is a usage error either way."""
    with pytest.raises(UsageError, match="smooth_angle_deg"):
        RasterOptions(smooth_angle_deg=angle)
    with pytest.raises(UsageError):
        LineOptions(crease_angle_deg=angle)


def test_smooth_shading_keeps_a_cad_plate_flat_around_its_countersunk_holes():
    """A plate with holes countersunk at 45 degrees, in isometric: smooth shading split at the
    lines' 60 degrees smoothed the rim's normal into the plate's long thin top triangles, a dark
    band smeared across the flat plate from each hole (--shading flat was clean). Split at the
    shading's own 30 degrees (Blender's auto smooth), every plate-top sample has the flat
    label, and the countersinks still shade smoothly (more than one band in them)."""
    from helpers import countersunk_plate

    from strokekit.camera.paths import parallel_path

    plate = build_scene(*countersunk_plate())
    cam = parallel_path(plate.center, plate.radius, "isometric", width=500, height=400, up_axis="z").cameras[0]
    # (a light whose n.l on the plate, 0.75, lies just above a band threshold, 2/3: the smear
    # of tilted normals crosses it)
    opts = RasterOptions(bands=3, light=(0.7, 0.3, 0.75), light_space="world")
    flat = render_raster(plate, cam, None, replace(opts, shading="flat"))
    hit = flat.hits.hit
    face = flat.hits.face[hit]
    top = plate.face_normals[face, 2] > 1 - 1e-9
    sink = np.abs(plate.face_normals[face, 2] - np.sqrt(0.5)) < 0.05  # (facets of a 45-degree cone)
    assert top.sum() > 20000 and sink.sum() > 1000
    smooth = render_raster(plate, cam, None, opts).labels_ss[hit]
    assert np.array_equal(smooth[top], flat.labels_ss[hit][top])
    assert len(np.unique(smooth[sink])) > 1
    smeared = render_raster(plate, cam, None, replace(opts, smooth_angle_deg=60.0)).labels_ss[hit]
    assert (smeared[top] != flat.labels_ss[hit][top]).sum() > 5000  # the smear, split at 60 degrees


@pytest.mark.parametrize("shading", ["flat", "smooth"])
def test_band_labels_match_analytic_sphere_lighting(sphere, sphere_occ, shading):
    """On a sphere the true normal is (P - c) / r: bands from n.l agree with the analytic ones
    except on a thin rim around band borders (flat facets shift them by a facet at most)."""
    cam = Camera(eye=(3.0, -2.0, 6.0), target=(3.0, -2.0, 1.0), fov_y=30, width=96, height=96)
    opts = RasterOptions(bands=4, supersample=1, shading=shading, light=(1.0, 1.0, 0.5), light_space="world")
    fr = render_raster(sphere, cam, sphere_occ, opts)
    hit = fr.hits.hit
    P = fr.hits.position[hit]
    n = P - np.array([3.0, -2.0, 1.0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    l = np.array([1.0, 1.0, 0.5]) / np.linalg.norm([1.0, 1.0, 0.5])
    true = quantize_bands((n @ l).astype(np.float32), 4)
    agree = (true == fr.labels_ss[hit]).mean()
    assert agree > (0.97 if shading == "flat" else 0.995)
    assert set(np.unique(fr.labels_ss[hit])) == {1, 2, 3, 4}
    assert (fr.labels_ss[~hit] == 0).all()


#: Toward the light for the box tests: its +x, +y, +z faces get n.l 0.15, 0.50, 0.85, three
#: bands far from the band thresholds 1/3 and 2/3.
BOX_LIGHT = (0.15, 0.5, 0.85)


@pytest.fixture(scope="module")
def box():
    m = trimesh.creation.box(extents=(2.0, 2.0, 2.0))
    return build_scene(np.asarray(m.vertices) + [1.0, 0.5, -2.0], np.asarray(m.faces))


@pytest.mark.parametrize("K", [1, 2])
def test_smooth_shading_keeps_box_faces_flat(box, K):
    """Smooth shading splits normals at edges sharper than --smooth-angle (default 30 deg): each
    visible face of a box is one band, and the band changes exactly where the hit moves to another
    face (at the box's edges). With an angle above 90 deg the edges are smoothed over and the
    faces get curved bands (what smooth shading did for every box before)."""
    occ = Occluder(box)
    cam = Camera(eye=(4.5, 3.5, 2.0), target=(1.0, 0.5, -2.0), fov_y=40, width=96, height=80)
    opts = RasterOptions(bands=3, supersample=K, shading="smooth", light=BOX_LIGHT, light_space="world")
    fr = render_raster(box, cam, occ, opts)
    hit = fr.hits.hit
    face = fr.hits.face[hit]
    lab = fr.labels_ss[hit]
    # The side of the box each sample hits, from its triangle's plane normal.
    side = np.argmax(box.face_normals[face], axis=1) + 3 * (box.face_normals[face].min(axis=1) < -0.5)
    assert sorted(np.unique(side)) == [0, 1, 2]  # the +x, +y, +z faces are seen
    expected = quantize_bands((box.face_normals[face] @ (np.array(BOX_LIGHT) / np.linalg.norm(BOX_LIGHT))), 3)
    assert np.array_equal(lab, expected)
    for sd, band in zip((0, 1, 2), (1, 2, 3)):
        assert set(np.unique(lab[side == sd])) == {band}
    # Label changes between neighbouring samples happen exactly where the box side changes.
    sides = np.full(fr.hits.shape, -1)
    sides[hit] = side
    for a, b in ((np.s_[:, 1:], np.s_[:, :-1]), (np.s_[1:, :], np.s_[:-1, :])):
        both = hit[a] & hit[b]
        assert np.array_equal((fr.labels_ss[a] != fr.labels_ss[b])[both], (sides[a] != sides[b])[both])
    # Flat shading gives the same labels on a box; smoothing across 90 deg edges does not.
    assert np.array_equal(render_raster(box, cam, occ, replace(opts, shading="flat")).labels_ss, fr.labels_ss)
    rounded = render_raster(box, cam, occ, replace(opts, smooth_angle_deg=120.0)).labels_ss[hit]
    assert any(len(np.unique(rounded[side == sd])) > 1 for sd in (0, 1, 2))


def test_smooth_angle_reaches_the_raster_pass_from_the_command_line(box, tmp_path, capsys):
    """`strokekit render --shading smooth` splits normals at --smooth-angle: the default keeps a
    cube's faces flat (same bands as --shading flat), --smooth-angle 120 rounds them; the lines'
    --crease-angle 120 leaves the shading as it is."""
    from strokekit_cli.main import main

    p = tmp_path / "box.obj"
    p.write_text("".join(f"v {x} {y} {z}\n" for x, y, z in box.vertices)
                 + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in box.faces))
    out = {}
    for name, extra in (("flat", ["--shading", "flat"]), ("smooth", ["--shading", "smooth"]),
                        ("rounded", ["--shading", "smooth", "--smooth-angle", "120"]),
                        ("creases", ["--shading", "smooth", "--crease-angle", "120"])):
        with pytest.raises(SystemExit) as e:
            main([str(a) for a in ["render", p, "--orbit", "1", "--elevation", "30", "--size", "64x64", "--bands", "3",
                                   "--no-svg", "--no-json", "-q", "--out", tmp_path / name, *extra]])
        assert e.value.code == 0, capsys.readouterr().err
        out[name] = read_png((tmp_path / name / "bands" / "frame_0001.png").read_bytes())
    assert (out["flat"] > 0).mean() > 0.1
    assert np.array_equal(out["smooth"], out["flat"]) and np.array_equal(out["creases"], out["flat"])
    assert not np.array_equal(out["rounded"], out["flat"])


def test_camera_space_light_follows_the_camera(sphere, sphere_occ):
    """A light given in camera space lights the same screen side from any viewpoint."""
    opts = RasterOptions(bands=2, supersample=1, light=(1.0, 0.0, 0.3), light_space="camera")
    for eye in [(3.0, -2.0, 6.0), (8.0, -2.0, 1.0), (3.0, 3.0, 1.001)]:
        cam = Camera(eye=eye, target=(3.0, -2.0, 1.0), up=(0, 1, 0), fov_y=30, width=64, height=64)
        lab = render_raster(sphere, cam, sphere_occ, opts).labels_ss
        left, right = lab[:, :32], lab[:, 32:]
        assert (right == 2).sum() > 5 * max((left == 2).sum(), 1)


def test_ramp_darkens_base_colour_and_gooch_goes_cool_to_warm(sphere):
    r = band_ramps(sphere, 3)
    assert np.allclose(r[0, -1], [0.9, 0.2, 0.1])
    assert np.all(np.diff(r[0].sum(axis=1)) > 0)
    g = band_ramps(sphere, 3, gooch=True)
    assert g[0, 0, 2] > g[0, 0, 0] and g[0, -1, 0] > g[0, -1, 2]


def test_masks_and_labels_are_consistent_and_antialiased(sphere, sphere_occ):
    cam = Camera(eye=(3.0, -2.0, 6.0), target=(3.0, -2.0, 1.0), fov_y=30, width=80, height=60)
    opts = RasterOptions(bands=3, supersample=4, masks=True, objectid=True, depth=True, shade=True)
    fr = render_raster(sphere, cam, sphere_occ, opts)
    cov = fr.coverage
    assert cov.shape == (60, 80, 4)
    assert np.allclose(cov.sum(axis=2), 1.0)
    # Anti-aliased: partial coverage exists along every border, and masks are 0..255 of it.
    assert ((cov[..., 0] > 0) & (cov[..., 0] < 1)).sum() > 50
    out = png_files(fr.images())
    assert sorted(out) == ["bands", "depth", "mask1", "mask2", "mask3", "objectid", "shade"]
    assert np.array_equal(read_png(out["bands"]), fr.labels)
    m2 = read_png(out["mask2"]).astype(float) / 255
    assert np.abs(m2 - cov[..., 2]).max() <= 0.5 / 255 + 1e-6
    # Majority label: where a band covers more than half of a pixel, the pixel carries it.
    assert np.all(fr.labels[cov[..., 2] > 0.5] == 2)
    shade = read_png(out["shade"])
    assert shade.shape == (60, 80, 4)
    assert np.array_equal(shade[..., 3], np.round((1 - cov[..., 0]) * 255).astype(np.uint8))
    ids = read_png(out["objectid"])
    assert set(np.unique(ids)) == {0, 1}
    depth = read_png(out["depth"])
    assert depth.dtype == np.uint16 and (depth[ids == 0] == 65535).all()
    assert depth[30, 40] < depth[ids == 1].max()  # the sphere's centre is its nearest point
    # Deterministic bytes.
    assert png_files(fr.images()) == raster_outputs(sphere, cam, sphere_occ, opts)


def test_only_asked_outputs_are_computed(sphere, sphere_occ, monkeypatch):
    cam = Camera(eye=(3.0, -2.0, 6.0), target=(3.0, -2.0, 1.0), fov_y=30, width=32, height=32)
    import strokekit.raster.fill as fill

    def boom(*a, **k):
        raise AssertionError("fill texture computed without being asked")

    import strokekit.raster.bands as bands

    monkeypatch.setattr(fill, "fill_ink", boom)
    monkeypatch.setattr(bands, "fill_coverage", boom)
    out = raster_outputs(sphere, cam, sphere_occ, RasterOptions(shade=False))
    assert list(out) == ["bands"]


def test_band_masks_agree_with_4x_reference_on_spot():
    """Bar: per band, IoU >= 0.99 between the z-buffer at supersample 2 and Embree rays at 4 x 4
    (the reference), and >= 0.999 for render's default (1 sample a pixel, edge pixels 4 x 4) and
    for 2 + 4."""
    scene = _model("spot.obj")
    occ = Occluder(scene)
    cam = orbit_path(scene.center, scene.radius, 1, width=512, height=512, start_azimuth=30).cameras[0]
    base = RasterOptions(bands=3, shading="smooth")
    ref = render_raster(scene, cam, occ, replace(base, supersample=4, edge_supersample=0), reference=True).coverage
    cov = {(K, R): render_raster(scene, cam, None, replace(base, supersample=K, edge_supersample=R)).coverage
           for K, R in ((2, 0), (1, 4), (2, 4))}
    for b in range(4):
        r = ref[..., b]
        iou = {k: np.minimum(c[..., b], r).sum() / np.maximum(c[..., b], r).sum() for k, c in cov.items()}
        assert iou[2, 0] >= 0.99 and iou[1, 4] >= 0.999 and iou[2, 4] >= 0.999, (b, iou)


# --- polygons -------------------------------------------------------------------------------------

def test_label_polygons_have_holes_and_exact_area():
    yy, xx = np.mgrid[0:60, 0:80]
    r = np.hypot(xx - 40, yy - 30)
    key = np.where(r < 10, 2, np.where(r < 25, 1, 0)).astype(np.int32)
    polys = label_polygons(key, tolerance_px=0.0)
    assert set(polys) == {1, 2}
    assert polys[1].area == (key == 1).sum() and polys[2].area == (key == 2).sum()
    assert polys[1].geom_type == "Polygon" and len(polys[1].interiors) == 1
    simp = label_polygons(key, tolerance_px=0.5)
    assert abs(simp[1].area - polys[1].area) < 0.5 * polys[1].length
    assert len(simp[1].exterior.coords) < len(polys[1].exterior.coords)
    assert simp[1].hausdorff_distance(polys[1]) <= 0.5 + 1e-9


def test_band_polygons_svg_layer(sphere, sphere_occ):
    cam = Camera(eye=(3.0, -2.0, 6.0), target=(3.0, -2.0, 1.0), fov_y=30, width=64, height=64)
    fr = render_raster(sphere, cam, sphere_occ, RasterOptions(bands=3, supersample=2, band_polygons=True))
    xml = bands_layer(band_regions(fr))
    assert 'inkscape:label="bands"' in xml and 'id="layer-bands"' in xml
    assert xml.count("<path") == len(np.unique(fr.labels[fr.labels > 0]))
    # Top band = the red base colour, linear (0.9, 0.2, 0.1) sRGB-encoded as SVG colours are
    # (written unencoded, #e6331a, the bands came out darker than any glTF viewer shows them).
    assert 'id="b0-3"' in xml and 'fill="#f37c59"' in xml
    # Each region is outlined in its own colour, 1 px wide, so that abutting anti-aliased regions
    # overlap and no light seam of background shows between bands.
    import re

    assert 'stroke-width="1"' in xml and 'stroke="none"' not in xml
    paths = re.findall(r"<path [^>]*>", xml)
    assert paths and all(re.search(r'fill="(#\w+)"', p)[1] == re.search(r'stroke="(#\w+)"', p)[1] for p in paths)


# --- lines and masks agree --------------------------------------------------------------------------

def _crack_midpoints(bg: np.ndarray) -> np.ndarray:
    """(n, 2) pixel-space midpoints of the unit edges between background and non-background pixels."""
    h = np.argwhere(bg[:, 1:] != bg[:, :-1])  # between (j, i) and (j, i+1)
    v = np.argwhere(bg[1:, :] != bg[:-1, :])
    return np.concatenate([np.stack([h[:, 1] + 1.0, h[:, 0] + 0.5], 1), np.stack([v[:, 1] + 0.5, v[:, 0] + 1.0], 1)])


def _dense(points: np.ndarray, offsets: np.ndarray, step: float = 0.2) -> np.ndarray:
    out = []
    for s in range(len(offsets) - 1):
        p = points[offsets[s]:offsets[s + 1]]
        for a, b in zip(p[:-1], p[1:]):
            n = max(int(np.ceil(np.linalg.norm(b - a) / step)), 1)
            out.append(a + (b - a) * (np.arange(n + 1) / n)[:, None])
    return np.concatenate(out)


def test_silhouettes_lie_on_background_mask_edge(sphere, sphere_occ):
    """Bar: silhouette strokes and the background mask's edge are within 1 px of each other,
    both ways (on a sphere every silhouette borders the background)."""
    from scipy.spatial import cKDTree

    cam = Camera(eye=(5.0, 0.5, 5.5), target=(3.0, -2.0, 1.0), fov_y=30, width=160, height=120)
    strokes = LineRenderer(sphere, LineOptions(kinds=("silhouette",))).render(cam)
    assert len(strokes) > 0 and set(strokes.kind.tolist()) == {KINDS.index("silhouette")}
    fr = render_raster(sphere, cam, sphere_occ, RasterOptions(supersample=2))
    cracks = _crack_midpoints(fr.labels == 0)
    pts = _dense(strokes.points, strokes.offsets)
    d_line_to_mask, _ = cKDTree(cracks).query(strokes.points)
    d_mask_to_line, _ = cKDTree(pts).query(cracks)
    assert d_line_to_mask.max() <= 1.0
    assert d_mask_to_line.max() <= 1.0


def test_background_edge_is_drawn_by_lines_on_spot():
    """On a real mesh every background edge of the mask is an outer silhouette (or border) of
    the line layer, within 1 px."""
    from scipy.spatial import cKDTree

    scene = _model("spot.obj")
    cam = orbit_path(scene.center, scene.radius, 1, width=256, height=256, start_azimuth=60).cameras[0]
    lr = LineRenderer(scene, LineOptions(kinds=("silhouette", "border")))
    strokes = lr.render(cam)
    fr = render_raster(scene, cam, lr.occluder, RasterOptions(supersample=2))
    cracks = _crack_midpoints(fr.labels == 0)
    d, _ = cKDTree(_dense(strokes.points, strokes.offsets)).query(cracks)
    assert d.max() <= 1.0, np.sort(d)[-5:]


# --- self-similar fills ---------------------------------------------------------------------------

def test_octave_weights_sum_to_one_and_wrap():
    s = np.linspace(0, 1, 11)
    a = octave_weights(s)
    assert np.allclose(a.sum(axis=1), 1.0)
    assert a[0, 0] == 0 and a[-1, 3] == 0
    assert np.allclose(a[-1, :3], a[0, 1:])  # octave i at the end of a cycle is octave i+1 at the start


def test_field_is_continuous_across_zoom_cycles():
    """The blend at z just below a power of two equals the one just above: no popping."""
    rng = np.random.default_rng(1)
    P = rng.uniform(-1, 1, size=(500, 3))
    obj = np.zeros(500, int)
    c, r = np.zeros((1, 3)), np.ones(1)
    for pat in ("hatch", "dots", "noise"):
        # pixel size 0.25 world units at period 16 px, radius 1: log2 z' = 2 exactly.
        lo = self_similar_field(P, obj, np.full(500, 0.25 * (1 - 1e-9)), c, r, 16.0, pat)
        hi = self_similar_field(P, obj, np.full(500, 0.25 * (1 + 1e-9)), c, r, 16.0, pat)
        assert np.abs(lo - hi).max() < 1e-5


def _centroid_period(img: np.ndarray) -> float:
    """Dominant period in px: 1 / power-weighted mean spatial frequency (Hann-windowed FFT)."""
    n = img.shape[0]
    w = np.hanning(n)
    a = (img - img.mean()) * w[:, None] * w[None, :]
    P = np.abs(np.fft.fft2(a)) ** 2
    f = np.hypot(np.fft.fftfreq(n)[:, None], np.fft.fftfreq(n)[None, :])
    m = f > 1.5 / n
    return float(P[m].sum() / (f[m] * P[m]).sum())


def test_fill_period_stays_constant_across_a_dolly(sphere, sphere_occ):
    """Bar: dolly 1x..8x; the dominant screen period of the fill image (central crop inside the
    sphere) stays within a factor 1.5 of its mean, while a fixed 3D texture would shrink 8x."""
    N = 384
    path = dolly_path(sphere.center, sphere.radius, 10, start=1.0, end=8.0, width=N, height=N)
    f = path.cameras[0].focal_px
    half = int(0.6 * f * np.sin(np.radians(20)) / (1.15 * 8))  # inside the sphere's disc at 8x
    opts = RasterOptions(bands=3, supersample=1, fill=True, fill_pattern="hatch", fill_period_px=16.0,
                         shade=False)
    periods, fixed = [], []
    for cam in path.cameras:
        fr = render_raster(sphere, cam, sphere_occ, opts)
        img = fr.fill_image()[N // 2 - half:N // 2 + half, N // 2 - half:N // 2 + half].astype(float)
        assert (fr.labels[N // 2 - half:N // 2 + half, N // 2 - half:N // 2 + half] > 0).all()
        periods.append(_centroid_period(img))
        # Control: the same texture at a fixed object-space scale (no zoom cycles).
        hit = fr.hits.hit
        P = fr.hits.position[hit]
        h = np.full(hit.shape, 0.0)
        h[hit] = self_similar_field(P, np.zeros(len(P), int), np.full(len(P), 4.0 / f), np.asarray([sphere.center]),
                                    np.ones(1), 16.0, "hatch")
        fixed.append(_centroid_period(h[N // 2 - half:N // 2 + half, N // 2 - half:N // 2 + half]))
    p = np.array(periods)
    assert p.max() <= 1.5 * p.mean() and p.mean() <= 1.5 * p.min(), p
    q = np.array(fixed)
    assert q[0] / q[-1] > 2.5, q  # the measurement does see scale changes


def test_fill_sticks_to_the_surface_when_the_camera_turns(sphere, sphere_occ):
    """Bar: no sliding. Turn the camera 6 degrees around the sphere at constant distance: the
    field at each surface point, looked up in the new frame where that point projects, keeps its
    value; looking up the same pixel instead (a screen-space texture) would not."""
    path = orbit_path(sphere.center, sphere.radius, 2, degrees_per_frame=6.0, width=200, height=200)
    a, b = path.cameras
    ha = cast_pixels(a, sphere_occ, 1)
    hb = cast_pixels(b, sphere_occ, 1)
    fa = fill_field(sphere, ha, 24.0, "noise")
    fb = fill_field(sphere, hb, 24.0, "noise")
    rows, cols = np.nonzero(ha.hit)
    X = ha.position[rows, cols]
    xy, z = b.project(X)
    u, v = xy[:, 0] - 0.5, xy[:, 1] - 0.5
    i0, j0 = np.floor(u).astype(int), np.floor(v).astype(int)
    ok = (i0 >= 0) & (j0 >= 0) & (i0 < 199) & (j0 < 199)
    i0, j0, u, v, z, rows, cols = i0[ok], j0[ok], u[ok], v[ok], z[ok], rows[ok], cols[ok]
    corners = [(j0, i0), (j0, i0 + 1), (j0 + 1, i0), (j0 + 1, i0 + 1)]
    # Keep points visible in b with all four neighbours on the same surface (depth agrees).
    vis = np.all([np.abs(hb.depth[c] - z) < 0.05 for c in corners], axis=0)
    assert vis.sum() > 5000
    tu, tv = (u - i0)[vis], (v - j0)[vis]
    vals = [fb[c][vis] for c in corners]
    interp = (1 - tv) * ((1 - tu) * vals[0] + tu * vals[1]) + tv * ((1 - tu) * vals[2] + tu * vals[3])
    here = fa[rows[vis], cols[vis]]
    stuck = np.abs(interp - here)
    slid = np.abs(fb[rows[vis], cols[vis]] - here)
    slid = slid[np.isfinite(slid)]
    assert np.median(stuck) < 0.01 and np.percentile(stuck, 99) < 0.05
    assert np.median(slid) > 5 * np.median(stuck)


def test_orthographic_zoom_keeps_fill_period(sphere, sphere_occ):
    """Orthographic zoom (ortho_height 1x..8x) acts like the dolly: the screen period holds."""
    N = 256
    periods = []
    for zoom in 2.0 ** np.linspace(0, 3, 6):
        cam = Camera(eye=(3.0, -2.0, 9.0), target=(3.0, -2.0, 1.0), width=N, height=N, projection="orthographic",
                     ortho_height=2.4 * zoom)
        fr = render_raster(sphere, cam, sphere_occ, RasterOptions(supersample=1, fill=True, shade=False))
        half = int(0.6 * N / (2.4 * 8) * 1.0)
        sl = slice(N // 2 - half, N // 2 + half)
        assert (fr.labels[sl, sl] > 0).all()
        periods.append(_centroid_period(fr.fill_image()[sl, sl].astype(float)))
    p = np.array(periods)
    assert p.max() <= 1.5 * p.mean() and p.mean() <= 1.5 * p.min(), p


@pytest.mark.parametrize("pattern", ["hatch", "dots", "noise"])
def test_tone_map_inks_each_band_by_its_darkness(sphere, sphere_occ, pattern):
    """Seed 003 4.2: thresholding the equalized texture by the band tone inks about that
    fraction of each band: darker bands get more marks."""
    from strokekit.raster.fill import band_darkness, fill_ink

    cam = Camera(eye=(3.0, -2.0, 5.0), target=(3.0, -2.0, 1.0), fov_y=40, width=200, height=200)
    fr = render_raster(sphere, cam, sphere_occ, RasterOptions(bands=3, supersample=1, fill_pattern=pattern,
                                                              fill_period_px=8.0))
    ink = fill_ink(sphere, fr.hits, fr.labels_ss, 3, pattern, 8.0)
    assert not ink[fr.labels_ss == 0].any()
    fractions = [ink[fr.labels_ss == b].mean() for b in (1, 2, 3)]
    for b, frac in zip((1, 2, 3), fractions):
        assert abs(frac - band_darkness(np.array(b), 3)) < 0.12, fractions
    assert fractions[0] > fractions[1] > fractions[2]


@pytest.mark.parametrize("scale, shift", [(1e-3, 0.0), (1e4, 0.0), (1.0, 1e5)])
def test_labels_do_not_depend_on_scene_scale_or_position(scale, shift):
    """The same view of a scaled / far translated sphere gives the same band labels (rays are
    cast in scene-centred float32 coordinates; the near plane is relative to the scene size)."""
    m = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    opts = RasterOptions(bands=3, supersample=1, shading="smooth")
    labels = []
    for s, t in ((1.0, 0.0), (scale, shift)):
        scene = build_scene(m.vertices * s + t, m.faces)
        cam = Camera(eye=(t + 0.5 * s, t + 0.8 * s, t + 4.0 * s), target=(t, t, t), fov_y=35, width=96, height=96)
        labels.append(render_raster(scene, cam, Occluder(scene), opts).labels)
    assert (labels[0] != labels[1]).mean() < 0.002
    assert (labels[0] > 0).mean() > 0.2


def test_pipeline_entry_points_agree(sphere, sphere_occ):
    """raster_file_suffixes names exactly the PNGs raster_outputs returns; the bands layer comes
    as picklable svgwrite elements that svg_document places under the line layers."""
    import pickle

    from strokekit.model import Strokes
    from strokekit.run.spec import raster_file_suffixes
    from strokekit.run.tasks import raster_outputs as ro
    from strokekit.run.tasks import raster_outputs_with_bands_layer
    from strokekit.writers.svg import svg_document

    cam = Camera(eye=(3.0, -2.0, 6.0), target=(3.0, -2.0, 1.0), fov_y=30, width=40, height=40)
    for opts in (RasterOptions(), RasterOptions(bands=2, masks=True, objectid=True, fill=True, shade=False),
                 RasterOptions(thresholds=(0.3,), depth=True, band_polygons=True)):
        out = ro(sphere, cam, sphere_occ, opts)
        assert list(out) == raster_file_suffixes(opts)
        pngs, layer = raster_outputs_with_bands_layer(sphere, cam, sphere_occ, opts)
        assert pngs == out and bool(layer) == opts.band_polygons
    svg = svg_document(Strokes.empty(), 40, 40, ("silhouette",), underlays=pickle.loads(pickle.dumps(layer)))
    assert svg.index('id="layer-bands"') < svg.index('id="layer-silhouette"')


def test_edge_supersample_matches_uniform_supersampling_at_edges(sphere, sphere_occ):
    """edge_supersample R resamples only the pixels at band/background edges R x R: the
    coverages then equal those of a uniform R x R supersampling, with far fewer rays."""
    cam = Camera(eye=(3.6, -1.2, 5.5), target=(3.0, -2.0, 1.0), fov_y=30, width=120, height=90)
    base = RasterOptions(bands=3, shading="smooth", edge_supersample=0)
    uniform = render_raster(sphere, cam, sphere_occ, replace(base, supersample=4)).coverage
    plain = render_raster(sphere, cam, sphere_occ, replace(base, supersample=1)).coverage
    for K in (1, 2):
        fr = render_raster(sphere, cam, sphere_occ, replace(base, supersample=K, edge_supersample=4))
        idx, _ = fr.edge_coverage
        assert len(idx) < 0.3 * 120 * 90  # only edge pixels are resampled
        assert np.abs(fr.coverage - uniform).max() < 1e-6
        assert np.allclose(fr.coverage.sum(axis=2), 1.0)
    assert np.abs(plain - uniform).max() > 0.2  # without it, K = 1 is visibly different
    with pytest.raises(UsageError):
        RasterOptions(supersample=2, edge_supersample=3)


def _thin_ribbon_scene():
    """A plane facing +z with two ribbons 0.3 px wide (at 8 px per world unit) in front of it,
    tilted nearly edge-on to the view so they fall in band 1 while the plane is in band 3, and
    running past the plane over the background: one along an image row, between the K = 2
    sample rows everywhere (orthographic view), one at 20 degrees."""
    quad = np.array([[0, 1, 2], [0, 2, 3]])
    plane = np.array([[-2, -2, 0], [2, -2, 0], [2, 2, 0], [-2, 2, 0]], float)

    def ribbon(p0, p1, w):
        return np.array([p0, p1, np.add(p1, w), np.add(p0, w)], float)

    # Rows y = 20.35 .. 20.65 px of the 64 px image: between the K = 2 sample rows 20.25 and
    # 20.75, on the K = 4 rows 20.375 and 20.625.
    y = 4 - 20.35 / 8
    row = ribbon([-3.5, y, 0.1], [3.5, y, 0.1], [0, -0.3 / 8, 0.5])
    a = np.radians(20.0)
    u, n = np.array([np.cos(a), np.sin(a), 0.0]), np.array([-np.sin(a), np.cos(a), 0.0])
    slant = ribbon(-3.5 * u + [0, -0.7, 0.1], 3.5 * u + [0, -0.7, 0.1], n * 0.3 / 8 + [0, 0, 0.5])
    return build_scene(np.r_[plane, row, slant], np.r_[quad, quad + 4, quad + 8])


@pytest.mark.parametrize("shading", ["flat", "smooth"])
@pytest.mark.parametrize("projection", ["orthographic", "perspective"])
def test_edge_supersample_finds_thin_triangles_between_the_samples(shading, projection):
    """Band slivers and thin parts narrower than the K x K sample spacing (trim, a rod over the
    background) are missed by most samples, so no K x K sample disagrees where they pass; the
    edge resampling still refines every pixel they cross (triangles whose incircle is too small
    to be sure of a sample), so the coverages equal uniform R x R supersampling there too.
    Choosing the pixels from the samples alone (neighbour samples or pixel majorities) left
    band 1 at IoU 0.40-0.42 (K = 2, orthographic) and 0.07-0.09 (perspective) here."""
    from strokekit.raster.bands import soft_iou

    scene = _thin_ribbon_scene()
    occ = Occluder(scene)
    cam = Camera(eye=(0.0, 0.0, 10.0), target=(0.0, 0.0, 0.0), fov_y=43.6, width=64, height=64,
                 projection=projection, ortho_height=8.0)
    base = RasterOptions(bands=3, shading=shading, light=(0.0, 0.0, 1.0), edge_supersample=0)
    uniform = render_raster(scene, cam, occ, replace(base, supersample=4)).coverage
    plain = render_raster(scene, cam, occ, replace(base, supersample=2)).coverage
    assert uniform[..., 1].sum() > 15  # the ribbons' band 1 ...
    assert soft_iou(plain[..., 1], uniform[..., 1]) < 0.5  # ... mostly between the K = 2 samples
    for K in (1, 2):
        fr = render_raster(scene, cam, occ, replace(base, supersample=K, edge_supersample=4))
        idx, _ = fr.edge_coverage
        assert len(idx) < 0.15 * 64 * 64
        assert np.abs(fr.coverage - uniform).max() < 1e-6
        assert all(soft_iou(fr.coverage[..., b], uniform[..., b]) > 0.999 for b in range(4))


def test_raster_pass_runs_on_the_embreex_fallback(sphere, sphere_occ):
    """Without open3d the occlusion falls back to embreex; the ray-cast raster pass (now the
    z-buffer's reference) went to
    Occluder.first_hits, which refused any backend but open3d, so every raster output (--bands,
    --masks ...) failed on such a machine. Through embreex the same rays give the same hits: the
    band labels of a lit sphere agree with open3d's on all but a few edge pixels."""
    pytest.importorskip("embreex")
    alt = Occluder(sphere, backend="embreex")
    assert alt.backend == "embreex"
    rng = np.random.default_rng(1)
    c = sphere.vertices.mean(axis=0)
    o = c + rng.normal(size=(500, 3)) * 0.2 + [0, 0, 4]
    d = c - o + rng.normal(size=(500, 3)) * 1.2
    ref, got = sphere_occ.first_hits(o, d), alt.first_hits(o, d)
    hit = ref["primitive_ids"] >= 0
    assert 100 < hit.sum() < 500 and np.array_equal(got["primitive_ids"] >= 0, hit)
    assert np.mean(got["primitive_ids"][hit] == ref["primitive_ids"][hit]) > 0.99
    same = got["primitive_ids"] == ref["primitive_ids"]
    assert np.allclose(got["t_hit"][hit], ref["t_hit"][hit], atol=1e-4)
    assert np.allclose(got["primitive_uvs"][same & hit], ref["primitive_uvs"][same & hit], atol=1e-3)
    assert np.isinf(got["t_hit"][~hit]).all()
    cam = Camera(eye=tuple(c + [0.5, 0.8, 4.0]), target=tuple(c), width=160, height=120)
    opts = RasterOptions(bands=3, masks=True)
    a = render_raster(sphere, cam, sphere_occ, opts, reference=True)
    b = render_raster(sphere, cam, alt, opts, reference=True)
    assert (a.labels == b.labels).mean() > 0.995 and len(np.unique(b.labels)) == 4


def test_srgb_transfer_round_trips_and_matches_the_standard():
    from strokekit.colour import srgb_decode, srgb_encode

    x = np.linspace(0, 1, 1001)
    assert np.allclose(srgb_decode(srgb_encode(x)), x, atol=1e-12)
    # IEC 61966-2-1 reference points: linear 0.5 -> 0.7354, 0.4 -> 0.6651 (170 / 255: a glTF base
    # colour 0.4 is byte 170 in the shade PNG, not 102)
    assert srgb_encode(0.5) == pytest.approx(0.735357, abs=1e-6)
    assert round(float(srgb_encode(0.4)) * 255) == 170


def test_orthographic_raster_starts_at_the_near_plane_as_the_lines_do(sphere, sphere_occ):
    """An orthographic section view (near plane through the sphere): the lines clip what lies
    before the near plane, so the raster pass must not show it either. Its rays started on the
    camera plane: the bands showed the cut-away front cap over the lines of the section."""
    from strokekit.raster.rays import cast_pixels

    c, r = np.asarray(sphere.center), sphere.radius
    near = 3.0 * r  # eye 3.5 r in front of the centre: the plane cuts the front cap off
    cam = Camera(eye=tuple(c + [0.0, 0.0, 3.5 * r]), target=tuple(c), width=32, height=32,
                 projection="orthographic", ortho_height=3.0 * r, near=near)
    hits = cast_pixels(cam, sphere_occ, 1)
    d = hits.depth[np.isfinite(hits.depth)]
    assert len(d) and d.min() >= near * (1 - 1e-5)
    assert hits.depth[16, 16] > 4.0 * r  # the centre ray starts inside: it meets the back wall


# --- the z-buffer pass (issue 17) -------------------------------------------------------------------

def _outline_scene():
    """A sphere and a box apart in the image (convex both: every visible contour edge lies on the
    outline against the background)."""
    m = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    b = trimesh.creation.box(extents=(1.4, 1.0, 1.2))
    bv = np.asarray(b.vertices) @ np.array([[0.8, 0.6, 0.0], [-0.6, 0.8, 0.0], [0.0, 0.0, 1.0]]) + [2.6, 0.3, -0.4]
    return build_scene(np.r_[m.vertices, bv], np.r_[m.faces, np.asarray(b.faces) + len(m.vertices)])


@pytest.mark.parametrize("projection", ["perspective", "orthographic", "cavalier"])
def test_svg_silhouettes_lie_on_the_edge_of_the_background_mask(tmp_path, capsys, projection):
    """Bar: the silhouettes of the SVG, drawn by the line pass (Embree visibility), lie on the
    edge of the raster pass's background mask (the z-buffer) within 1 px, and the mask's edge
    pixels lie along them: the two passes see the same outline, in perspective, orthographic and
    oblique (cavalier: the z-buffer shears the vertices along the slanted rays) projections."""
    from scipy.spatial import cKDTree

    from strokekit_cli.main import main

    scene = _outline_scene()
    p = tmp_path / "two.obj"
    p.write_text("".join(f"v {float(x)!r} {float(y)!r} {float(z)!r}\n" for x, y, z in scene.vertices)
                 + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in scene.faces))
    target = (1.3, 0.2, -0.2)
    if projection == "cavalier":
        cam = {"projection": "cavalier", "target": list(target), "distance": 8.0, "ortho_height": 4.4,
               "azimuth": 15.0, "elevation": 10.0}
    else:
        cam = {"eye": [2.2, 1.6, 7.0], "target": list(target), "projection": projection,
               **({"fov_y": 40.0} if projection == "perspective" else {"ortho_height": 4.4})}
    path = tmp_path / "cam.json"
    path.write_text(json.dumps({"width": 240, "height": 180, "frames": [cam]}))
    with pytest.raises(SystemExit) as e:
        main([str(a) for a in ["render", p, "--camera", path, "--kinds", "silhouette", "--bands", "3", "--masks",
                               "--no-json", "-q", "--out", tmp_path / "o"]])
    assert e.value.code == 0, capsys.readouterr().err
    silhouettes = read_svg(tmp_path / "o" / "frame_0001.svg").layers["silhouette"]
    assert len(silhouettes) >= 2
    sil, _, _ = segment_samples(silhouettes.points, silhouettes.offsets, 0.5)
    # Background coverage from the masks: 1 - the sum of the band masks.
    masks = sum(read_png((tmp_path / "o" / f"mask{b}" / "frame_0001.png").read_bytes()).astype(float) for b in (1, 2, 3))
    bg = 1.0 - masks / 255.0
    partial = np.argwhere((bg > 0.02) & (bg < 0.98))[:, ::-1] + 0.5
    cross = [((np.argwhere(a != b)[:, ::-1] + 0.5) + off / 2) for a, b, off in
             (((bg[:, 1:] >= 0.5), (bg[:, :-1] >= 0.5), np.array([1.0, 0.0])),
              ((bg[1:] >= 0.5), (bg[:-1] >= 0.5), np.array([0.0, 1.0])))]
    edge = np.concatenate([partial] + cross)
    assert len(partial) > 200
    d_sil, _ = cKDTree(edge).query(sil)
    assert d_sil.max() <= 1.0, d_sil.max()
    d_edge, _ = cKDTree(sil).query(partial)
    assert d_edge.max() <= 1.0, d_edge.max()


def _room_views():
    return [((5.3, 4.6, -4.1), (10.0, 5.5, -6.0)), ((4.7, 5.2, -5.4), (0.0, 3.0, -8.0)),
            ((6.1, 2.2, -1.3), (3.0, 4.0, -9.0)), ((8.9, 1.0, -8.9), (0.0, 6.0, 0.0))]


def test_a_camera_inside_a_room_gets_masks_without_holes():
    """Bar: inside the shared wallhole room, with a near plane that cuts through the walls, the
    floor and the ceiling around the camera (12 to 30 triangles cross it), the z-buffer clips
    those triangles (Sutherland-Hodgman) instead of dropping them: its masks equal the ray-cast
    reference's (rays start on the near plane). Drawn without the crossing triangles, the same
    views would have holes."""
    scene = _model("wallhole.obj")
    occ = Occluder(scene)
    opts = RasterOptions(bands=3, masks=True)
    for eye, target in _room_views():
        cam = Camera(eye=eye, target=target, fov_y=110, width=200, height=150, near=1.0)
        _, z = cam.project(scene.vertices)
        zf = z[scene.faces]
        crossing = (zf.min(axis=1) < 1.0) & (zf.max(axis=1) > 1.0)
        assert crossing.sum() >= 10
        fr = render_raster(scene, cam, None, opts)
        ref = render_raster(scene, cam, occ, opts, reference=True)
        assert np.array_equal(fr.labels, ref.labels)
        for b in range(1, 4):
            assert np.abs(fr.mask(b).astype(int) - ref.mask(b)).max() <= 16  # (one of 16 edge samples)
        kept = build_scene(scene.vertices, scene.faces[~crossing])
        holes = render_raster(kept, cam, None, opts).labels == 0
        assert holes.sum() > (fr.labels == 0).sum() + 100


@pytest.mark.parametrize("K", [1, 2])
def test_a_closed_box_seen_from_inside_has_no_background(K):
    """Inside a closed box every sample sees a wall, also where the wall triangles cross the near
    plane (the walls beside the camera; the near plane itself lies inside the box)."""
    m = trimesh.creation.box(extents=(4.0, 3.0, 5.0))
    m = m.subdivide()
    scene = build_scene(m.vertices, m.faces)
    occ = Occluder(scene)
    for eye, target in (((0.3, 0.2, 0.1), (1.0, 0.5, -0.7)), ((-0.8, -0.6, 0.5), (0.0, 0.0, 0.0))):
        cam = Camera(eye=eye, target=target, fov_y=120, width=120, height=90, near=0.2)
        _, z = cam.project(scene.vertices)
        zf = z[scene.faces]
        assert ((zf.min(axis=1) < 0.2) & (zf.max(axis=1) > 0.2)).sum() >= 8
        fr = render_raster(scene, cam, None, RasterOptions(supersample=K, masks=True))
        assert (fr.coverage[..., 0] == 0).all()
        ref = render_raster(scene, cam, occ, RasterOptions(supersample=K, masks=True), reference=True)
        assert (fr.labels != ref.labels).mean() < 0.002


@pytest.mark.parametrize("projection, angles", [("cavalier", {"azimuth": 20.0, "elevation": 10.0}),
                                                ("cabinet", {"oblique_angle": 30.0}), ("isometric", {})])
def test_the_zbuffer_draws_parallel_projections_as_the_rays_do(sphere, sphere_occ, projection, angles):
    """Oblique projections are orthographic ones after a shear of the vertices along the slanted
    rays: the z-buffer's faces, depths and labels are the ray-cast reference's."""
    cam = Camera.parallel(projection, tuple(sphere.center), 6.0, ortho_height=3.0, width=160, height=120, **angles)
    opts = RasterOptions(bands=4, supersample=2, edge_supersample=0)
    fr = render_raster(sphere, cam, None, opts)
    ref = render_raster(sphere, cam, sphere_occ, opts, reference=True)
    assert (fr.hits.face == ref.hits.face).mean() > 0.998
    both = (fr.hits.face == ref.hits.face) & fr.hits.hit
    assert both.sum() > 5000
    assert np.abs(fr.hits.depth[both] - ref.hits.depth[both]).max() < 1e-5 * sphere.radius * 10
    assert (fr.labels != ref.labels).mean() < 0.002


def test_default_quality_resamples_only_the_mixed_pixels(sphere):
    """Render's default: 1 sample a pixel, then 4 x 4 on the pixels a band, material or object edge
    crosses (a few percent of the image): its masks equal a uniform 4 x 4 sampling's."""
    cam = Camera(eye=(3.6, -1.2, 5.5), target=(3.0, -2.0, 1.0), fov_y=30, width=160, height=120)
    fr = render_raster(sphere, cam, None, RasterOptions(bands=3))
    assert fr.options.supersample == 1 and fr.options.edge_supersample == 4
    assert fr.hits.face.shape == (120, 160) and fr.mixed.samples == 16
    assert len(fr.mixed.pixels) < 0.15 * 160 * 120
    uniform = render_raster(sphere, cam, None, RasterOptions(bands=3, supersample=4, edge_supersample=0))
    assert np.abs(fr.coverage - uniform.coverage).max() < 1e-6
    assert np.array_equal(fr.labels, uniform.labels)
    assert np.abs(fr.shade_image().astype(int) - uniform.shade_image()).max() <= 1


def test_material_and_object_edges_are_resampled_too():
    """Two touching boxes of different materials and objects, every face in one band: the edge
    between them is a colour and id edge, not a band edge; it is resampled like one (the shade
    image's edge pixels mix the two colours as 4 x 4 sampling does)."""
    a = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    b = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    v = np.r_[a.vertices, np.asarray(b.vertices) + [1.0, 0.0, 0.0]]
    f = np.r_[a.faces, np.asarray(b.faces) + len(a.vertices)]
    n = len(a.faces)
    scene = build_scene(v, f, face_object=np.repeat([0, 1], n), face_material=np.repeat([0, 1], n),
                        objects=("a", "b"), materials=(Material("red", (0.9, 0.1, 0.1, 1.0)),
                                                       Material("blue", (0.1, 0.1, 0.9, 1.0))))
    cam = Camera(eye=(0.5, 0.0, 4.0), target=(0.5, 0.0, 0.0), fov_y=30, width=96, height=64,
                 projection="orthographic", ortho_height=1.7)
    opts = RasterOptions(bands=1, light=(0.0, 0.0, 1.0), objectid=True)
    fr = render_raster(scene, cam, None, opts)
    uniform = render_raster(scene, cam, None, replace(opts, supersample=4, edge_supersample=0))
    seam = 48  # x = 0.5 world at the image centre: the boxes meet at pixel column 48's left side
    assert seam in {int(p) % 96 for p in fr.mixed.pixels} or seam - 1 in {int(p) % 96 for p in fr.mixed.pixels}
    assert np.abs(fr.shade_image().astype(int) - uniform.shade_image()).max() <= 1
    ids = fr.objectid_image()
    assert set(np.unique(ids)) == {0, 1, 2}


def test_fill_is_antialiased_like_the_bands(sphere, sphere_occ):
    """The fill's marks get grey levels along their edges (the tone threshold smoothed over one
    sample cell), not the 5 levels of a 2 x 2 box filter of binary marks, and the image is closer
    to 8 x 8 supersampled binary marks (mean error 6.9 grey levels against 11.7 for the 2 x 2
    binary fill, at the same 4 field samples a pixel)."""
    from strokekit.raster.fill import fill_ink

    cam = Camera(eye=(3.0, -2.0, 5.0), target=(3.0, -2.0, 1.0), fov_y=40, width=128, height=128)
    opts = RasterOptions(bands=3, fill=True, shade=False, fill_period_px=12.0)
    img = render_raster(sphere, cam, None, opts).fill_image().astype(float)

    from strokekit.raster.bands import face_shading, light_direction

    shading = face_shading(sphere, cam, opts, light_direction(cam, opts))

    def binary(K):  # K x K rays a pixel, binary marks, box-filtered
        hits = cast_pixels(cam, sphere_occ, K)
        labels, _ = shading.labels(hits.face, hits.bary)
        ink = fill_ink(sphere, hits, labels, 3, "hatch", 12.0).astype(float)
        return 255.0 * (1.0 - ink.reshape(128, K, 128, K).mean(axis=(1, 3)))

    ref, old = binary(8), binary(2)
    assert len(np.unique(img)) > 40 and len(np.unique(old)) <= 5
    inside = render_raster(sphere, cam, None, opts).labels > 0
    err, err_old = np.abs(img - ref)[inside].mean(), np.abs(old - ref)[inside].mean()
    assert err < 0.75 * err_old, (err, err_old)


def test_png_bytes_are_valid_deterministic_and_round_trip():
    """The PNG writer (Up filter, zlib level 1): every image kind reads back equal in Pillow, the
    same array gives the same bytes."""
    from PIL import Image

    from strokekit.writers.png import png_bytes

    rng = np.random.default_rng(0)
    for a in (rng.integers(0, 256, (37, 53), dtype=np.uint8), rng.integers(0, 65536, (20, 31), dtype=np.uint16),
              rng.integers(0, 256, (17, 9, 3), dtype=np.uint8), rng.integers(0, 256, (5, 7, 4), dtype=np.uint8),
              np.zeros((1, 1), np.uint8)):
        data = png_bytes(a)
        Image.open(io.BytesIO(data)).verify()
        back = read_png(data)
        assert back.dtype == a.dtype and np.array_equal(back, a)
        assert png_bytes(a.copy()) == data
    with pytest.raises(ValueError):
        png_bytes(np.zeros((4, 4), np.float32))


def test_raster_passes_are_the_same_bytes_in_another_process(tmp_path, capsys):
    """A user's rerun is another process (another hash seed, kernels loaded from numba's cache),
    and a pool worker draws frames too: every pass file (bands, masks, shade, object ids, depth,
    fill, lines, the EXR, the polygons' SVG) and the run manifest are the same bytes, here, in a
    new interpreter and with a pool worker drawing one of the frames."""
    import subprocess
    import sys

    from helpers import SAMPLES, cli_env

    from strokekit_cli.main import main

    args = ["render", str(SAMPLES / "still_life.glb"), "--orbit", "2", "--size", "96x72", "--bands", "3", "--masks",
            "--objectid", "--depth", "--fill", "--band-polygons", "--exr", "--lines-png", "-q"]
    with pytest.raises(SystemExit) as e:
        main(args + ["--out", str(tmp_path / "here")])
    assert e.value.code == 0, capsys.readouterr().err
    for name, extra in (("rerun", ["--workers", "1"]), ("pool", ["--workers", "2"])):
        subprocess.run([sys.executable, "-m", "strokekit_cli.main", *args, *extra, "--out", str(tmp_path / name)],
                       check=True, env=cli_env(PYTHONHASHSEED=str(len(name))), cwd=tmp_path)

    def files(d):
        return {str(p.relative_to(d)): p.read_bytes() for p in sorted(d.rglob("*")) if p.is_file()}

    here = files(tmp_path / "here")
    assert {"bands/frame_0002.png", "mask1/frame_0001.png", "fill/frame_0001.png", "frame_0002.exr",
            ".strokekit-run.json"} <= set(here), sorted(here)
    for name in ("rerun", "pool"):
        there = files(tmp_path / name)
        assert sorted(there) == sorted(here), name
        assert [k for k in here if here[k] != there[k]] == [], name



def test_regions_are_the_sorted_material_object_pairs():
    """Scene.regions (a 1-D unique of one integer a pair) gives the pairs in (material, object)
    order and each face's index among them, as a unique of the pairs as rows does (the oracle)."""
    rng = np.random.default_rng(3)
    n = 40
    verts = rng.normal(size=(3 * n, 3))
    faces = np.arange(3 * n).reshape(n, 3)
    fm = rng.integers(0, 4, n)
    fo = rng.integers(0, 3, n)
    scene = build_scene(verts, faces, fo, fm, objects=("a", "b", "c"), materials=tuple(Material(f"m{i}") for i in range(4)))
    region, mat, obj = scene.regions
    pairs, inverse = np.unique(np.column_stack([scene.face_material, scene.face_object]).astype(np.int64), axis=0,
                               return_inverse=True)
    assert np.array_equal(mat, pairs[:, 0]) and np.array_equal(obj, pairs[:, 1])
    assert region.dtype == np.int32 and np.array_equal(region, inverse.reshape(-1))
    one = build_scene(verts, faces)
    assert one.regions[0] is None and list(one.regions[1]) == [0] and list(one.regions[2]) == [0]
