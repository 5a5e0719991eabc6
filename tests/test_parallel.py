"""The parallel projections of technical drawing (issue 20, seed 001 3.2): isometric, dimetric,
trimetric (axonometric: the image plane perpendicular to the rays) and cavalier, cabinet (oblique:
receding lines at an angle, at full or half length), in camera files, `strokekit camera parallel`,
the drawing and the raster pass. The reference positions come from the textbook matrices (rotation
about the vertical axis, then about the horizontal one; the oblique shear), not from the camera
code."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from helpers import box_mesh

from strokekit import LineOptions, LineRenderer, build_scene
from strokekit.camera.paths import camera_path_from_json
from strokekit.camera.view import ISOMETRIC_ELEVATION, Camera
from strokekit.errors import InputError
from strokekit_cli.main import main

W = H = 400
SIZE = 3.0  # ortho_height: world units across the image height
F = H / SIZE  # px per world unit
TARGET = np.array([0.5, 0.5, 0.5])
CORNERS = np.array([[x, y, z] for x in (0.0, 1.0) for y in (0.0, 1.0) for z in (0.0, 1.0)])
EDGES = [(i, j) for i in range(8) for j in range(i + 1, 8) if np.abs(CORNERS[i] - CORNERS[j]).sum() == 1]

#: (projection, angles given, textbook azimuth, elevation, oblique shear scale and angle)
VIEWS = [
    ("isometric", {}, 45.0, math.degrees(math.atan(1 / math.sqrt(2))), None),
    ("dimetric", {"elevation": 20.0}, 45.0, 20.0, None),
    ("trimetric", {"azimuth": 30.0, "elevation": 25.0}, 30.0, 25.0, None),
    ("cavalier", {}, 0.0, 0.0, (1.0, 45.0)),
    ("cabinet", {}, 0.0, 0.0, (0.5, 45.0)),
    ("cabinet", {"azimuth": 30.0, "elevation": 20.0, "oblique_angle": 30.0}, 30.0, 20.0, (0.5, 30.0)),
]


def rot_x(b):
    c, s = math.cos(b), math.sin(b)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def rot_y(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def textbook_pixels(points, azimuth, elevation, oblique):
    """Seed 001's way: view coordinates V = R_x(elevation) R_y(-azimuth) (P - target) (x right, y
    up, z toward the viewer); axonometric drops z, oblique adds the receding axis: a point d deeper
    (d = -z) is drawn d * scale * (cos a, sin a) further right and up. Then to pixels, y down."""
    V = (rot_x(math.radians(elevation)) @ rot_y(-math.radians(azimuth)) @ (np.asarray(points) - TARGET).T).T
    x, y = V[:, 0], V[:, 1]
    if oblique is not None:
        scale, angle = oblique
        depth = -V[:, 2]
        x = x + scale * math.cos(math.radians(angle)) * depth
        y = y + scale * math.sin(math.radians(angle)) * depth
    return np.stack([W / 2 + F * x, H / 2 - F * y], axis=1)


def camera(projection, angles):
    return Camera.parallel(projection, tuple(TARGET), 4.0, ortho_height=SIZE, width=W, height=H, **angles)


@pytest.fixture(scope="module")
def cube_renderer():
    v, f = box_mesh((0, 0, 0), (1, 1, 1))
    return LineRenderer(build_scene(v, f), LineOptions())


@pytest.mark.parametrize("projection, angles, az, el, oblique", VIEWS)
def test_cube_corners_project_where_the_textbook_matrices_put_them(projection, angles, az, el, oblique):
    """Camera.project of each corner of a unit cube equals the textbook projection (to float
    rounding): the angle conventions, the isometric elevation and the oblique shear are the
    seed's."""
    p, _ = camera(projection, angles).project(CORNERS)
    assert np.abs(p - textbook_pixels(CORNERS, az, el, oblique)).max() < 1e-9


def _drawn_edges(strokes, expected_px):
    """The cube edges the strokes draw, as corner pairs, after checking that every stroke point is
    a corner (its surface point) drawn within 0.01 px of that corner's textbook position (the
    isometric near and far corners share a pixel: the surface point tells them apart)."""
    corner = np.linalg.norm(strokes.surface[:, None] - CORNERS[None], axis=2).argmin(axis=1)
    assert np.allclose(strokes.surface, CORNERS[corner], atol=1e-9)
    err = np.linalg.norm(strokes.points - expected_px[corner], axis=1)
    assert err.max() < 0.01, err.max()
    out = set()
    for s in range(len(strokes)):
        c = corner[strokes.stroke(s)]
        out |= {tuple(sorted((int(a), int(b)))) for a, b in zip(c[:-1], c[1:]) if a != b}
    return out


@pytest.fixture(scope="module")
def cube_hidden_renderer(cube_renderer):
    return LineRenderer(cube_renderer.scene, LineOptions(occlusion=(0, 15)))


@pytest.mark.parametrize("projection, angles, az, el, oblique", VIEWS)
def test_cube_drawn_in_each_parallel_projection_has_its_corners_within_a_hundredth_of_a_pixel(
        cube_renderer, cube_hidden_renderer, projection, angles, az, el, oblique):
    """A unit cube with its hidden lines: every drawn point is a corner within 0.01 px of the
    textbook position; the visible edges are the nine not touching the far corner (the one
    farthest along the rays; the oblique projections see the same three faces as the view they
    slant), the hidden ones exactly the three of the far corner, each behind one face (level 1:
    in isometric the far corner lies right behind the near one, where three faces meet, and the
    rays from its edges run along face diagonals: still one surface each). The visible-only
    drawing is the level-0 part."""
    cam = camera(projection, angles)
    px = textbook_pixels(CORNERS, az, el, oblique)
    far = int(np.argmax(CORNERS @ cam.view_dir))
    strokes = cube_hidden_renderer.render(cam)
    assert set(strokes.occlusion.tolist()) == {0, 1}
    assert _drawn_edges(strokes.select(strokes.occlusion == 0), px) == {e for e in EDGES if far not in e}
    assert _drawn_edges(strokes.select(strokes.occlusion == 1), px) == {e for e in EDGES if far in e}
    assert _drawn_edges(cube_renderer.render(cam), px) == {e for e in EDGES if far not in e}


def test_an_isometric_camera_foreshortens_the_three_axes_alike():
    right, up, _ = Camera.parallel("isometric", (0, 0, 0), 1.0).basis
    lengths = np.hypot(np.eye(3) @ right, np.eye(3) @ up)
    assert np.allclose(lengths, math.sqrt(2 / 3))
    assert math.isclose(ISOMETRIC_ELEVATION, 35.26438968, rel_tol=1e-9)


def test_an_oblique_camera_keeps_the_target_at_the_image_centre():
    cam = Camera.parallel("cavalier", (1.0, 2.0, 3.0), 5.0, ortho_height=2.0, width=300, height=200,
                          azimuth=20.0, elevation=10.0)
    p, z = cam.project(np.array([[1.0, 2.0, 3.0]]))
    assert np.allclose(p, [[150.0, 100.0]]) and math.isclose(float(z[0]), 5.0)


@pytest.mark.parametrize("projection, angles", [(p, a) for p, a, *_ in VIEWS])
def test_a_parallel_camera_survives_the_json_round_trip(projection, angles):
    cam = camera(projection, angles)
    back = Camera.from_json(json.loads(json.dumps(cam.to_json())))
    assert np.allclose(back.eye, cam.eye, atol=1e-12) and back.projection == projection
    assert (back.azimuth, back.elevation, back.oblique_angle) == (cam.azimuth, cam.elevation, cam.oblique_angle)
    path = camera_path_from_json({"width": W, "height": H, "frames": [
        {k: v for k, v in cam.to_json().items() if k not in ("width", "height")}]})
    assert np.allclose(path.cameras[0].project(CORNERS)[0], cam.project(CORNERS)[0], atol=1e-9)


@pytest.mark.parametrize("frame, needle", [
    ({"projection": "isometric", "target": [0, 0, 0], "ortho_height": 1, "eye": [1, 1, 1]},
     "give 'distance' (world units before the target) instead of 'eye'"),
    ({"projection": "isometric", "target": [0, 0, 0], "ortho_height": 1}, "needs 'distance'"),
    ({"projection": "dimetric", "target": [0, 0, 0], "ortho_height": 1, "distance": 3}, "needs elevation"),
    ({"projection": "trimetric", "target": [0, 0, 0], "ortho_height": 1, "distance": 3, "elevation": 20},
     "needs azimuth"),
    ({"projection": "isometric", "target": [0, 0, 0], "ortho_height": 1, "distance": 3, "azimuth": 30},
     "azimuth must be 45, 135, 225 or 315"),
    ({"projection": "isometric", "target": [0, 0, 0], "ortho_height": 1, "distance": 3, "elevation": 30},
     "a dimetric camera takes another"),
    ({"projection": "cavalier", "target": [0, 0, 0], "ortho_height": 1, "distance": 3, "fov_y": 30}, "no 'fov_y'"),
    ({"projection": "cabinet", "target": [0, 0, 0], "ortho_height": 1, "distance": -3}, "distance must be a number > 0"),
    ({"eye": [0, 0, 5], "target": [0, 0, 0], "azimuth": 10}, "'azimuth' belongs to the projections"),
    ({"projection": "isometric", "target": [0, 0, 0], "ortho_height": 1, "distance": 3, "oblique_angle": 30},
     "oblique_angle belongs to the oblique projections"),
])
def test_a_bad_parallel_camera_is_one_line_naming_the_file_and_frame(frame, needle):
    with pytest.raises(InputError) as e:
        camera_path_from_json({"frames": [frame]}, "shot.json")
    msg = str(e.value)
    assert msg.startswith("shot.json: frame 1: ") and needle in msg and "\n" not in msg, msg


def test_keyframes_of_an_angled_projection_turn_their_angles_at_a_constant_distance():
    key = {"projection": "trimetric", "target": [0, 0, 0], "distance": 5, "ortho_height": 3, "elevation": 30}
    path = camera_path_from_json({"frame_count": 5, "keyframes": [dict(key, frame=0, azimuth=20),
                                                                   dict(key, frame=4, azimuth=60)]})
    assert [c.azimuth for c in path.cameras] == [20.0, 30.0, 40.0, 50.0, 60.0]
    assert np.allclose([c.to_json()["distance"] for c in path.cameras], 5.0)


def run_cli(args, capsys):
    with pytest.raises(SystemExit) as e:
        main([str(a) for a in args])
    out = capsys.readouterr()
    return e.value.code, out.out, out.err


@pytest.fixture
def cube_obj(tmp_path):
    v, f = box_mesh((0, 0, 0), (1, 1, 1))
    p = tmp_path / "cube.obj"
    p.write_text("".join(f"v {x:g} {y:g} {z:g}\n" for x, y, z in v) + "".join(f"f {a + 1} {b + 1} {c + 1}\n"
                                                                          for a, b, c in f))
    return p


def test_cli_camera_parallel_writes_a_file_render_reads(cube_obj, tmp_path, capsys):
    out = tmp_path / "cav.json"
    code, _, err = run_cli(["camera", "parallel", cube_obj, "--projection", "cabinet", "--width", "300",
                            "--height", "200", "-o", out], capsys)
    assert code == 0, err
    path = camera_path_from_json(json.loads(out.read_text()))
    cam = path.cameras[0]
    assert cam.projection == "cabinet" and cam.shear == pytest.approx((0.5 * math.cos(math.pi / 4),) * 2)
    # The whole cube is in the image.
    p, _ = cam.project(CORNERS)
    assert (p >= 0).all() and (p[:, 0] <= 300).all() and (p[:, 1] <= 200).all()


def test_cli_camera_parallel_refuses_a_missing_angle_as_a_usage_error(cube_obj, capsys):
    code, _, err = run_cli(["camera", "parallel", cube_obj, "--projection", "trimetric"], capsys)
    assert code == 2 and "needs azimuth and elevation" in err and err.count("\n") == 1, err


@pytest.mark.parametrize("projection, angles", [("isometric", {}), ("cavalier", {"azimuth": 20.0, "elevation": 10.0}),
                                                ("cabinet", {"oblique_angle": 30.0})])
def test_the_raster_pass_casts_along_the_projection_rays(cube_renderer, projection, angles):
    """Each raster sample's hit point projects back to its own pixel centre (the rays run along the
    slanted projection direction of an oblique camera, not along its image-plane normal), and the
    cube covers the pixels its lines outline."""
    from strokekit.raster.bands import RasterOptions, render_raster

    cam = camera(projection, angles)
    frame = render_raster(cube_renderer.scene, cam, cube_renderer.occluder,
                          RasterOptions(bands=3, supersample=2, edge_supersample=0))
    rows, cols = np.nonzero(frame.hits.hit)
    p, _ = cam.project(frame.hits.position[rows, cols])
    assert np.abs(p - (np.stack([cols, rows], axis=1) + 0.5) / 2).max() < 1e-6
    lines = cube_renderer.render(cam).points
    assert np.abs([cols.min() / 2 - lines[:, 0].min(), rows.min() / 2 - lines[:, 1].min(),
                   (cols.max() + 1) / 2 - lines[:, 0].max(), (rows.max() + 1) / 2 - lines[:, 1].max()]).max() <= 1.0


def _glb_json(data: bytes) -> dict:
    import struct

    jlen, _ = struct.unpack_from("<I4s", data, 12)
    return json.loads(data[20:20 + jlen])


@pytest.mark.parametrize("projection, angles", [("isometric", {}), ("cavalier", {"oblique_angle": 30.0})])
def test_the_glb_camera_says_what_gltf_can(cube_renderer, projection, angles):
    """glTF has perspective and orthographic cameras only: an axonometric frame's GLB camera is the
    exact orthographic one (looking along the rays, centred on the target, ortho_height tall); an
    oblique frame's is the orthographic view of its image plane from straight on, centred on the
    target, with the projection and its receding shear in the camera's extras."""
    from strokekit.writers.gltf import glb_for_frame

    cam = camera(projection, angles)
    doc = _glb_json(glb_for_frame(cube_renderer.render(cam), cam))
    gcam = doc["cameras"][0]
    assert gcam["type"] == "orthographic" and gcam["orthographic"]["ymag"] == pytest.approx(SIZE / 2)
    assert gcam["extras"]["projection"] == projection
    node = next(n for n in doc["nodes"] if "camera" in n)
    right, up, fwd = cam.basis
    x, y, z, w = node["rotation"]
    # The node's -Z axis (rotated by the quaternion) is fwd, and the target lies on that axis.
    minus_z = -np.array([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)])
    assert np.allclose(minus_z, fwd, atol=1e-9)
    to_target = np.subtract(cam.target, node["translation"])
    assert np.allclose(to_target - (to_target @ fwd) * fwd, 0.0, atol=1e-9)
    if cam.is_oblique:
        assert gcam["extras"]["receding_shear"] == pytest.approx(list(cam.shear))
        assert "no oblique projection" in gcam["extras"]["note"]
    else:
        assert np.allclose(node["translation"], cam.eye)
