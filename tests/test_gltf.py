"""glTF ribbons (strokekit.writers.gltf) and brushes (strokekit.ribbons.brushes): GLB layout, material,
embedded texture, camera round trip, sequence visibility keys, and the Khronos validator on GLBs
written for shared models."""

from __future__ import annotations

import io
import json
import os
import shutil
import struct
import subprocess
from pathlib import Path

import numpy as np
import pygltflib
import pytest
from PIL import Image

from strokekit.camera.gltf import gltf_camera_path
from strokekit.camera.view import Camera
from strokekit.errors import InputError, UsageError
from strokekit.model import Strokes
from strokekit.ribbons.brushes import BUNDLED, brush_rgba, bundled_brush, load_brush
from strokekit.writers.gltf import GltfOptions, glb_for_frame, glb_for_sequence, ribbons_for

MODELS = Path(__file__).resolve().parents[2] / "shared" / "models"


def spiral_strokes(camera: Camera, frame: int = 1, n: int = 3) -> Strokes:
    """n strokes: 3D curves on a sphere of radius 1, projected with the camera."""
    pts, surf, off = [], [], [0]
    for k in range(n):
        t = np.linspace(0, 2.5, 40 + 10 * k)
        X = np.stack([np.cos(t + k), np.sin(2 * t) * 0.3 + 0.2 * k, np.sin(t + k)], 1)
        X /= np.linalg.norm(X, axis=1, keepdims=True)
        p, _ = camera.project(X)
        pts.append(p), surf.append(X), off.append(off[-1] + len(p))
    pts, surf = np.concatenate(pts), np.concatenate(surf)
    return Strokes.build(pts, surf, np.zeros(len(pts)), off, np.arange(n) % 3, camera=camera, frame=frame)


CAM = Camera(eye=(0.5, 1.0, 4.0), target=(0.0, 0.0, 0.0), fov_y=40.0, width=640, height=480)


def parse_glb(data: bytes) -> tuple[dict, bytes]:
    magic, version, length = struct.unpack_from("<4sII", data, 0)
    assert magic == b"glTF" and version == 2 and length == len(data)
    jlen, jtype = struct.unpack_from("<I4s", data, 12)
    assert jtype == b"JSON" and jlen % 4 == 0
    doc = json.loads(data[20:20 + jlen])
    rest = data[20 + jlen:]
    blob = b""
    if rest:
        blen, btype = struct.unpack_from("<I4s", rest, 0)
        assert btype == b"BIN\0" and blen % 4 == 0
        blob = rest[8:8 + blen]
    return doc, blob


def accessor_array(doc: dict, blob: bytes, i: int) -> np.ndarray:
    acc = doc["accessors"][i]
    bv = doc["bufferViews"][acc["bufferView"]]
    dt = {5126: "<f4", 5123: "<u2", 5125: "<u4"}[acc["componentType"]]
    n = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}[acc["type"]]
    a = np.frombuffer(blob, dt, acc["count"] * n, bv["byteOffset"] + acc.get("byteOffset", 0))
    return a.reshape(acc["count"], n) if n > 1 else a


def test_frame_glb_layout_material_and_texture():
    """One mesh with a primitive per line kind, 4-byte aligned buffer views, an embedded PNG
    brush with alpha, unlit double-sided BLEND material with a PBR fallback; pygltflib reads it."""
    s = spiral_strokes(CAM)
    data = glb_for_frame(s, CAM, GltfOptions(brush="ink"))
    doc, blob = parse_glb(data)
    assert all(bv["byteOffset"] % 4 == 0 for bv in doc["bufferViews"])
    assert doc["buffers"][0]["byteLength"] == len(blob)
    mesh = doc["meshes"][0]
    assert len(mesh["primitives"]) == 3  # kinds 0, 1, 2
    for prim in mesh["primitives"]:
        mat = doc["materials"][prim["material"]]
        assert mat["doubleSided"] and mat["alphaMode"] == "BLEND"
        assert "KHR_materials_unlit" in mat["extensions"]
        assert mat["pbrMetallicRoughness"]["metallicFactor"] == 0.0
        assert set(prim["attributes"]) == {"POSITION", "TEXCOORD_0", "TEXCOORD_1"}
        ex = prim["extras"]["strokes"]
        assert sum(ex["triangle_count"]) * 3 == doc["accessors"][prim["indices"]]["count"]
    assert "KHR_materials_unlit" in doc["extensionsUsed"] and "extensionsRequired" not in doc
    img = doc["images"][0]
    bv = doc["bufferViews"][img["bufferView"]]
    png = blob[bv["byteOffset"]:bv["byteOffset"] + bv["byteLength"]]
    im = Image.open(io.BytesIO(png))
    assert im.mode == "RGBA" and np.asarray(im)[..., 3].min() == 0 and np.asarray(im)[..., 3].max() >= 240
    g = pygltflib.GLTF2.load_from_bytes(data)
    assert len(g.meshes) == 1 and g.cameras[0].type == "perspective"


def test_positions_and_uvs_match_the_ribbon_mesh():
    """The GLB holds the ribbon vertices (node translation + float32 positions) and texture
    coordinates of strokekit.ribbons, split per kind in stroke order."""
    s = spiral_strokes(CAM)
    opts = GltfOptions()
    m = ribbons_for(s, CAM, opts)
    doc, blob = parse_glb(glb_for_frame(s, CAM, opts))
    node = [n for n in doc["nodes"] if "mesh" in n][0]
    t = np.array(node["translation"])
    vk = m.kind[m.stroke_of_vertex]
    for prim in doc["meshes"][0]["primitives"]:
        k = ["silhouette", "border", "crease"].index(prim["extras"]["kind"])
        pos = accessor_array(doc, blob, prim["attributes"]["POSITION"]) + t
        assert np.abs(pos - m.positions[vk == k]).max() < 1e-5 * np.abs(m.positions).max()
        uv = accessor_array(doc, blob, prim["attributes"]["TEXCOORD_0"])
        assert np.allclose(uv, m.uv[vk == k], atol=1e-6)
        acc = doc["accessors"][prim["attributes"]["POSITION"]]
        assert np.allclose(acc["min"], pos.min(0) - t) and np.allclose(acc["max"], pos.max(0) - t)


@pytest.mark.parametrize("projection", ["perspective", "orthographic"])
def test_camera_node_reproduces_the_frame_view(tmp_path, projection):
    """Opening the GLB shows the same view: the camera read back from the file projects every
    ribbon vertex onto the pixel it was built for."""
    cam = Camera(eye=(2.0, 1.5, 3.0), target=(0.1, 0.0, -0.2), fov_y=50.0, width=640, height=480,
                 projection=projection, ortho_height=3.0)
    s = spiral_strokes(cam)
    opts = GltfOptions()
    path = tmp_path / "f.glb"
    path.write_bytes(glb_for_frame(s, cam, opts))
    back = gltf_camera_path(path, width=640, height=480).cameras[0]
    m = ribbons_for(s, cam, opts)
    px, z = back.project(m.positions)
    assert np.abs(px - m.pixels).max() < 1e-3
    assert np.all(z > 0)


def test_image_space_ribbons_are_flat_pixels_with_an_orthographic_view():
    s = spiral_strokes(CAM)
    doc, blob = parse_glb(glb_for_frame(s, CAM, GltfOptions(space="image", alpha_mode="MASK", alpha_cutoff=0.4)))
    prim = doc["meshes"][0]["primitives"][0]
    pos = accessor_array(doc, blob, prim["attributes"]["POSITION"])
    assert np.all(pos[:, 2] == 0) and pos[:, 0].min() >= -10 and pos[:, 1].max() <= CAM.height + 10
    mat = doc["materials"][0]
    assert mat["alphaMode"] == "MASK" and mat["alphaCutoff"] == pytest.approx(0.4)
    cam = doc["cameras"][0]
    assert cam["type"] == "orthographic" and cam["orthographic"]["ymag"] == CAM.height / 2


def test_same_strokes_same_bytes_and_empty_frame():
    s = spiral_strokes(CAM)
    assert glb_for_frame(s, CAM) == glb_for_frame(s, CAM)
    empty = Strokes.empty(camera=CAM)
    doc, blob = parse_glb(glb_for_frame(empty, CAM))
    assert "meshes" not in doc and doc["cameras"] and doc["scenes"][0]["nodes"]


def step_value(doc, blob, anim, node, path, t):
    """Value of a STEP channel at time t."""
    for ch in anim["channels"]:
        if ch["target"]["node"] == node and ch["target"]["path"] == path:
            smp = anim["samplers"][ch["sampler"]]
            assert smp["interpolation"] == "STEP"
            ts = accessor_array(doc, blob, smp["input"])
            vs = accessor_array(doc, blob, smp["output"])
            i = max(0, int(np.searchsorted(ts, t + 1e-5, side="right")) - 1)  # float32 key times
            return vs[i]
    return None


def test_sequence_shows_each_frame_only_on_its_frame():
    """One node per frame under 'strokes', scale 1 on its own frame and 0 on every other; the
    camera node follows the frame cameras."""
    cams = [Camera(eye=(4 * np.sin(a), 1.0, 4 * np.cos(a)), target=(0, 0, 0), width=640, height=480)
            for a in np.linspace(0, 1, 5)]
    frames = [spiral_strokes(c, frame=i + 1) for i, c in enumerate(cams)]
    opts = GltfOptions(fps=12.0)
    doc, blob = parse_glb(glb_for_sequence(frames, opts))
    root = [n for n in doc["nodes"] if n.get("name") == "strokes"][0]
    kids = root["children"]
    assert len(kids) == 5
    anim = doc["animations"][0]
    cam_node = [i for i, n in enumerate(doc["nodes"]) if "camera" in n][0]
    for f in range(5):
        t = (f + 1) / 12.0  # frame numbers 1..5: key time = frame / fps
        scales = [step_value(doc, blob, anim, k, "scale", t)[0] for k in kids]
        assert scales == [1.0 if i == f else 0.0 for i in range(5)]
        eye = step_value(doc, blob, anim, cam_node, "translation", t)
        assert np.allclose(eye, cams[f].eye, atol=1e-6)
    # before the first frame, the first frame shows
    assert [step_value(doc, blob, anim, k, "scale", 0.0)[0] for k in kids] == [1.0, 0.0, 0.0, 0.0, 0.0]


def test_bundled_brushes_deterministic_with_tiling_body():
    """Brush PNGs are the same bytes every time; the body's last column continues into its first
    (the body repeats without a seam); alpha spans 0..255."""
    for name in BUNDLED:
        b = bundled_brush(name)
        bundled_brush.cache_clear()
        assert bundled_brush(name).png == b.png
        rgba = brush_rgba(b.png).astype(float)
        w = rgba.shape[1]
        x0, x1 = int(b.tex_head * w), int((1 - b.tex_tail) * w)
        # phase 0 (first body column) and phase 1 (first tail column) hold the same edge
        assert np.abs(rgba[:, x0, 3] - rgba[:, x1, 3]).mean() < 0.05 * 255, name
        assert rgba[..., 3].min() == 0 and rgba[..., 3].max() >= 250


def test_user_brush_alpha_from_luminance_unless_it_has_alpha(tmp_path):
    """A scanned stroke on white: white is transparent, black opaque, grey half; an RGBA PNG keeps
    its own alpha."""
    g = np.full((16, 64, 3), 255, np.uint8)
    g[4:12, 8:56] = 0
    g[6:10, 20:30] = 128
    Image.fromarray(g, "RGB").save(tmp_path / "scan.png")
    b = load_brush(tmp_path / "scan.png")
    a = brush_rgba(b.png)[..., 3]
    assert a[0, 0] == 0 and a[5, 10] == 255 and abs(int(a[7, 25]) - 127) <= 2
    assert not b.tinted
    rgba = np.zeros((8, 32, 4), np.uint8)
    rgba[..., 3] = 77
    Image.fromarray(rgba, "RGBA").save(tmp_path / "own.png")
    assert np.all(brush_rgba(load_brush(tmp_path / "own.png").png)[..., 3] == 77)
    with pytest.raises(InputError):
        load_brush(tmp_path / "missing.png")
    (tmp_path / "bad.png").write_bytes(b"not a png")
    with pytest.raises(InputError):
        load_brush(tmp_path / "bad.png")
    # a user's brush is not tinted: the material is white so the scan's own colour shows
    doc, _ = parse_glb(glb_for_frame(spiral_strokes(CAM), CAM, GltfOptions(brush=str(tmp_path / "scan.png"))))
    assert doc["materials"][0]["pbrMetallicRoughness"]["baseColorFactor"] == [1.0, 1.0, 1.0, 1.0]


def test_options_are_checked():
    with pytest.raises(UsageError):
        GltfOptions(alpha_mode="OPAQUE")
    with pytest.raises(UsageError):
        GltfOptions(space="screen")
    with pytest.raises(UsageError):
        GltfOptions(color="red")
    with pytest.raises(InputError):
        glb_for_frame(spiral_strokes(CAM), CAM, GltfOptions(brush="no-such-brush"))


# --- Khronos glTF validator -------------------------------------------------------------------------

_VALIDATE_JS = r"""
const fs = require('fs');
const validator = require('gltf-validator');
(async () => {
  const out = [];
  for (const f of process.argv.slice(2)) {
    const r = await validator.validateBytes(new Uint8Array(fs.readFileSync(f)), {maxIssues: 200, format: 'glb'});
    out.push({file: f, errors: r.issues.numErrors, warnings: r.issues.numWarnings,
              messages: r.issues.messages.filter(m => m.severity <= 1)});
  }
  process.stdout.write(JSON.stringify(out));
})().catch(e => { console.error(String(e)); process.exit(2); });
"""


def _validator_dir() -> Path | None:
    """A folder whose node_modules holds gltf-validator: $GLTF_VALIDATOR_DIR, the repo's
    .ci/node, or /tmp/gv (npm install gltf-validator there)."""
    cands = [os.environ.get("GLTF_VALIDATOR_DIR"), Path(__file__).resolve().parents[1] / ".ci" / "node", "/tmp/gv"]
    for c in cands:
        if c and (Path(c) / "node_modules" / "gltf-validator").is_dir():
            return Path(c)
    return None


def _frames_for_model(name: str, n: int):
    from strokekit.camera.paths import orbit_path
    from strokekit.lines.renderer import LineRenderer
    from strokekit.options import LineOptions
    from strokekit.scene.load import load_scene

    sc = load_scene(MODELS / name)
    path = orbit_path(sc.center, sc.radius, 8, width=512, height=512)
    lr = LineRenderer(sc, LineOptions())
    return [lr.render(path.cameras[i], i + 1) for i in range(n)]


def test_khronos_validator_zero_errors_zero_warnings(tmp_path):
    """Every kind of GLB we write (per frame, sequence, world and image space, BLEND and MASK,
    bundled and user brushes, empty frames) for shared models passes the Khronos validator with
    no error and no warning."""
    if shutil.which("node") is None:
        pytest.skip("node is not installed (needed to run the Khronos glTF validator)")
    vdir = _validator_dir()
    if vdir is None:
        pytest.skip("gltf-validator not found: npm install --prefix .ci/node gltf-validator@2.0.0-dev.3.10 "
                    "(as .ci/run does), or set GLTF_VALIDATOR_DIR")
    models = [m for m in ("spot.obj", "fandisk.obj", "teapot.obj") if (MODELS / m).exists()]
    if not models:
        pytest.skip(f"shared models not found in {MODELS}")
    scan = np.full((32, 128, 3), 255, np.uint8)
    scan[8:24, 10:118] = 40
    Image.fromarray(scan).save(tmp_path / "scan.png")
    variants = [GltfOptions(), GltfOptions(space="image", alpha_mode="MASK", brush="dry"),
                GltfOptions(brush=str(tmp_path / "scan.png"), unlit=False, level_texcoord=False)]
    files = []
    for mi, model in enumerate(models):
        frames = _frames_for_model(model, 3)
        assert sum(len(f) for f in frames) > 0
        for vi, opts in enumerate(variants):
            for f in frames[:1]:
                p = tmp_path / f"{mi}_{vi}_frame.glb"
                p.write_bytes(glb_for_frame(f, f.camera, opts))
                files.append(p)
            p = tmp_path / f"{mi}_{vi}_seq.glb"
            p.write_bytes(glb_for_sequence(frames, opts))
            files.append(p)
    p = tmp_path / "empty.glb"
    p.write_bytes(glb_for_frame(Strokes.empty(camera=CAM), CAM))
    files.append(p)
    js = tmp_path / "validate.js"
    js.write_text(_VALIDATE_JS)
    env = dict(os.environ, NODE_PATH=str(vdir / "node_modules"))
    r = subprocess.run(["node", str(js)] + [str(f) for f in files], capture_output=True, text=True, env=env,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    reports = json.loads(r.stdout)
    assert len(reports) == len(files)
    bad = [(Path(x["file"]).name, x["messages"][:3]) for x in reports if x["errors"] or x["warnings"]]
    assert not bad, bad


def test_primitives_per_kind_hold_their_strokes_when_kinds_are_interleaved():
    """Strokes of mixed kinds in chain order: each primitive holds exactly its kind's strokes
    (ids and triangle ranges in extras), and TEXCOORD_1 carries each stroke's (level, weight)."""
    from dataclasses import replace

    s = spiral_strokes(CAM, n=5)
    s = replace(s, kind=np.array([2, 0, 2, 1, 0], np.int8), ids=np.array([50, 51, 52, 53, 54]),
                level=np.array([0.0, 1.0, 2.0, 3.0, 4.0]), level_weight=np.array([0.1, 0.2, 0.3, 0.4, 0.5]))
    doc, blob = parse_glb(glb_for_frame(s, CAM, GltfOptions(taper=0.0)))
    seen = {}
    for prim in doc["meshes"][0]["primitives"]:
        ex = prim["extras"]
        seen[ex["kind"]] = ex["strokes"]["id"]
        idx = accessor_array(doc, blob, prim["indices"]).reshape(-1, 3)
        lv = accessor_array(doc, blob, prim["attributes"]["TEXCOORD_1"])
        for sid, first, count, level, w in zip(ex["strokes"]["id"], ex["strokes"]["first_triangle"],
                                               ex["strokes"]["triangle_count"], ex["strokes"]["level"],
                                               ex["strokes"]["level_weight"]):
            k = sid - 50
            assert level == k and w == pytest.approx(0.1 * (k + 1))
            verts = np.unique(idx[first:first + count])
            assert np.allclose(lv[verts], [k, 0.1 * (k + 1)])
    assert seen == {"silhouette": [51, 54], "border": [53], "crease": [50, 52]}


def test_float32_positions_stay_on_their_pixels_far_from_the_origin():
    """A scene translated by 1e5: the node translation takes the offset, so the float32 vertices
    stored in the file still project within 0.05 px of their outline."""
    off = np.array([1e5, -2e5, 3e5])
    cam = Camera(eye=tuple(off + [0.5, 1.0, 4.0]), target=tuple(off), fov_y=40.0, width=640, height=480)
    s = spiral_strokes(Camera(eye=(0.5, 1.0, 4.0), target=(0, 0, 0), fov_y=40.0, width=640, height=480))
    from dataclasses import replace

    s = replace(s, surface=s.surface + off, camera=cam)
    opts = GltfOptions()
    m = ribbons_for(s, cam, opts)
    doc, blob = parse_glb(glb_for_frame(s, cam, opts))
    node = [n for n in doc["nodes"] if "mesh" in n][0]
    vk = m.kind[m.stroke_of_vertex]
    for prim in doc["meshes"][0]["primitives"]:
        k = ["silhouette", "border", "crease"].index(prim["extras"]["kind"])
        pos = accessor_array(doc, blob, prim["attributes"]["POSITION"]).astype(float) + node["translation"]
        px, _ = cam.project(pos)
        assert np.abs(px - m.pixels[vk == k]).max() < 0.05


@pytest.mark.parametrize("projection, eye, target", [
    ("perspective", (0.0, 0.0, 1.3), (0.0, 0.0, -400.0)),  # near the sphere, target far away: znear
    ("orthographic", (0.0, 0.0, 30.0), (0.0, 0.0, 29.99)),  # target just ahead of the eye: zfar
])
def test_camera_clip_planes_hold_every_ribbon(projection, eye, target):
    """The glTF camera's clip planes come from the ribbons' depths, not from the eye-target
    distance alone: a viewer must show every ribbon the frame has."""
    cam = Camera(eye=eye, target=target, fov_y=60.0, width=640, height=480, projection=projection,
                 ortho_height=3.0)
    s = spiral_strokes(cam)
    doc, blob = parse_glb(glb_for_frame(s, cam, GltfOptions()))
    c = doc["cameras"][0][projection]
    node = [n for n in doc["nodes"] if n.get("name", "").startswith("strokes_")][0]
    pos = np.concatenate([accessor_array(doc, blob, p["attributes"]["POSITION"])
                          for p in doc["meshes"][node["mesh"]]["primitives"]]) + node.get("translation", [0, 0, 0])
    z = cam.depth(pos)
    assert z.min() > c["znear"] >= 0.0
    assert z.max() < c.get("zfar", np.inf)


def test_sequence_keys_are_never_later_than_their_frame_time():
    """A player sampling a STEP track at exactly N / fps must show frame N: float32(N / 24) is
    later than N / 24 for N = 1, 2, 4, 8, 11, 13, ..., which showed frame N - 1 there."""
    cams = [Camera(eye=(4 * np.sin(a), 1.0, 4 * np.cos(a)), target=(0, 0, 0), width=64, height=48)
            for a in np.linspace(0, 1, 14)]
    frames = [spiral_strokes(c, frame=i + 1, n=1) for i, c in enumerate(cams)]
    doc, blob = parse_glb(glb_for_sequence(frames, GltfOptions(fps=24.0)))
    kids = [n for n in doc["nodes"] if n.get("name") == "strokes"][0]["children"]
    anim = doc["animations"][0]
    for f in range(1, 15):
        shown = []
        for k in kids:
            ch = [c for c in anim["channels"] if c["target"]["node"] == k][0]
            smp = anim["samplers"][ch["sampler"]]
            ts = accessor_array(doc, blob, smp["input"]).astype(float)
            vs = accessor_array(doc, blob, smp["output"])
            shown.append(vs[max(0, int(np.searchsorted(ts, f / 24.0, side="right")) - 1)][0])
        assert shown == [1.0 if i == f - 1 else 0.0 for i in range(14)], f


def test_ribbon_colours_are_the_svg_colours_in_linear_light():
    """baseColorFactor is linear in glTF; the SVG's kind colours are sRGB. Written unconverted, a
    silhouette ribbon rendered lighter than its SVG line."""
    from strokekit.colour import srgb_encode
    from strokekit.model import KINDS
    from strokekit.writers.svg import KIND_COLORS

    doc, _ = parse_glb(glb_for_frame(spiral_strokes(CAM), CAM, GltfOptions(brush="ink")))
    for m in doc["materials"]:
        want = KIND_COLORS[m["name"]]
        got = srgb_encode(m["pbrMetallicRoughness"]["baseColorFactor"][:3])
        assert "#%02x%02x%02x" % tuple(int(round(v * 255)) for v in got) == want
    assert {m["name"] for m in doc["materials"]} <= set(KINDS)
