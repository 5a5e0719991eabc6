"""Issue 21, the library side of tests/test_faults.py: the rules behind each fix, tested where
they live (the camera file reader, the occluder's inside test, the scene cache's warnings, the
line pass's memory estimate, a run's write errors)."""

from __future__ import annotations

import base64
import errno
import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest
import trimesh

from strokekit.camera.paths import camera_path_from_json, orbit_path
from strokekit.camera.view import Camera
from strokekit.errors import InputError, UsageError
from strokekit.lines import budget
from strokekit.lines.sightlines import eye_enclosed
from strokekit.options import LineOptions
from strokekit.run import RenderRequest, RunWriteError, run
from strokekit.run.spec import OutputOptions, RunSpec
from strokekit.scene.load import build_scene, load_scene
from strokekit.scene.occluder import Occluder

# --- camera files ------------------------------------------------------------------------------------


def test_an_up_that_turns_parallel_between_keys_is_an_error_naming_the_frame():
    """The eye passes straight over the target with up (0, 1, 0) on both keys: in the middle
    frame the view is straight down, and its roll would be a fallback's."""
    keys = [{"frame": 0, "eye": [0, 1, 5], "target": [0, 0, 0]}, {"frame": 2, "eye": [0, 1, -5], "target": [0, 0, 0]}]
    with pytest.raises(InputError, match="k.json: frame 1, between the keyframes at frame 0 and frame 2: the up "
                                         "vector turns parallel to the view direction"):
        camera_path_from_json({"frame_count": 3, "keyframes": keys}, "k.json")


def test_an_up_just_off_the_view_axis_is_a_camera_as_any():
    """The threshold is Camera.basis's (1e-6): an up 1e-3 off the view axis fixes the roll."""
    path = camera_path_from_json({"frames": [{"eye": [0, 5, 0], "target": [0, 0, 0], "up": [1e-3, 1, 0]}]}, "c.json")
    right, up, fwd = path.cameras[0].basis
    assert np.allclose(up, [1, 0, 0], atol=1e-9) or np.allclose(up, [-1, 0, 0], atol=1e-9)
    assert Camera(eye=(0, 5, 0), target=(0, 0, 0)).up_along_view  # the library keeps its fallback
    assert not Camera(eye=(0, 5, 0), target=(0, 0, 0), up=(1e-3, 1, 0)).up_along_view


# --- inside a closed mesh, by ray parity ------------------------------------------------------------------

@pytest.mark.parametrize("backend", ["open3d", "embreex"])
@pytest.mark.parametrize("inward", [False, True])
def test_eye_inside_a_closed_box_by_parity_whatever_the_winding(backend, inward):
    box = trimesh.creation.box()
    scene = build_scene(box.vertices, box.faces[:, ::-1] if inward else box.faces)
    occ = Occluder(scene, backend)
    assert occ.backend == backend
    assert eye_enclosed(occ, Camera(eye=(0.1, 0.2, 0.3), target=(1, 0, 0)))
    assert not eye_enclosed(occ, Camera(eye=(3, 2, 1), target=(0, 0, 0)))
    assert not eye_enclosed(occ, Camera(eye=(0.1, 0.2, 0.3), target=(1, 0, 0), projection="orthographic"))


def test_eye_inside_a_thick_walled_room_is_outside_the_solid():
    """Two nested closed boxes (a room with walls of some thickness): the hollow is outside the
    solid (every ray crosses the walls twice); inside the wall itself is inside."""
    outer, inner = trimesh.creation.box(extents=(4, 4, 4)), trimesh.creation.box(extents=(3, 3, 3))
    scene = build_scene(np.r_[outer.vertices, inner.vertices], np.r_[outer.faces, inner.faces[:, ::-1] + 8])
    occ = Occluder(scene)
    assert not eye_enclosed(occ, Camera(eye=(0.1, 0.2, 0.3), target=(1, 0, 0)))
    assert eye_enclosed(occ, Camera(eye=(1.75, 0.2, 0.3), target=(0, 0, 0)))


# --- a scene's warnings, through the cache ----------------------------------------------------------------

def _textured_gltf(path: Path) -> Path:
    box = trimesh.creation.box()
    v, i = box.vertices.astype(np.float32), box.faces.astype(np.uint16).ravel()
    blob = v.tobytes() + i.tobytes()
    doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
           "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": 0}]}],
           "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
           "textures": [{"source": 0}], "images": [{"uri": "wood%20grain.png"}],
           "buffers": [{"byteLength": len(blob),
                        "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode()}],
           "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": v.nbytes},
                           {"buffer": 0, "byteOffset": v.nbytes, "byteLength": i.nbytes}],
           "accessors": [{"bufferView": 0, "componentType": 5126, "count": len(v), "type": "VEC3",
                          "min": [-0.5] * 3, "max": [0.5] * 3},
                         {"bufferView": 1, "componentType": 5123, "count": len(i), "type": "SCALAR"}]}
    path.write_text(json.dumps(doc))
    return path


def test_a_missing_texture_warns_on_every_load_naming_the_file_loaded(tmp_path, monkeypatch):
    """The warning is kept in the scene cache (a cached load warns too) without the file's name,
    which each load adds: a copy elsewhere names the copy. Once the image is there, no warning
    (the image is part of the cache key)."""
    from strokekit.scene import load

    monkeypatch.setenv("STROKEKIT_CACHE", "1")
    monkeypatch.setenv("STROKEKIT_CACHE_DIR", str(tmp_path / "cache"))
    a = _textured_gltf(tmp_path / "a.gltf")
    first = load_scene(a)
    with monkeypatch.context() as m:
        m.setattr(load, "_read_parts", lambda p: pytest.fail("the cache did not answer"))
        second = load_scene(a)
    assert first.warnings == second.warnings and len(first.warnings) == 1
    assert first.warnings[0].startswith(f"{a}: image 0 (wood%20grain.png) not found")
    (tmp_path / "b").mkdir()
    b = Path(shutil.copy(a, tmp_path / "b" / "b.gltf"))
    assert load_scene(b).warnings[0].startswith(f"{b}: ")
    (tmp_path / "wood grain.png").write_bytes(b"not even a PNG: never read")
    assert load_scene(a).warnings == ()


# --- the line pass's memory, before a run ----------------------------------------------------------------

def test_the_line_pass_estimate_follows_the_spacing_and_refuses_what_does_not_fit(monkeypatch):
    box = trimesh.creation.icosphere(subdivisions=3)
    scene = build_scene(box.vertices, box.faces)
    cams = list(enumerate(orbit_path(scene.center, scene.radius, 12, width=800, height=600).cameras, 1))
    coarse = budget.visibility_samples(scene, cams[0][1], LineOptions(sample_spacing_px=4.0))
    fine = budget.visibility_samples(scene, cams[0][1], LineOptions(sample_spacing_px=0.04))
    assert 0 < coarse < fine and 50 < fine / coarse < 100  # ~100x the samples, but for the +1 per edge
    budget.check_lines_fit(scene, cams, LineOptions(sample_spacing_px=0.04))
    monkeypatch.setattr(budget, "machine_memory_bytes", lambda: fine * budget.BYTES_PER_SAMPLE // 2)
    budget.check_lines_fit(scene, cams, LineOptions(sample_spacing_px=4.0))
    with pytest.raises(UsageError, match=r"^sample_spacing_px 0.04 px: the line pass of frame \d+ needs about") as e:
        budget.check_lines_fit(scene, cams, LineOptions(sample_spacing_px=0.04))
    assert e.value.option == "sample_spacing_px"


# --- a run that cannot write ------------------------------------------------------------------------------

def test_a_write_error_stops_the_run_and_raises_it_with_the_result(tmp_path, monkeypatch):
    """The library side of the CLI's one line: run() raises RunWriteError, an OSError naming the
    first file that could not be written, with the result (frames written before, the failed
    frame); the frame's other files are gone."""
    from strokekit import fileio

    box = trimesh.creation.box()
    path = tmp_path / "box.obj"
    box.export(path)
    scene = load_scene(path)
    cams = tuple(enumerate(orbit_path(scene.center, scene.radius, 3, width=64, height=48).cameras, 1))
    out = tmp_path / "o"
    real = os.replace

    def replace(src, dst, *a, **k):
        if Path(dst).name == "frame_0002.json":
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return real(src, dst, *a, **k)

    monkeypatch.setattr(fileio.os, "replace", replace)
    spec = RunSpec(scene_path=str(path), cameras=cams, outputs=OutputOptions(out_dir=out), request=RenderRequest(strokes="lines", coherence="none"))
    with pytest.raises(RunWriteError) as e:
        run(spec)
    assert isinstance(e.value, OSError) and e.value.errno == errno.ENOSPC
    assert e.value.filename == str(out / "frame_0002.json")
    res = e.value.result
    assert res.frames_ok == [1] and list(res.failures) == [2] and res.exit_code == 1 and res.status == "failed"
    assert res.write_error == f"{out / 'frame_0002.json'}: {os.strerror(errno.ENOSPC)}"
    assert sorted(p.name for p in out.iterdir()) == [".strokekit-run.json", "frame_0001.json", "frame_0001.svg"]


def test_open3d_imported_from_several_threads_at_once_is_whole_in_each():
    """A dask worker runs frames in threads: each must get open3d whole, never the half-made module
    another thread is still initializing (AttributeError: partially initialized module 'open3d')."""
    import subprocess
    import sys

    code = ("import threading\n"
            "from strokekit.scene.occluder import import_open3d\n"
            "out = []\n"
            "def go():\n"
            "    try:\n"
            "        out.append(hasattr(import_open3d(), 'core') and hasattr(import_open3d().t, 'geometry'))\n"
            "    except Exception as e:\n"
            "        out.append(repr(e))\n"
            "ts = [threading.Thread(target=go) for _ in range(4)]\n"
            "[t.start() for t in ts]\n[t.join() for t in ts]\n"
            "print(out)\n")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    assert p.stdout.strip() == "[True, True, True, True]"
