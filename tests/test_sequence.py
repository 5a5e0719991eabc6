"""The in-memory sequence (`strokekit.render_sequence`): the frames `strokekit render` writes."""

from __future__ import annotations

import json

import numpy as np
import pytest
from helpers import SAMPLES

from strokekit import LineRenderer, RenderRequest, load_camera_path, load_scene, render_sequence
from strokekit_cli.main import main


def _cli(args, capsys) -> int:
    with pytest.raises(SystemExit) as e:
        main([str(a) for a in args])
    capsys.readouterr()
    return e.value.code


@pytest.fixture(scope="module")
def still_life():
    return load_scene(SAMPLES / "still_life.glb"), load_camera_path(SAMPLES / "orbit.json")


@pytest.mark.parametrize("extra, request_", [
    ([], RenderRequest()),  # a sequence: brush paths carried from frame to frame
    (["--strokes", "lines"], RenderRequest(strokes="lines")),  # the lines, tracked
])
def test_render_sequence_gives_the_frames_the_cli_writes(still_life, tmp_path, capsys, extra, request_):
    """The still life's first four frames: each Frame has the ids and points of the frame JSON
    the command writes, and Frame.to_json() is that file's bytes."""
    scene, path = still_life
    out = tmp_path / "o"
    assert _cli(["render", SAMPLES / "still_life.glb", "--camera", SAMPLES / "orbit.json", "--frames", "1-4",
                 "--workers", "1", "--no-svg", "-q", "--out", out, *extra], capsys) == 0
    frames = list(render_sequence(scene, path.cameras[:4], request_))
    assert [f.number for f in frames] == [1, 2, 3, 4]
    for f in frames:
        written = (out / f"frame_{f.number:04d}.json").read_bytes()
        doc = json.loads(written)
        assert [s["id"] for s in doc["strokes"]] == f.strokes.ids.tolist()
        points = np.concatenate([np.asarray(s["points"], float).reshape(-1, 2) for s in doc["strokes"]])
        assert np.allclose(points, f.strokes.points, atol=5e-5)
        assert f.to_json() == written
    # The strokes are carried over: brush paths, or lines whose ids are no longer chain order.
    doc = json.loads(frames[3].to_json())
    if request_.strokes == "lines":
        assert doc["tracking"] == "kalnins" and frames[3].paths is None
        untracked = LineRenderer(scene, request_.lines).render(path.cameras[3], 4)
        assert frames[3].strokes.ids.tolist() != untracked.ids.tolist()
    else:
        assert doc["tracking"] == doc["strokes_are"] == "brush" and all(f.paths is not None for f in frames)


def test_the_readme_example_renders_a_tracked_sequence(tmp_path, monkeypatch):
    """The README's Python example, as it stands there (run in a folder beside the samples)."""
    monkeypatch.chdir(SAMPLES.parent)
    out = tmp_path / "svg"
    out.mkdir()
    said = []
    # --- README: from here ---
    from strokekit import RenderRequest, load_camera_path, load_scene, render_sequence

    scene = load_scene("samples/still_life.glb")
    path = load_camera_path("samples/orbit.json")
    for frame in render_sequence(scene, path.cameras[:4], RenderRequest(strokes="lines")):
        strokes = frame.strokes                # tracked lines: a line keeps its id from frame to frame
        said.append((frame.number, strokes.ids.tolist()))
        (out / f"frame_{frame.number:04d}.svg").write_text(frame.to_svg())
    # --- README: to here ---
    assert [n for n, _ in said] == [1, 2, 3, 4]
    untracked = LineRenderer(scene, RenderRequest().lines).render(path.cameras[3], 4)
    assert said[-1][1] != untracked.ids.tolist()  # ids carried from frame 1, not frame 4's own chain order
    assert sorted(p.name for p in out.iterdir()) == [f"frame_{n:04d}.svg" for n in (1, 2, 3, 4)]


def test_a_sequence_of_one_camera_draws_its_lines_and_a_raster_pass_stays_in_memory(still_life):
    """One camera: the exact lines, untracked; with a raster request the Frame holds the raster
    pass (its images), and the frame JSON says its objects."""
    from strokekit.raster.bands import RasterOptions

    scene, path = still_life
    (frame,) = render_sequence(scene, path.cameras[:1], RenderRequest(raster=RasterOptions(bands=2)))
    assert frame.paths is None and frame.strokes is frame.lines
    assert frame.raster is not None and set(frame.raster.images()) >= {"bands", "shade"}
    doc = json.loads(frame.to_json())
    assert doc["tracking"] == "none" and "strokes_are" not in doc
    assert [o["name"] for o in doc["raster"]["objects"]] == list(scene.objects)
