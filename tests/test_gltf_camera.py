"""A glTF camera node with its animation as a camera path (BRIEF 1.2: "a glTF camera node (with its
animation, if any) is a third source"): small GLBs built here with pygltflib (a box and a camera
node), sampled at the path's fps and checked against the analytic camera motion."""

from __future__ import annotations

import base64
import json
import math
import re
from pathlib import Path

import numpy as np
import pygltflib
import pytest

from strokekit.camera.gltf import gltf_camera_path
from strokekit.camera.paths import load_camera_path
from strokekit.camera.view import Camera
from strokekit.errors import InputError

YFOV = 0.7  # radians

BOX_POS = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], np.float32)
BOX_TRI = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                    [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]], np.uint16)


class Glb:
    """A glTF document under construction: a box mesh (node 0) and a perspective camera; arrays
    packed into one binary blob (GLB chunk or, for .gltf, a base64 data URI)."""

    def __init__(self):
        self.blob = bytearray()
        self.g = pygltflib.GLTF2(
            asset=pygltflib.Asset(version="2.0"), scene=0, scenes=[pygltflib.Scene(nodes=[0])],
            cameras=[pygltflib.Camera(type="perspective", perspective=pygltflib.Perspective(
                yfov=YFOV, aspectRatio=1.5, znear=0.01))],
            nodes=[], meshes=[], accessors=[], bufferViews=[], buffers=[], animations=[])
        pos = self.accessor(BOX_POS, "VEC3", target=34962)
        idx = self.accessor(BOX_TRI.reshape(-1), "SCALAR", target=34963, component=5123)
        self.g.meshes.append(pygltflib.Mesh(primitives=[pygltflib.Primitive(
            attributes=pygltflib.Attributes(POSITION=pos), indices=idx)]))
        self.node(mesh=0)

    def accessor(self, arr, kind: str, target=None, component=5126, stride=None) -> int:
        """Accessor of `arr`; with `stride` the elements sit `stride` bytes apart (interleaved
        with filler bytes)."""
        a = np.asarray(arr, np.float32 if component == 5126 else np.uint16)
        rows = a.reshape(len(a), -1)
        esize = rows.shape[1] * a.itemsize
        if stride:
            raw = bytearray(b"\xff" * (stride * len(rows)))
            for k, r in enumerate(rows):
                raw[k * stride:k * stride + esize] = r.tobytes()
        else:
            raw = rows.tobytes()
        while len(self.blob) % 4:
            self.blob.append(0)
        self.g.bufferViews.append(pygltflib.BufferView(buffer=0, byteOffset=len(self.blob), byteLength=len(raw),
                                                       byteStride=stride, target=target))
        self.blob += raw
        kw = {}
        if kind == "VEC3" and component == 5126:
            kw = {"min": rows.min(0).tolist(), "max": rows.max(0).tolist()}
        if kind == "SCALAR" and component == 5126:
            kw = {"min": [float(rows.min())], "max": [float(rows.max())]}
        self.g.accessors.append(pygltflib.Accessor(bufferView=len(self.g.bufferViews) - 1, componentType=component,
                                                   count=len(rows), type=kind, **kw))
        return len(self.g.accessors) - 1

    def node(self, parent: int | None = None, **kw) -> int:
        self.g.nodes.append(pygltflib.Node(**kw))
        i = len(self.g.nodes) - 1
        if parent is None:
            self.g.scenes[0].nodes.append(i) if i else None
        else:
            p = self.g.nodes[parent]
            p.children = (p.children or []) + [i]
        return i

    def animate(self, channels: list[tuple[int, str, list, list, str]], stride=None) -> None:
        """One animation; channels (node, path, key times, values, interpolation)."""
        anim = pygltflib.Animation(channels=[], samplers=[])
        for node, path, times, values, interp in channels:
            kind = "VEC4" if path == "rotation" else "VEC3"
            inp = self.accessor(np.asarray(times, float), "SCALAR")
            out = self.accessor(np.asarray(values, float), kind, stride=stride)
            anim.samplers.append(pygltflib.AnimationSampler(input=inp, output=out, interpolation=interp))
            anim.channels.append(pygltflib.AnimationChannel(
                sampler=len(anim.samplers) - 1, target=pygltflib.AnimationChannelTarget(node=node, path=path)))
        self.g.animations.append(anim)

    def save(self, path: Path) -> Path:
        blob = bytes(self.blob) + b"\0" * (-len(self.blob) % 4)
        if path.suffix == ".glb":
            self.g.buffers = [pygltflib.Buffer(byteLength=len(blob))]
            self.g.set_binary_blob(blob)
            self.g.save_binary(str(path))
        else:
            uri = "data:application/octet-stream;base64," + base64.b64encode(blob).decode()
            self.g.buffers = [pygltflib.Buffer(byteLength=len(blob), uri=uri)]
            self.g.save_json(str(path))
        return path


def f32(v):
    return np.asarray(v, np.float32).astype(np.float64)


def yaw_quat(deg: float) -> list[float]:
    """(x, y, z, w) of a rotation by deg about +Y."""
    h = math.radians(deg) / 2
    return [0.0, math.sin(h), 0.0, math.cos(h)]


def yaw_dir(theta: np.ndarray) -> np.ndarray:
    """View direction (local -Z) after a rotation by theta (radians) about +Y."""
    return np.stack([-np.sin(theta), np.zeros_like(theta), -np.cos(theta)], -1)


def eyes(path) -> np.ndarray:
    return np.array([c.eye for c in path.cameras])


def fwds(path) -> np.ndarray:
    return np.array([c.basis[2] for c in path.cameras])


@pytest.mark.parametrize("suffix,stride", [(".glb", None), (".gltf", 20)])
def test_linear_translation_gives_one_camera_per_frame_on_the_line(tmp_path, suffix, stride):
    """A to B over 1 s at 24 fps: 25 frames (both ends included), frame k exactly at A + k/24 (B - A);
    the lens is the camera's yfov. Also from a .gltf with a data URI and a strided output."""
    A, B = [0.0, 0.5, 6.0], [3.0, -1.0, 4.0]
    doc = Glb()
    cam = doc.node(camera=0, translation=A)
    doc.animate([(cam, "translation", [0.0, 1.0], [A, B], "LINEAR")], stride=stride)
    path = gltf_camera_path(doc.save(tmp_path / f"s{suffix}"))
    assert len(path) == 25 and path.fps == 24.0
    t = np.arange(25) / 24.0
    expected = np.array(A) + t[:, None] * (np.array(B) - np.array(A))
    assert np.abs(eyes(path) - expected).max() < 1e-12
    assert np.allclose(fwds(path), [0, 0, -1], atol=1e-15)
    c = path.cameras[0]
    assert c.fov_y == pytest.approx(math.degrees(f32(YFOV))) and (c.width, c.height) == (1536, 1024)
    # another fps samples the same motion more or less densely; sizes given are kept
    p10 = gltf_camera_path(tmp_path / f"s{suffix}", width=300, height=200, fps=10)
    assert len(p10) == 11 and p10.fps == 10.0 and (p10.cameras[3].width, p10.cameras[3].height) == (300, 200)
    assert np.abs(eyes(p10) - (np.array(A) + (np.arange(11) / 10)[:, None] * np.subtract(B, A))).max() < 1e-12


def test_frames_span_all_camera_channels_from_the_earliest_to_the_latest_key(tmp_path):
    """Translation keys on [0.5, 1], rotation keys on [0, 1.5]: frames cover 0..1.5 s; before its
    first key a channel holds its first value, after its last key its last value."""
    doc = Glb()
    cam = doc.node(camera=0, translation=[9, 9, 9])
    doc.animate([(cam, "translation", [0.5, 1.0], [[0, 0, 5], [0, 0, 7]], "LINEAR"),
                 (cam, "rotation", [0.0, 1.5], [yaw_quat(0), yaw_quat(0)], "LINEAR")])
    path = gltf_camera_path(doc.save(tmp_path / "s.glb"))
    assert len(path) == 37
    z = eyes(path)[:, 2]
    assert np.all(z[:13] == 5.0) and np.all(z[24:] == 7.0) and z[18] == pytest.approx(6.0, abs=1e-12)


def test_rotation_is_slerp_about_y(tmp_path):
    """Yaw keys 0, 120, 240 degrees at t = 0, 1, 2: the view direction turns at a constant rate
    in each segment (slerp), matching the analytic direction within 1e-9 (angles of the stored
    float32 quaternions); up stays +Y."""
    keys = [yaw_quat(a) for a in (0, 120, 240)]
    doc = Glb()
    cam = doc.node(camera=0, translation=[0, 0, 5])
    doc.animate([(cam, "rotation", [0.0, 1.0, 2.0], keys, "LINEAR")])
    path = gltf_camera_path(doc.save(tmp_path / "s.glb"))
    assert len(path) == 49
    q = f32(keys)
    key_angles = 2 * np.arctan2(q[:, 1], q[:, 3])
    t = np.arange(49) / 24.0
    theta = np.interp(t, [0.0, 1.0, 2.0], key_angles)
    assert np.abs(fwds(path) - yaw_dir(theta)).max() < 1e-9
    assert np.abs(np.array([c.basis[1] for c in path.cameras]) - [0, 1, 0]).max() < 1e-9
    assert np.allclose(eyes(path), [0, 0, 5])


def test_rotation_slerp_takes_the_shortest_way(tmp_path):
    """A key stored as the negated quaternion (same rotation) turns 90 degrees, not 270."""
    neg = [-x for x in yaw_quat(90)]
    doc = Glb()
    cam = doc.node(camera=0)
    doc.animate([(cam, "rotation", [0.0, 1.0], [yaw_quat(0), neg], "LINEAR")])
    path = gltf_camera_path(doc.save(tmp_path / "s.glb"))
    q = f32(neg)
    end = 2 * np.arctan2(-q[1], -q[3])
    assert np.abs(fwds(path) - yaw_dir(np.arange(25) / 24.0 * end)).max() < 1e-9


def test_camera_under_an_animated_parent_follows_the_parent(tmp_path):
    """Parent at (1, 0, 0), scale 2, turning 0 -> 180 degrees about Y over 1 s; the camera child at
    (0, 0, 5) keeps looking at the parent's origin while its eye orbits at radius 10. An earlier
    animation that moves only the box is not the camera's."""
    doc = Glb()
    parent = doc.node(translation=[1, 0, 0], scale=[2, 2, 2])
    doc.node(parent=parent, camera=0, translation=[0, 0, 5])
    doc.animate([(0, "translation", [0.0, 3.0], [[0, 0, 0], [0, 9, 0]], "LINEAR")])
    doc.animate([(parent, "rotation", [0.0, 1.0], [yaw_quat(0), [0, 1, 0, 0]], "LINEAR")])
    path = gltf_camera_path(doc.save(tmp_path / "s.glb"))
    assert len(path) == 25  # the box's 3 s animation does not count
    theta = np.pi * np.arange(25) / 24.0
    expected = np.array([1, 0, 0]) + 10 * np.stack([np.sin(theta), 0 * theta, np.cos(theta)], -1)
    assert np.abs(eyes(path) - expected).max() < 1e-9
    assert np.abs(fwds(path) - yaw_dir(theta)).max() < 1e-9


def test_step_holds_each_value_until_the_next_key(tmp_path):
    P = [[0, 0, 5], [1, 0, 5], [2, 0, 5]]
    doc = Glb()
    cam = doc.node(camera=0)
    doc.animate([(cam, "translation", [0.0, 0.5, 1.0], P, "STEP")])
    path = gltf_camera_path(doc.save(tmp_path / "s.glb"))
    assert len(path) == 25
    x = eyes(path)[:, 0]
    assert np.all(x[:12] == 0.0) and np.all(x[12:24] == 1.0) and x[24] == 2.0


def test_step_keys_at_float32_times_land_on_their_frames(tmp_path):
    """Key times k/24 stored as float32 are not the float64 frame times: each frame still shows its
    own key, not the one before (the sequence GLBs strokekit writes are keyed this way)."""
    from strokekit.model import Strokes
    from strokekit.writers.gltf import GltfOptions, glb_for_sequence

    cams = [Camera(eye=(4 * np.sin(a), 1.0 + a, 4 * np.cos(a)), target=(0, 0, 0), width=320, height=240, fov_y=45)
            for a in np.linspace(0, 1.3, 30)]
    frames = [Strokes.empty(camera=c, frame=i + 1) for i, c in enumerate(cams)]
    p = tmp_path / "seq.glb"
    p.write_bytes(glb_for_sequence(frames, GltfOptions(fps=24.0)))
    back = gltf_camera_path(p, fps=24.0)
    assert len(back) == 30
    assert np.abs(eyes(back) - np.array([c.eye for c in cams])).max() < 1e-5
    assert np.abs(fwds(back) - np.array([c.basis[2] for c in cams])).max() < 1e-5
    assert back.cameras[0].fov_y == pytest.approx(45.0, abs=1e-4)


def test_cubicspline_with_zero_tangents_passes_through_the_keys(tmp_path):
    """Zero tangents: every key is a frame value exactly, halfway between keys is the midpoint and
    elsewhere the Hermite blend 3s^2 - 2s^3; rotation keys are met too."""
    P = np.array([[0, 0, 5], [2, 1, 5], [2, 3, 1]], float)
    Z = np.zeros(3)
    R = [yaw_quat(0), yaw_quat(60), yaw_quat(-30)]
    Zq = [0.0] * 4
    doc = Glb()
    cam = doc.node(camera=0)
    doc.animate([(cam, "translation", [0.0, 0.5, 1.0], [v for p in P for v in (Z, p, Z)], "CUBICSPLINE"),
                 (cam, "rotation", [0.0, 0.5, 1.0], [v for q in R for v in (Zq, q, Zq)], "CUBICSPLINE")])
    path = gltf_camera_path(doc.save(tmp_path / "s.glb"))
    assert len(path) == 25
    e = eyes(path)
    for k, frame in enumerate((0, 12, 24)):
        assert np.abs(e[frame] - P[k]).max() < 1e-12
        q = f32(R[k])
        assert np.abs(path.cameras[frame].basis[2] - yaw_dir(np.array(2 * np.arctan2(q[1], q[3])))).max() < 1e-9
    assert np.abs(e[6] - (P[0] + P[1]) / 2).max() < 1e-12
    s = 4 / 12
    h = 3 * s * s - 2 * s ** 3
    assert np.abs(e[16] - ((1 - h) * P[1] + h * P[2])).max() < 1e-12


def test_without_camera_animation_one_frame_at_the_rest_transform(tmp_path):
    """No animation, or one that moves only the box: the rest transform gives one frame."""
    for animate in (False, True):
        doc = Glb()
        doc.node(camera=0, translation=[0, 1, 5], rotation=yaw_quat(30))
        if animate:
            doc.animate([(0, "scale", [0.0, 1.0], [[1, 1, 1], [2, 2, 2]], "LINEAR")])
        path = load_camera_path(doc.save(tmp_path / f"s{animate}.glb"))
        assert len(path) == 1
        assert np.allclose(path.cameras[0].eye, [0, 1, 5])
        assert np.allclose(path.cameras[0].basis[2], yaw_dir(np.array(math.radians(30))), atol=1e-7)


@pytest.mark.parametrize("break_it,needle", [
    (lambda g: setattr(g.animations[0].samplers[0], "interpolation", "BEZIER"), "interpolation 'BEZIER'"),
    (lambda g: setattr(g.accessors[g.animations[0].samplers[0].output], "count", 50), "reads past the end"),
    (lambda g: setattr(g.accessors[g.animations[0].samplers[0].output], "type", "VEC2"), "VEC3 values"),
    (lambda g: setattr(g.accessors[g.animations[0].samplers[0].output], "componentType", 5125), "neither float"),
    (lambda g: setattr(g.animations[0].samplers[0], "input", 99), "accessor 99"),
    (lambda g: setattr(g.animations[0].channels[0], "sampler", 3), "sampler 3"),
    (lambda g: setattr(g.nodes[1], "matrix", np.eye(4).reshape(-1).tolist()), "has a matrix"),
])
def test_malformed_animation_is_one_clear_error(tmp_path, break_it, needle):
    doc = Glb()
    cam = doc.node(camera=0)
    doc.animate([(cam, "translation", [0.0, 1.0], [[0, 0, 5], [0, 0, 6]], "LINEAR")])
    break_it(doc.g)
    p = doc.save(tmp_path / "bad.glb")
    with pytest.raises(InputError) as e:
        gltf_camera_path(p)
    msg = str(e.value)
    assert needle in msg and str(p) in msg and "\n" not in msg


def test_key_times_must_increase(tmp_path):
    doc = Glb()
    cam = doc.node(camera=0)
    doc.animate([(cam, "translation", [0.0, 1.0, 1.0], [[0, 0, 5], [0, 0, 6], [0, 0, 7]], "LINEAR")])
    with pytest.raises(InputError, match="increase strictly"):
        gltf_camera_path(doc.save(tmp_path / "bad.glb"))


def test_cli_renders_one_frame_per_animation_frame(tmp_path, capsys):
    """`render scene.glb --camera scene.glb` draws the box from the animated camera: 4 frames for a
    1/8 s animation at 24 fps; a bad animation is one line and exit 1."""
    from strokekit_cli.main import main

    doc = Glb()
    cam = doc.node(camera=0, translation=[0, 0, 6])
    doc.animate([(cam, "translation", [0.0, 0.125], [[0, 0, 6], [1.5, 0.5, 6]], "LINEAR")])
    scene = doc.save(tmp_path / "scene.glb")
    with pytest.raises(SystemExit) as e:
        main(["render", str(scene), "--camera", str(scene), "--size", "96x64", "--out", str(tmp_path / "o"), "-q"])
    err = capsys.readouterr().err
    assert e.value.code == 0, err
    svgs = sorted(p.name for p in (tmp_path / "o").glob("*.svg"))
    assert svgs == [f"frame_{k:04d}.svg" for k in (1, 2, 3, 4)]
    d1 = json.loads((tmp_path / "o" / "frame_0001.json").read_text())
    d4 = json.loads((tmp_path / "o" / "frame_0004.json").read_text())
    assert d1["strokes"] and d4["strokes"] and d1["strokes"] != d4["strokes"]

    doc.g.animations[0].samplers[0].interpolation = "BEZIER"
    bad = doc.save(tmp_path / "bad.glb")
    with pytest.raises(SystemExit) as e:
        main(["render", str(scene), "--camera", str(bad), "--out", str(tmp_path / "o2"), "-q"])
    err = capsys.readouterr().err
    assert e.value.code == 1 and "BEZIER" in err and len(err.strip().splitlines()) == 1


@pytest.mark.parametrize("xmag,ymag,needle", [
    (1.0, 0.0, "xmag and ymag must be > 0"),
    # A width past the image limit (the writers failed on it later).
    (1e9, 1.0, "orthographic xmag / ymag .* the width must be 1 to 100000 px"),
])
def test_orthographic_lens_giving_no_usable_image_is_one_clear_error(tmp_path, xmag, ymag, needle):
    doc = Glb()
    doc.g.cameras = [pygltflib.Camera(type="orthographic", orthographic=pygltflib.Orthographic(
        xmag=xmag, ymag=ymag, znear=0.0, zfar=10.0))]
    doc.node(camera=0, translation=[0, 0, 5])
    with pytest.raises(InputError, match=needle):
        gltf_camera_path(doc.save(tmp_path / "o.glb"))


@pytest.mark.parametrize("matrix", [[1.0] * 15, [1.0] * 17])
def test_camera_node_matrix_of_the_wrong_size_is_one_clear_error(tmp_path, matrix):
    """A node matrix that is not 16 numbers was an internal error (numpy's reshape ValueError)."""
    doc = Glb()
    doc.node(camera=0, matrix=matrix)
    with pytest.raises(InputError, match=r"m\.glb: node 1 has a malformed matrix: glTF needs 16 numbers"):
        gltf_camera_path(doc.save(tmp_path / "m.glb"))


def test_camera_node_matrix_places_the_camera(tmp_path):
    doc = Glb()
    doc.node(camera=0, matrix=[1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 2, 3, 5, 1])  # column-major: translation last
    cam = gltf_camera_path(doc.save(tmp_path / "m.glb")).cameras[0]
    assert np.allclose(cam.eye, [2, 3, 5]) and np.allclose(cam.basis[2], [0, 0, -1])


@pytest.mark.parametrize("aspect,needle", [
    (1e30, "aspectRatio 1e+30 gives an image 1.024e+33 x 1024 px: the width must be 1 to 100000 px"),
    (1e-9, "aspectRatio 1e-09 gives an image"),
    (-2.0, "aspectRatio must be a number > 0, got -2.0"),
])
def test_perspective_aspect_ratio_giving_no_usable_width_is_one_clear_error(tmp_path, aspect, needle):
    """aspectRatio 1e30 was accepted and the frame failed later in the writers ('Integer exceeds
    64-bit range'); a width of 0 or below was blamed on the image size, not the lens."""
    doc = Glb()
    doc.g.cameras[0].perspective.aspectRatio = aspect
    doc.node(camera=0, translation=[0, 0, 5])
    with pytest.raises(InputError, match=re.escape("a.glb: camera at node 1: perspective " + needle)):
        gltf_camera_path(doc.save(tmp_path / "a.glb"))


@pytest.mark.parametrize("kind,block,needle", [
    ("orthographic", None, "camera 0 is orthographic but has no 'orthographic' block (xmag, ymag)"),
    ("perspective", None, "camera 0 is perspective but has no 'perspective' block (yfov)"),
    ("fisheye", "perspective", "camera 0 has type 'fisheye': glTF cameras are 'perspective' or 'orthographic'"),
])
def test_camera_without_the_lens_its_type_names_is_one_clear_error(tmp_path, kind, block, needle):
    """An orthographic camera without its 'orthographic' block was drawn in perspective at 40
    degrees (exit 0); likewise a perspective one without 'perspective', and an unknown type."""
    doc = Glb()
    lens = doc.g.cameras[0].perspective
    doc.g.cameras = [pygltflib.Camera(type=kind, perspective=lens if block == "perspective" else None)]
    doc.node(camera=0, translation=[0, 0, 5])
    with pytest.raises(InputError, match=re.escape("l.glb: " + needle)):
        gltf_camera_path(doc.save(tmp_path / "l.glb"))


def test_a_child_index_naming_no_node_is_one_clear_error(tmp_path):
    """A node whose children name a node the file does not have was accepted (the camera drawn as
    if the child were not there); it is a broken file."""
    doc = Glb()
    cam = doc.node(camera=0, translation=[0, 0, 5])
    doc.g.nodes[cam].children = [7]
    with pytest.raises(InputError, match=r"c\.glb: node 1 has child 7, but there is no such node"):
        gltf_camera_path(doc.save(tmp_path / "c.glb"))
