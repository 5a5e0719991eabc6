"""The run manifest decides what `--skip-existing` may keep: its digests must change with
everything that changes a frame's bytes and with nothing else (an option a later version added,
at its default, leaves the digests of older runs as they were), and a manifest must read back
as it was written."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
import trimesh
from helpers import model_path, run_cli

from strokekit.camera.paths import orbit_path
from strokekit.options import LineOptions
from strokekit.raster.options import PassOptions, RasterOptions
from strokekit.run import RenderRequest, manifest
from strokekit.run.manifest import RUN_MANIFEST, canonical, read_run_manifest, run_manifest, settings_changed
from strokekit.run.spec import OutputOptions, RunSpec
from strokekit.scene.load import load_scene
from strokekit.style.linesets import LineSet, Style
from strokekit.writers.options import GltfOptions


@pytest.fixture(scope="module")
def scenes(tmp_path_factory):
    d = tmp_path_factory.mktemp("scenes")
    trimesh.creation.box().export(d / "box.obj")
    trimesh.creation.icosphere(subdivisions=1).export(d / "ball.obj")
    return {n: load_scene(d / f"{n}.obj") for n in ("box", "ball")}


def _spec(scene, n=4, out="out", cams=None, **kw):
    outputs = kw.pop("outputs", {})
    request = kw.pop("request", {})
    cams = cams or tuple(orbit_path(scene.center, scene.radius, n, width=64, height=64).select(range(1, n + 1)))
    return RunSpec(scene_path="scene.obj", cameras=cams, outputs=OutputOptions(out_dir=Path(out), **outputs),
                   request=RenderRequest(**{"strokes": "lines", "coherence": "none", **request}), **kw)


def _manifest(scenes, scene="box", **kw):
    return run_manifest(_spec(scenes[scene], **kw), scenes[scene])


# Each changes some frame's bytes: each must make another run.
CHANGES = {
    "--stroke-width": dict(request=dict(style=Style(width=2.0))),
    "--decimals": dict(outputs=dict(decimals=3)),
    "--pattern": dict(outputs=dict(pattern="f_{frame:03d}")),
    "--no-json": dict(outputs=dict(json=False)),
    "--gltf": dict(outputs=dict(gltf=True)),
    "--brush": dict(outputs=dict(gltf=True, gltf_options=GltfOptions(brush="pencil"))),
    "--hidden-dashes": dict(request=dict(style=Style(dashes=(4.0, 2.0)))),
    "--dash-paths": dict(outputs=dict(dash_paths=True), request=dict(style=Style(dashes=(4.0, 2.0)))),
    "--style": dict(request=dict(style=Style(sets=(LineSet(name="outline", kinds=("silhouette",)),)))),
    "--svg-lines": dict(outputs=dict(svg_lines="centreline")),
    "--exr": dict(outputs=dict(exr=PassOptions())),
    "--min-length": dict(request=dict(lines=LineOptions(min_length_px=3.0))),
    "--kinds": dict(request=dict(lines=LineOptions(kinds=("silhouette",)))),
    "--bands": dict(request=dict(raster=RasterOptions(bands=4))),
    "--strokes brush": dict(request=dict(strokes="brush", coherence=None)),
    "--coherence kalnins": dict(request=dict(coherence="kalnins")),
}


def test_the_same_run_twice_has_the_same_digests(scenes):
    a, b = _manifest(scenes), _manifest(scenes)
    assert a == b
    assert json.loads(json.dumps(a["settings"])) == a["settings"]  # (plain JSON: what the file keeps)
    assert set(a["frames"]) == {1, 2, 3, 4} and len(set(a["frames"].values())) == 4


def test_the_output_folder_is_not_part_of_the_run(scenes):
    assert _manifest(scenes, out="elsewhere") == _manifest(scenes)


@pytest.mark.parametrize("change", sorted(CHANGES))
def test_each_option_that_changes_bytes_makes_another_run(scenes, change):
    base, other = _manifest(scenes), _manifest(scenes, **CHANGES[change])
    assert other["scene"] == base["scene"]
    assert other["options"] != base["options"] and other["run"] != base["run"], change
    assert settings_changed(base, other), change  # and the refusal can name it


def test_every_option_change_is_its_own_digest(scenes):
    """No two different changes fall on one digest (a digest that left a part of the options out
    would merge some of them)."""
    digests = [_manifest(scenes, **kw)["options"] for kw in CHANGES.values()] + [_manifest(scenes)["options"]]
    assert len(set(digests)) == len(digests)


def test_another_scene_changes_the_scene_digest_alone(scenes):
    box, ball = _manifest(scenes), run_manifest(_spec(scenes["box"]), scenes["ball"])
    assert ball["scene"] != box["scene"] and ball["run"] != box["run"]
    assert ball["options"] == box["options"] and ball["frames"] == box["frames"]


def test_options_added_later_at_their_default_leave_older_digests(scenes):
    """The EXR codec and float type, the dashes and the smooth angle of flat bands entered the
    options after runs had been made: at their defaults (or where they change no byte) they are
    not digested; set otherwise, they are."""
    exr = _manifest(scenes, outputs=dict(exr=PassOptions()))
    assert "codec" not in json.dumps(exr["settings"]) and "precision" not in json.dumps(exr["settings"])
    for other in (PassOptions(codec="piz"), PassOptions(precision="full")):
        assert _manifest(scenes, outputs=dict(exr=other))["options"] != exr["options"]
    plain = _manifest(scenes)
    assert not any("hidden_dashes" in k or "dash_paths" in k for k in plain["settings"])
    flat = [_manifest(scenes, request=dict(raster=RasterOptions(shading="flat", smooth_angle_deg=a)))
            for a in (20.0, 40.0)]
    assert flat[0]["options"] == flat[1]["options"]
    smooth = [_manifest(scenes, request=dict(raster=RasterOptions(shading="smooth", smooth_angle_deg=a)))
              for a in (20.0, 40.0)]
    assert smooth[0]["options"] != smooth[1]["options"]


def test_a_brush_image_of_ones_own_is_digested_by_its_bytes(scenes, tmp_path):
    png = tmp_path / "brush.png"
    png.write_bytes(b"one")
    one = _manifest(scenes, outputs=dict(gltf=True, gltf_options=GltfOptions(brush=str(png))))
    png.write_bytes(b"two")
    two = _manifest(scenes, outputs=dict(gltf=True, gltf_options=GltfOptions(brush=str(png))))
    assert one["options"] != two["options"] and "brush_sha256" in json.dumps(two["settings"])


def test_a_frame_digest_is_its_camera_or_with_carried_strokes_all_before_it(scenes):
    s = scenes["box"]
    cams = tuple(orbit_path(s.center, s.radius, 4, width=64, height=64).select(range(1, 5)))
    moved = cams[:2] + ((3, dataclasses.replace(cams[2][1], fov_y=cams[2][1].fov_y + 1.0)),) + cams[3:]
    # Lines drawn afresh: a frame's digest is its own camera's.
    a, b = _manifest(scenes, cams=cams), _manifest(scenes, cams=moved)
    assert [f for f in a["frames"] if a["frames"][f] != b["frames"][f]] == [3]
    # Tracked strokes carry over: frame 3's camera changes frames 3 and 4, not 1 and 2; a longer
    # range of the same path keeps the digests of the frames it shares.
    carried = dict(request=dict(coherence="kalnins"))
    a, b = _manifest(scenes, cams=cams, **carried), _manifest(scenes, cams=moved, **carried)
    assert [f for f in a["frames"] if a["frames"][f] != b["frames"][f]] == [3, 4]
    head = _manifest(scenes, cams=cams[:2], **carried)
    assert head["frames"] == {1: a["frames"][1], 2: a["frames"][2]}
    assert head["frames"][1] != _manifest(scenes, cams=cams[:2])["frames"][1]  # (chained, not the camera's)


def test_canonical_is_plain_json_in_a_fixed_form():
    @dataclasses.dataclass(frozen=True)
    class Part:
        a: tuple = (1, 2)
        b: Path = Path("x/y")

    assert canonical({1: Part(), "n": np.float32(0.5), "i": np.int64(3), "none": None}) == {
        "1": {"a": [1, 2], "b": "x/y"}, "n": 0.5, "i": 3, "none": None}
    assert type(canonical(np.int64(3))) is int
    with pytest.raises(TypeError, match="cannot digest a object"):
        canonical(object())


def test_a_manifest_reads_back_as_written(scenes, tmp_path):
    m = _manifest(scenes)
    path = manifest.write_run_manifest(tmp_path, m, {3: "c", 1: "a", 2: "b"})
    assert path == tmp_path / RUN_MANIFEST
    text = path.read_text()
    assert list(json.loads(text)["frames"]) == ["1", "2", "3"] and text.endswith("}\n")
    back = read_run_manifest(tmp_path)
    assert back == {"strokekit_run": 1, "run": m["run"], "scene": m["scene"], "options": m["options"],
                    "settings": m["settings"], "frames": {1: "a", 2: "b", 3: "c"}}


@pytest.mark.parametrize("text", [
    "not json", "[]", '{"strokekit_run": 2, "run": "r", "scene": "s", "options": "o", "frames": {}}',
    '{"strokekit_run": 1, "run": 5, "scene": "s", "options": "o", "frames": {}}',
    '{"strokekit_run": 1, "run": "r", "scene": "s", "frames": {}}',
    '{"strokekit_run": 1, "run": "r", "scene": "s", "options": "o", "frames": {"one": "x"}}',
    '{"strokekit_run": 1, "run": "r", "scene": "s", "options": "o"}'])
def test_a_manifest_of_another_version_or_broken_is_none(tmp_path, text):
    (tmp_path / RUN_MANIFEST).write_text(text)
    assert read_run_manifest(tmp_path) is None


def test_no_manifest_is_none(tmp_path):
    assert read_run_manifest(tmp_path) is None


def test_the_refused_resume_names_changed_cameras_as_ranges():
    new = {"run": "r1", "scene": "s", "options": "o", "frames": {f: "c" for f in range(1, 12)}}
    old = {**new, "run": "r0", "frames": {**new["frames"], **{f: "x" for f in (1, 2, 3, 7, 9, 10, 11)}}}
    said = manifest.not_a_resume(Path("out"), old, new, {1, 2, 3, 4, 7, 9, 10, 11, 12})
    assert "(.strokekit-run.json differs: cameras of frames 1-3, 7, 9-11);" in said
    assert "holds frames of another run" in said  # (neither scene nor options differ)
    one = manifest.not_a_resume(Path("out"), {**new, "run": "r0", "frames": {**new["frames"], 5: "x"}}, new, {5})
    assert "cameras of frames 5);" in one


def test_the_refused_resume_says_at_most_three_settings():
    """...and not an output turned off beside them (that alone would resume): --no-json here."""
    old = {"settings": {"lines.min_length_px": 0.0, "lines.split_angle_deg": 90.0, "outputs.decimals": 2,
                        "outputs.svg": True, "outputs.json": True, "gone": 1}}
    new = {"settings": {"lines.min_length_px": 3.0, "lines.split_angle_deg": 45.0, "outputs.decimals": 3,
                        "outputs.svg": True, "outputs.json": False}}
    said = settings_changed(old, new)
    assert said == ("gone 1 there, none now; --min-length 0.0 there, 3.0 now; --split-angle 90.0 there, 45.0 now; "
                    "1 more")
    assert settings_changed(old, new, most=5).endswith("--split-angle 90.0 there, 45.0 now; --decimals 2 there, 3 now")
    assert settings_changed({}, new) == "" and settings_changed(old, {"settings": None}) == ""


def test_an_output_turned_on_again_is_said_by_its_switch_alone():
    """A run with --gltf against a manifest without it (GLBs of an earlier run may be there): the
    refusal names --gltf, not each of the ribbons' options (none there); a raster pass or EXR
    on in one run only is said as one setting."""
    old = {"settings": {"outputs.gltf": True, "outputs.gltf_options.taper": 8.0, "outputs.gltf_options.unlit": True,
                        "lines.min_length_px": 0.0}}
    new = {"settings": {"outputs.gltf": False, "outputs.gltf_options": None, "lines.min_length_px": 0.0}}
    assert settings_changed(new, old) == "--gltf false there, true now"
    assert settings_changed(old, new) == "--gltf true there, false now"
    bands = {"settings": {"outputs.json": True, "outputs.raster_options.bands": 3, "outputs.raster_options.shade": True,
                          "outputs.exr": None}}
    exr = {"settings": {"outputs.json": True, "outputs.raster_options": None, "outputs.exr.passes": ["depth"]}}
    assert settings_changed(bands, exr) == "--exr none there, on now; a raster pass on there, none now"


# --- a resume with outputs turned off -------------------------------------------------------------

#: Outputs a run may turn off and still resume, each with options only it reads set otherwise than
#: the run that turns it off has them: {name: (the earlier run's options, the resuming run's)}.
DROPS = {
    "--gltf": (dict(outputs=dict(gltf=True, gltf_options=GltfOptions(taper=2.0, brush="dry"))), {}),
    "--gltf-sequence": (dict(outputs=dict(gltf=True, gltf_sequence=True, gltf_options=GltfOptions())), {}),
    "--no-svg": (dict(outputs=dict(decimals=4, svg_lines="centreline")), dict(outputs=dict(svg=False))),
    "--no-json": ({}, dict(outputs=dict(json=False))),
    "--exr": (dict(outputs=dict(exr=PassOptions(codec="piz")), request=dict(raster=RasterOptions(bands=4))),
              dict(request=dict(raster=RasterOptions(bands=4)))),
    "--lines-png": (dict(outputs=dict(lines_png=True)), {}),
    "--bands with --no-json": (dict(outputs=dict(json=False), request=dict(raster=RasterOptions(bands=3))),
                               dict(outputs=dict(json=False))),
    "--gltf and --exr": (dict(outputs=dict(gltf=True, gltf_options=GltfOptions(), exr=PassOptions()),
                              request=dict(raster=RasterOptions(bands=3))),
                         dict(request=dict(raster=RasterOptions(bands=3)))),
}


def _through_a_file(m: dict) -> dict:
    """A manifest as the next run reads it from the folder."""
    return {**json.loads(json.dumps({k: v for k, v in m.items() if k != "frames"})), "frames": m["frames"]}


@pytest.mark.parametrize("drop", sorted(DROPS))
def test_a_run_that_only_turns_outputs_off_resumes(scenes, drop):
    """Its digests differ (a folder's manifest tells the runs apart), yet the frames of the run
    before count as its own; turning the output on again is no resume (the manifest no longer
    holds that output's options)."""
    before, now = (_manifest(scenes, **kw) for kw in DROPS[drop])
    assert before["options"] != now["options"]
    assert manifest.resumes_from(_through_a_file(before), now), drop
    assert not manifest.resumes_from(_through_a_file(now), before), drop


#: Runs that turn an output off and change what a kept output holds: {what: (before, now, said)}.
NOT_DROPS = {
    "--stroke-width": (dict(outputs=dict(gltf=True, gltf_options=GltfOptions())),
                       dict(request=dict(style=Style(width=2.0))), "--stroke-width 1.5 there, 2.0 now"),
    "--decimals": (dict(outputs=dict(gltf=True)), dict(outputs=dict(decimals=3)), "--decimals 2 there, 3 now"),
    "--kinds": ({}, dict(outputs=dict(json=False), request=dict(
        lines=LineOptions(kinds=("silhouette",)))), "--kinds silhouette,border,crease,material,nonmanifold there, "
        "silhouette now"),
    # The frame JSON says what the raster pass saw (objects, materials): kept, it keeps the raster pass.
    "--bands with the JSON": (dict(request=dict(raster=RasterOptions(bands=3))), {},
                              "a raster pass on there, none now"),
    # The EXR reads the raster pass: only its PNGs turned off is another raster pass.
    "--bands with --exr": (dict(outputs=dict(exr=PassOptions()), request=dict(raster=RasterOptions(bands=4))),
                           dict(outputs=dict(exr=PassOptions()), request=dict(raster=RasterOptions(pngs=False))),
                           "--bands 4 there, 3 now; the raster PNGs true there, false now"),
    "--exr with the JSON": (dict(outputs=dict(exr=PassOptions()), request=dict(raster=RasterOptions(pngs=False))),
                            {}, "a raster pass on there, none now"),
    "--pattern": (dict(outputs=dict(gltf=True)), dict(outputs=dict(pattern="f_{frame:03d}")),
                  "--pattern frame_{frame:04d} there, f_{frame:03d} now"),
}


@pytest.mark.parametrize("what", sorted(NOT_DROPS))
def test_turning_an_output_off_with_a_shared_change_is_another_run(scenes, what):
    """Refused, naming the change and not the output turned off."""
    before, now, said = NOT_DROPS[what]
    old, new = _through_a_file(_manifest(scenes, **before)), _manifest(scenes, **now)
    assert not manifest.resumes_from(old, new), what
    assert settings_changed(old, new) == said


def test_a_resume_trusts_only_settings_that_are_the_options_digested(scenes):
    """An edited manifest (settings that no longer give its options digest) or one written
    before settings were kept is no resume with an output turned off."""
    old = _through_a_file(_manifest(scenes, outputs=dict(gltf=True)))
    new = _manifest(scenes)
    assert manifest.resumes_from(old, new)
    edited = {**old, "settings": {**old["settings"], "outputs.gltf_sequence": True}}
    assert not manifest.resumes_from(edited, new)
    assert not manifest.resumes_from({k: v for k, v in old.items() if k != "settings"}, new)
    assert not manifest.resumes_from(old, _manifest(scenes, "ball"))  # (another scene)
    assert not manifest.resumes_from(None, new)


def test_a_folder_rendered_by_an_earlier_version_still_resumes(tmp_path, capsys):
    """The digests are a contract with the folders users already have: these are the manifest of
    `render spot.obj --orbit 12 --strokes lines` as the version before this test wrote it (frames
    1 and 2). A change to the digests' spelling (a key, the order, the length) refuses every one
    of those folders with --skip-existing."""
    out = tmp_path / "o"
    code, _, err = run_cli(["render", model_path("spot.obj"), "--orbit", "12", "--frames", "1-2", "--strokes", "lines",
                            "--out", out, "-q"], capsys)
    assert code == 0, err
    m = read_run_manifest(out)
    assert (m["run"], m["scene"], m["options"]) == ("d2ce8e07b1cf145f", "1cf18937921a7fd1", "d344e8cf2402895f")
    assert m["frames"] == {1: "7f94792914b16beb", 2: "e3c9d42360792484"}
    assert (out / RUN_MANIFEST).read_text().startswith('{\n "strokekit_run": 1,\n "run": "d2ce8e07b1cf145f",')


def test_the_refused_resume_is_one_exact_line():
    out, fix = Path("some/out"), "remove them or render without --skip-existing"
    new = {"run": "r1", "scene": "s1", "options": "o1", "frames": {1: "a", 2: "b"}}
    both = {**new, "run": "r0", "scene": "s0", "options": "o0", "frames": {1: "a", 2: "x"}}
    assert manifest.not_a_resume(out, both, new, {1, 2}) == (
        "--skip-existing: some/out/ holds frames of another scene or other options (.strokekit-run.json differs: "
        f"scene, options, cameras of frames 2); {fix}")
    old = {**new, "run": "r0", "options": "o0", "settings": {"outputs.decimals": 2}}
    assert manifest.not_a_resume(out, old, {**new, "settings": {"outputs.decimals": 3}}, {1}) == (
        "--skip-existing: some/out/ holds frames of other options (.strokekit-run.json differs: options "
        f"(--decimals 2 there, 3 now)); {fix}")
    # Settings that differ where the options digest does not (an edited file) are not named.
    same = {**new, "run": "r0", "settings": {"outputs.decimals": 2}}
    assert manifest.not_a_resume(out, same, {**new, "settings": {"outputs.decimals": 3}}, {1}) == (
        f"--skip-existing: some/out/ holds frames of another run (.strokekit-run.json differs: run); {fix}")
