"""OBJ material libraries and object names: a missing .mtl is a warning and its usemtl groups stay
materials; objects are named by the OBJ's `o` (else `g`) lines, not by their materials."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from strokekit.scene.load import load_scene
from strokekit_cli.main import main

CUBE_V = "".join(f"v {x} {y} {z}\n" for x, y, z in [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0),
                                                     (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)])
SIDES = "f 1 4 3\nf 1 3 2\nf 1 2 6\nf 1 6 5\nf 2 3 7\nf 2 7 6\nf 3 4 8\nf 3 8 7\nf 4 1 5\nf 4 5 8\n"
LID = "f 5 6 7\nf 5 7 8\n"
MTL = "newmtl wood\nKd 0.6 0.4 0.2\nnewmtl metal\nKd 0.7 0.7 0.75\n"


def crate(folder: Path, mtl: bool, head: str = "o crate\n", lid_head: str = "") -> Path:
    """A unit box: 10 faces of wood, a lid of 2 faces of metal (4 material-boundary edges)."""
    p = folder / "crate.obj"
    p.write_text("mtllib lid.mtl\n" + head + CUBE_V + "usemtl wood\n" + SIDES + lid_head + "usemtl metal\n" + LID)
    if mtl:
        (folder / "lid.mtl").write_text(MTL)
    return p


@pytest.fixture(autouse=True)
def own_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("STROKEKIT_CACHE", "1")
    monkeypatch.setenv("STROKEKIT_CACHE_DIR", str(tmp_path / "cache"))


def lid_material(scene) -> set[str]:
    top = np.all(np.isclose(scene.vertices[scene.faces][:, :, 2], 1.0), axis=1)
    return {scene.materials[i].name for i in scene.face_material[top]}


def test_a_missing_material_library_is_a_warning_naming_the_obj_and_the_library(tmp_path):
    """The .mtl was dropped in silence (trimesh logs at debug level): one materials, no boundary,
    `--kinds material` drew nothing. The warning goes where a glTF's missing texture's does, and a
    cached load says it too."""
    p = crate(tmp_path, mtl=False)
    first, second = load_scene(p), load_scene(p)
    assert first.warnings == second.warnings and len(first.warnings) == 1, first.warnings
    w = first.warnings[0]
    assert w.startswith(f"{p}: material library lid.mtl not found beside the file") and "\n" not in w, w
    (tmp_path / "lid.mtl").write_text(MTL)
    assert load_scene(p).warnings == ()


def test_without_its_library_the_usemtl_groups_stay_materials_of_the_default_colour(tmp_path):
    with_mtl = load_scene(crate(tmp_path, mtl=True))
    (tmp_path / "lid.mtl").unlink()
    without = load_scene(tmp_path / "crate.obj")
    assert sorted(m.name for m in without.materials) == ["metal", "wood"]
    assert all(m.base_color == (0.8, 0.8, 0.8, 1.0) for m in without.materials)
    assert int(without.is_material_boundary.sum()) == int(with_mtl.is_material_boundary.sum()) == 4
    assert lid_material(without) == lid_material(with_mtl) == {"metal"}
    assert without.objects == with_mtl.objects


def test_one_usemtl_without_its_library_keeps_the_default_material(tmp_path):
    p = tmp_path / "one.obj"
    p.write_text("mtllib gone.mtl\no box\n" + CUBE_V + "usemtl wood\n" + SIDES + LID)
    s = load_scene(p)
    assert [m.name for m in s.materials] == ["default"] and s.objects == ("box",)
    assert "gone.mtl not found" in s.warnings[0]


@pytest.mark.parametrize("mtl", [True, False])
def test_objects_are_named_by_the_obj_not_by_their_materials(tmp_path, mtl):
    """With two materials trimesh named the pieces "metal" and "wood": those went into object ids
    and Cryptomatte names. The object is the OBJ's `o crate`, one object of two materials."""
    s = load_scene(crate(tmp_path, mtl=mtl))
    assert s.objects == ("crate",) and set(s.face_object.tolist()) == {0}
    assert sorted(m.name for m in s.materials) == ["metal", "wood"]


def test_two_objects_sharing_materials_keep_their_names_and_faces(tmp_path):
    s = load_scene(crate(tmp_path, mtl=True, head="o box\n", lid_head="o lid\n"))
    assert sorted(s.objects) == ["box", "lid"]
    top = np.all(np.isclose(s.vertices[s.faces][:, :, 2], 1.0), axis=1)
    assert {s.objects[i] for i in s.face_object[top]} == {"lid"}
    assert {s.objects[i] for i in s.face_object[~top]} == {"box"}
    assert lid_material(s) == {"metal"}


def test_groups_name_the_objects_of_an_obj_without_o_lines(tmp_path):
    s = load_scene(crate(tmp_path, mtl=True, head="g body\n", lid_head="g top\n"))
    assert sorted(s.objects) == ["body", "top"]


def test_cli_draws_the_material_boundaries_of_an_obj_without_its_library(tmp_path, capsys):
    p = crate(tmp_path, mtl=False)
    cam = tmp_path / "c.json"
    cam.write_text('{"width": 200, "height": 200, "frames": [{"eye": [3, 2.5, 4], "target": [0.5, 0.5, 0.5]}]}')
    with pytest.raises(SystemExit) as e:
        main(["render", str(p), "--camera", str(cam), "--kinds", "material", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    warn = [line for line in err.splitlines() if line.startswith("strokekit: warning:")]
    assert e.value.code in (0, None) and len(warn) == 1 and f"{p}: material library lid.mtl" in warn[0], err
    svg = (tmp_path / "o" / "frame_0001.svg").read_text()
    assert svg.count("<path") >= 1
