"""Camera path files (BRIEF 1.2): what a bad value in them gives (one InputError naming the file and
the field, one line and exit 1 from the CLI, never an internal error) and how keyframes become
cameras."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from strokekit.camera.paths import camera_path_from_json, load_camera_path
from strokekit.camera.view import MAX_IMAGE_PX
from strokekit.errors import InputError
from strokekit_cli.main import main

KEY0 = {"frame": 0, "eye": [0, 0, 5], "target": [0, 0, 0]}
KEY2 = {"frame": 2, "eye": [0, 0, 6], "target": [0, 0, 0]}
FRAME0 = {"eye": [0, 0, 5], "target": [0, 0, 0]}  # an entry of the frames form (no "frame")


def keyed(keys=(KEY0, KEY2), **top) -> dict:
    return {"width": 200, "height": 200, "frame_count": 3, "keyframes": list(keys), **top}


def write(tmp_path: Path, data: dict, name: str = "cam.json") -> Path:
    p = tmp_path / name
    p.write_text(json.dumps(data))
    return p


def load_error(tmp_path: Path, data: dict) -> str:
    with pytest.raises(InputError) as e:
        load_camera_path(write(tmp_path, data))
    msg = str(e.value)
    assert msg.startswith(str(tmp_path / "cam.json") + ": ") and "\n" not in msg, msg
    return msg


# --- bad values: one InputError naming the file and the field ------------------------------------

@pytest.mark.parametrize("data,needles", [
    (keyed([dict(KEY0, frame="a")]), ["keyframe 1", "'frame' must be a whole number", '"a"']),
    (keyed([dict(KEY0, frame=None)]), ["keyframe 1", "'frame' must be a whole number", "null"]),
    (keyed([dict(KEY0, frame=True)]), ["keyframe 1", "'frame' must be a whole number", "true"]),
    (keyed([KEY0, dict(KEY2, frame=10 ** 400)]), ["keyframe 2", "out of range"]),
    (keyed(frame_count="x"), ["frame_count must be a whole number", '"x"']),
    (keyed(frame_count=None), ["frame_count must be a whole number", "null"]),
    (keyed(frame_count=0), ["frame_count must be between 1 and"]),
    (keyed(frame_count=10 ** 12), ["frame_count must be between 1 and"]),
    (keyed(frame_count=float("inf")), ["frame_count must be a whole number"]),
    ({"width": float("inf"), "frames": [FRAME0]}, ["width must be a whole number"]),
    ({"width": 10 ** 400, "frames": [FRAME0]}, ["image size", f"at most {MAX_IMAGE_PX} px", "width"]),
    ({"height": 1e20, "frames": [FRAME0]}, ["image size", "height"]),
    ({"frames": [dict(FRAME0, width=10 ** 20)]}, ["frame 1", "image size", "width"]),
    ({"frames": [dict(FRAME0, fov_y=10 ** 400)]}, ["frame 1", "bad value"]),
    ({"frames": [dict(FRAME0, near=10 ** 400)]}, ["frame 1", "bad value"]),
    ({"fps": 10 ** 400, "frames": [FRAME0]}, ["fps"]),
])
def test_bad_numbers_are_one_input_error_naming_the_file_and_field(tmp_path, data, needles):
    """Strings, nulls, infinities and integers beyond float range where a number belongs were
    internal errors (ValueError, TypeError, OverflowError) or, for a width of 1e20 px, failed late
    in the writers: each is one line naming the file and the field."""
    msg = load_error(tmp_path, data)
    for n in needles:
        assert n in msg, msg


@pytest.mark.parametrize("data,needle", [
    (keyed([dict(KEY0, frame="a")]), "'frame' must be a whole number"),
    (keyed(frame_count="x"), "frame_count must be a whole number"),
    ({"width": 1e400, "frames": [KEY0]}, "width must be a whole number"),
    # (said as the eye out of range, with no numpy warning: it was "'up' ... is parallel to the view")
    ({"frames": [dict(FRAME0, eye=[1e160, 0, 5])]}, "cam.json: frame 1: camera eye (1e+160, 0, 5) is out of range"),
])
def test_cli_reports_bad_camera_numbers_in_one_line_exit_1(tmp_path, capsys, data, needle):
    cam = write(tmp_path, data)
    obj = tmp_path / "tri.obj"
    obj.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(SystemExit) as e:
        main(["render", str(obj), "--camera", str(cam), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert e.value.code == 1 and len(err.strip().splitlines()) == 1, err
    assert "cam.json" in err and needle in err and "internal error" not in err


# --- frame numbers are whole numbers --------------------------------------------------------------

@pytest.mark.parametrize("data,needle", [
    (keyed(frame_count=2.7), "frame_count must be a whole number, got 2.7"),
    (keyed([dict(KEY0, frame=0.5), dict(KEY2, frame=0.9)]), "keyframe 1: 'frame' must be a whole number, got 0.5"),
    (keyed([KEY0, dict(KEY2, frame=1.5)]), "keyframe 2: 'frame' must be a whole number, got 1.5"),
    ({"width": 200.5, "frames": [KEY0]}, "width must be a whole number, got 200.5"),
])
def test_fractional_frame_numbers_are_refused(tmp_path, data, needle):
    """frame_count 2.7 silently became 2, and keyframes at 0.5 and 0.9 were reported as 'two
    keyframes for frame 0': frames are whole numbers, a fraction is refused by name."""
    assert needle in load_error(tmp_path, data)


def test_integral_floats_count_as_whole_numbers():
    path = camera_path_from_json(keyed([dict(KEY0, frame=0.0), dict(KEY2, frame=2.0)], frame_count=3.0,
                                       width=200.0), "k.json")
    assert len(path) == 3 and path.cameras[0].width == 200
    assert np.allclose(path.cameras[2].eye, KEY2["eye"])


# --- keyframe interpolation: eye, target and up ----------------------------------------------------

def centre_of(cam, point) -> np.ndarray:
    xy, z = cam.project(np.array([point], float))
    assert z[0] > 0
    return xy[0]


@pytest.mark.parametrize("interpolation", ["linear", "smooth"])
def test_a_target_shared_by_the_keyframes_stays_at_the_image_centre(interpolation):
    """Keys eye (0,0,5) and eye (10,0,0), both looking at the origin: the origin is the image
    centre in every frame between them. Slerping the orientation and rebuilding the target as
    eye + distance x forward put it at x = 8.4 of 200 px in the middle frame."""
    keys = [{"frame": 0, "eye": [0, 0, 5], "target": [0, 0, 0]},
            {"frame": 4, "eye": [10, 0, 0], "target": [0, 0, 0]},
            {"frame": 8, "eye": [0, 3, -6], "target": [0, 0, 0]}]
    path = camera_path_from_json(keyed(keys, frame_count=9, interpolation=interpolation), "k.json")
    for f, cam in enumerate(path.cameras):
        assert np.allclose(cam.target, 0.0), f
        assert np.allclose(centre_of(cam, [0, 0, 0]), [100, 100]), f


def test_a_moving_target_moves_on_the_line_between_the_keys():
    keys = [{"frame": 0, "eye": [0, 0, 5], "target": [0, 0, 0]},
            {"frame": 4, "eye": [4, 0, 5], "target": [2, 1, 0]}]
    path = camera_path_from_json(keyed(keys, frame_count=5), "k.json")
    for f, cam in enumerate(path.cameras):
        t = f / 4
        assert np.allclose(cam.eye, [4 * t, 0, 5]) and np.allclose(cam.target, [2 * t, t, 0])
        assert np.allclose(centre_of(cam, [2 * t, t, 0]), [100, 100])


def roll_deg(cam) -> float:
    """Angle of the camera's up' from +Y, about the view direction -Z (positive toward +X)."""
    _, up, fwd = cam.basis
    assert np.allclose(fwd, [0, 0, -1])
    return float(np.degrees(np.arctan2(up[0], up[1])))


def test_the_up_vector_turns_at_an_even_rate_between_the_keys():
    keys = [{"frame": 0, "eye": [0, 0, 5], "target": [0, 0, 0], "up": [0, 1, 0]},
            {"frame": 4, "eye": [0, 0, 5], "target": [0, 0, 0], "up": [2, 0, 0]}]
    path = camera_path_from_json(keyed(keys, frame_count=5), "k.json")
    assert np.allclose([roll_deg(c) for c in path.cameras], [0, 22.5, 45, 67.5, 90])


def test_keys_with_the_same_up_keep_it_as_given():
    keys = [{"frame": 0, "eye": [0, 4, 5], "target": [0, 0, 0], "up": [0, 0, 1]},
            {"frame": 2, "eye": [5, 4, 0], "target": [0, 0, 0], "up": [0, 0, 1]}]
    assert camera_path_from_json(keyed(keys), "k.json").cameras[1].up == (0.0, 0.0, 1.0)


def test_opposite_ups_roll_half_a_turn_through_a_sideways_up():
    keys = [{"frame": 0, "eye": [0, 0, 5], "target": [0, 0, 0], "up": [0, 1, 0]},
            {"frame": 2, "eye": [0, 0, 5], "target": [0, 0, 0], "up": [0, -1, 0]}]
    mid = camera_path_from_json(keyed(keys), "k.json").cameras[1]
    assert abs(roll_deg(mid)) == pytest.approx(90.0)


def test_an_eye_that_passes_through_the_target_is_one_clear_error(tmp_path):
    keys = [{"frame": 0, "eye": [0, 0, 5], "target": [0, 0, 0]},
            {"frame": 2, "eye": [0, 0, -5], "target": [0, 0, 0]}]
    msg = load_error(tmp_path, keyed(keys))
    assert "frame 1, between the keyframes at frame 0 and frame 2" in msg and "target equals eye" in msg


# --- keyframe lenses: one projection, near / fov / ortho_height interpolated ---------------------

def test_keyframes_mixing_projections_are_refused_naming_the_file_and_frames(tmp_path):
    """Key 0 perspective and key 2 orthographic gave a perspective frame 1 with key 0's lens and a
    jump at frame 2: a projection has no in-between, so such a path is an input error."""
    keys = [dict(KEY0), dict(KEY2, projection="orthographic", ortho_height=2)]
    msg = load_error(tmp_path, keyed(keys))
    assert "keyframes at frame 0 (perspective) and frame 2 (orthographic) mix projections" in msg


def test_near_is_interpolated_between_keys():
    """near came from the earlier key only (0.5 until the next key, then a jump to 2.5): it changes
    linearly, and after the last key that key's near holds."""
    keys = [dict(KEY0, near=0.5), dict(KEY0, frame=4, near=2.5)]
    path = camera_path_from_json(keyed(keys, frame_count=6), "k.json")
    assert [c.near for c in path.cameras] == pytest.approx([0.5, 1.0, 1.5, 2.0, 2.5, 2.5])


def test_near_on_some_keyframes_only_is_refused(tmp_path):
    keys = [dict(KEY0), dict(KEY2, near=0.5)]
    msg = load_error(tmp_path, keyed(keys))
    assert "the keyframe at frame 2 gives 'near' and the one at frame 0 does not" in msg


def test_orthographic_keys_interpolate_ortho_height_and_perspective_keys_fov():
    ortho = [dict(KEY0, projection="orthographic", ortho_height=2, near=1.0),
             dict(KEY2, projection="orthographic", ortho_height=4, near=3.0)]
    mid = camera_path_from_json(keyed(ortho), "k.json").cameras[1]
    assert mid.is_ortho and mid.ortho_height == pytest.approx(3.0) and mid.near == pytest.approx(2.0)
    persp = [dict(KEY0, fov_y=30), dict(KEY2, fov_y=50)]
    mid = camera_path_from_json(keyed(persp), "k.json").cameras[1]
    assert not mid.is_ortho and mid.fov_y == pytest.approx(40.0)


def test_cli_refuses_a_mixed_projection_path_in_one_line(tmp_path, capsys):
    cam = write(tmp_path, keyed([dict(KEY0), dict(KEY2, projection="orthographic", ortho_height=2)]))
    obj = tmp_path / "tri.obj"
    obj.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(SystemExit) as e:
        main(["render", str(obj), "--camera", str(cam), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert e.value.code == 1 and len(err.strip().splitlines()) == 1 and "cam.json" in err and "mix projections" in err
    assert not (tmp_path / "o").exists() or not any((tmp_path / "o").iterdir())


def test_a_folder_given_as_camera_file_is_named_as_such(tmp_path):
    """--camera naming a folder said "cannot write: Is a directory" (an OSError caught as a write
    failure); it is an input error that says what the path is."""
    with pytest.raises(InputError, match="is a folder, not a camera file"):
        load_camera_path(tmp_path)


def test_keyframes_of_different_image_sizes_are_refused():
    """Frames between two keys of different sizes took the earlier key's size, then jumped: a path
    has one image size (an error naming both keyframes)."""
    keys = [{"frame": 0, "eye": [0, 0, 5], "target": [0, 0, 0]},
            {"frame": 4, "eye": [4, 0, 5], "target": [0, 0, 0], "width": 300}]
    with pytest.raises(InputError, match=r"k\.json: keyframes at frame 0 \(200 x 200 px\) and frame 4 "
                                         r"\(300 x 200 px\) have different image sizes"):
        camera_path_from_json(keyed(keys, frame_count=5), "k.json")


@pytest.mark.parametrize("data,needles", [
    ({"frames": [dict(FRAME0, fovy=20)]}, ["frame 1", 'unknown key "fovy"', "did you mean 'fov_y'"]),
    ({"frames": [KEY0]}, ["frame 1", 'unknown key "frame"']),  # the frames form is in order
    (dict(keyed(), frame_cont=3), ['unknown key "frame_cont"', "did you mean 'frame_count'"]),
    ({"frames": [FRAME0], "keyframes": [KEY0]}, ["both 'frames' and 'keyframes'"]),
    ({"frames": [dict(FRAME0, up=[0, 0, 0])]}, ["frame 1", "'up' is (0, 0, 0)"]),
])
def test_a_typo_or_a_contradiction_in_a_camera_file_is_said(tmp_path, data, needles):
    """A misspelt key ("fovy") silently gave the default (40 degrees); both forms at once silently
    used 'frames'. Keys starting with '_' stay free for comments."""
    msg = load_error(tmp_path, data)
    assert all(n in msg for n in needles), msg


def test_comment_keys_are_allowed(tmp_path):
    path = load_camera_path(write(tmp_path, {"_comment": "shot 12", "frames": [dict(FRAME0, _note="hero")]}))
    assert len(path.cameras) == 1


@pytest.mark.parametrize("elevation", [90.0, -90.0, 89.99999, -89.99999])
def test_orbit_straight_above_or_below_still_turns(elevation):
    """At elevation +-90 the up axis is the view axis: the image's up now turns with the azimuth,
    as it does just short of it (every frame was the same image)."""
    import numpy as np

    from strokekit.camera.paths import orbit_path

    top = orbit_path(np.zeros(3), 1.0, 8, elevation=elevation)
    near = orbit_path(np.zeros(3), 1.0, 8, elevation=elevation - np.sign(elevation) * 1e-4)
    for a, b in zip(top.cameras, near.cameras):
        assert np.allclose(a.basis[0], b.basis[0], atol=1e-4) and np.allclose(a.basis[1], b.basis[1], atol=1e-4)
    rights = np.array([c.basis[0] for c in top.cameras])
    assert len({tuple(np.round(r, 6)) for r in rights}) == 8


# --- a key of the other lens, a frame count the list contradicts, booleans as numbers -------------

@pytest.mark.parametrize("data,needles", [
    ({"frames": [dict(FRAME0, ortho_height=2)]}, ["frame 1", "'ortho_height' belongs to a parallel camera"]),
    ({"frames": [dict(FRAME0, projection="perspective", ortho_height=2)]}, ["frame 1", "'ortho_height'"]),
    (keyed([dict(KEY0, ortho_height=2), KEY2]), ["keyframe 1", "'ortho_height' belongs to a parallel camera"]),
])
def test_a_key_of_the_other_lens_is_refused_by_name(tmp_path, data, needles):
    """'ortho_height' on a perspective frame was accepted and ignored (as 'azimuth' on a
    perspective frame and 'distance' on an orthographic one are not)."""
    msg = load_error(tmp_path, data)
    for n in needles:
        assert n in msg, msg


def test_an_orthographic_frame_with_the_fov_y_earlier_versions_wrote_still_reads(tmp_path):
    """`camera parallel --projection orthographic` wrote an unused fov_y into each frame until now:
    the camera files users keep read as before, the fov_y ignored."""
    ortho = dict(FRAME0, projection="orthographic", ortho_height=2)
    a = load_camera_path(write(tmp_path, {"frames": [dict(ortho, fov_y=30)]})).cameras[0]
    b = load_camera_path(write(tmp_path, {"frames": [ortho]})).cameras[0]
    pts = np.array([[0.3, -0.2, 0.1], [1.0, 0.5, -0.4]])
    assert a.is_ortho and a.ortho_height == b.ortho_height == 2
    assert np.array_equal(a.project(pts)[0], b.project(pts)[0])


def test_a_frame_count_the_frames_list_contradicts_is_refused(tmp_path):
    """"frame_count": 3 beside one entry of 'frames' was accepted and rendered 1 frame. A count
    that agrees is harmless; 'interpolation' has nothing to act on in the frames form."""
    msg = load_error(tmp_path, {"frame_count": 3, "frames": [FRAME0]})
    assert "frame_count 3 disagrees with 'frames', which lists 1 frame " in msg, msg
    assert "frame_count" in load_error(tmp_path, {"frame_count": 1.5, "frames": [FRAME0]})
    assert "'interpolation' belongs to the keyframe form" in load_error(
        tmp_path, {"interpolation": "smooth", "frames": [FRAME0, FRAME0]})
    assert len(load_camera_path(write(tmp_path, {"frame_count": 2, "frames": [FRAME0, FRAME0]}))) == 2


@pytest.mark.parametrize("data,needles", [
    ({"frames": [dict(FRAME0, fov_y=True)]}, ["frame 1", "'fov_y' must be a number, got true"]),
    ({"frames": [dict(FRAME0, fov_y="30")]}, ["frame 1", "'fov_y' must be a number", '"30"']),
    ({"frames": [dict(FRAME0, up=[True, False, False])]}, ["frame 1", "'up' must be a list of 3 numbers",
                                                           "[true, false, false]"]),
    ({"frames": [dict(FRAME0, eye=[0, True, 5])]}, ["frame 1", "'eye' must be a list of 3 numbers"]),
    ({"frames": [dict(FRAME0, target=[False, 0, 0])]}, ["frame 1", "'target' must be a list of 3 numbers"]),
    ({"frames": [dict(FRAME0, near=True)]}, ["frame 1", "'near' must be a number, got true"]),
    ({"frames": [dict(FRAME0, projection="orthographic", ortho_height=True)]}, ["'ortho_height' must be a number"]),
    ({"fps": True, "frames": [FRAME0]}, ["fps must be a number > 0, got true"]),
    (keyed([dict(KEY0, fov_y=False), KEY2]), ["keyframe 1", "'fov_y' must be a number, got false"]),
    ({"frames": [{"projection": "cabinet", "target": [0, 0, 0], "ortho_height": 1, "distance": True}]},
     ["frame 1", "'distance' must be a number, got true"]),
    ({"frames": [{"projection": "cabinet", "target": [0, 0, 0], "ortho_height": True, "distance": 3}]},
     ["frame 1", "'ortho_height' must be a number, got true"]),
    ({"frames": [{"projection": "cabinet", "target": [0, 0, 0], "ortho_height": 1, "distance": 3,
                  "up": [0, True, 0]}]}, ["frame 1", "'up' must be a list of 3 numbers"]),
    ({"frames": [{"projection": "cabinet", "target": [0, 0, 0], "ortho_height": 1, "distance": 3,
                  "oblique_angle": True}]}, ["frame 1", "'oblique_angle' must be a number, got true"]),
])
def test_booleans_are_not_numbers_anywhere_in_a_camera_file(tmp_path, data, needles):
    """"fov_y": true became a 1 degree lens and "up": [true, false, false] the x axis (float(True)
    is 1.0), as "width": true already was not: a boolean where a number belongs is refused."""
    msg = load_error(tmp_path, data)
    for n in needles:
        assert n in msg, msg


def test_the_camera_files_strokekit_writes_read_back():
    """`strokekit camera parallel --projection orthographic` wrote the frame's unused fov_y: the
    writer now leaves it out of parallel frames, and what it writes reads back."""
    from strokekit.camera.paths import parallel_path

    for projection in ("orthographic", "cabinet"):
        path = parallel_path(np.zeros(3), 1.0, projection, frames=2)
        data = json.loads(json.dumps(path.to_json()))
        assert all("fov_y" not in f for f in data["frames"]), data
        back = camera_path_from_json(data, "p.json")
        assert back.cameras[0].eye == pytest.approx(path.cameras[0].eye)


# --- coordinates out of range: one line, no numpy warning -----------------------------------------

@pytest.mark.parametrize("data,needles", [
    ({"frames": [dict(FRAME0, eye=[1e160, 0, 5])]}, ["frame 1", "camera eye (1e+160, 0, 5) is out of range",
                                                     "1e+15"]),
    ({"frames": [dict(FRAME0, eye=[1e308, 0, 5])]}, ["frame 1", "camera eye", "out of range"]),
    ({"frames": [dict(FRAME0, eye=[0, 0, -1.7e308], target=[0, 0, 1.7e308])]}, ["frame 1", "camera eye",
                                                                                 "out of range"]),
    ({"frames": [dict(FRAME0, target=[0, -1e200, 0])]}, ["frame 1", "camera target", "out of range"]),
    ({"frames": [dict(FRAME0, up=[0, 1e200, 0])]}, ["frame 1", "camera up", "out of range"]),
    ({"frames": [dict(FRAME0, near=1e300)]}, ["frame 1", "camera near", "out of range"]),
    ({"frames": [dict(FRAME0, projection="orthographic", ortho_height=1e300)]}, ["camera ortho_height",
                                                                                 "out of range"]),
    ({"frames": [{"projection": "cabinet", "target": [0, 0, 0], "ortho_height": 1, "distance": 1e300}]},
     ["frame 1", "camera distance", "out of range"]),
    ({"frames": [{"projection": "cabinet", "target": [1e300, 0, 0], "ortho_height": 1, "distance": 3}]},
     ["frame 1", "camera target", "out of range"]),
    ({"frames": [{"projection": "cabinet", "target": [0, 0, 0], "ortho_height": 1, "distance": 3,
                  "up": [0, 1e300, 0]}]}, ["frame 1", "camera up", "out of range"]),
    (keyed([KEY0, dict(KEY2, eye=[1e200, 0, 6])]), ["keyframe 2", "camera eye", "out of range"]),
])
def test_a_coordinate_out_of_range_is_said_without_a_numpy_warning(tmp_path, data, needles):
    """An eye at 1e160 overflowed in a dot product (a numpy RuntimeWarning on stderr) and was then
    reported as an 'up' parallel to the view direction. Coordinates and lengths are limited to
    1e15 world units (view.MAX_COORD), checked before any arithmetic."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        msg = load_error(tmp_path, data)
    for n in needles:
        assert n in msg, msg


def test_coordinates_at_the_limit_are_accepted():
    path = camera_path_from_json({"frames": [dict(FRAME0, eye=[1e15, 0, 5]), dict(FRAME0, eye=[-1e15, 1e15, 1e15])]})
    assert path.cameras[1].eye == (-1e15, 1e15, 1e15)


def _gltf_camera(tmp_path: Path, nodes: list) -> Path:
    p = tmp_path / "cam.gltf"
    p.write_text(json.dumps({"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": nodes,
                             "cameras": [{"type": "perspective", "perspective": {"yfov": 0.7, "znear": 0.01}}]}))
    return p


def test_gltf_camera_nodes_out_of_range_say_so_without_a_numpy_warning(tmp_path):
    """A glTF camera node scaled by 1e300 overflowed in the norm of its axes (a numpy warning, then
    'camera target equals eye'); nested, the scales overflowed the world matrix. A camera node's
    scale does not change the view; a translation or world matrix out of range is one line."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for scale in (1e300, 1e-300):
            cam = load_camera_path(_gltf_camera(tmp_path, [{"camera": 0, "scale": [scale] * 3,
                                                            "translation": [0, 0, 5]}])).cameras[0]
            assert cam.eye == (0.0, 0.0, 5.0) and np.allclose(cam.basis[2], [0, 0, -1]), scale
        with pytest.raises(InputError, match=r"cam\.gltf: the world transform of camera node 1 is out of range"):
            load_camera_path(_gltf_camera(tmp_path, [{"children": [1], "scale": [1e300] * 3},
                                                     {"camera": 0, "scale": [1e300] * 3}]))
        with pytest.raises(InputError, match=r"cam\.gltf: camera at node 0: camera eye \(1e\+160, 0, 5\) is out"):
            load_camera_path(_gltf_camera(tmp_path, [{"camera": 0, "translation": [1e160, 0, 5]}]))


def test_frames_past_the_path_s_end_are_all_named():
    """A frame range running past the camera path names every frame beyond it, not its last one."""
    from strokekit.camera.frames import parse_frames
    from strokekit.errors import UsageError

    assert parse_frames("28-30", 30) == [28, 29, 30]
    for spec, said in (("40-45", "frames 40-45 are"), ("25-33", "frames 31-33 are"), ("31", "frame 31 is"),
                       ("1,30-31", "frame 31 is")):
        with pytest.raises(UsageError, match=said):
            parse_frames(spec, 30)
