"""The optional dependencies (`strokekit[cluster]`: dask.distributed, `strokekit[plot]`:
matplotlib): the README's main job runs without them, and a feature that needs one says in one
line which extra installs it, before any work (exit 2), never a traceback."""

from __future__ import annotations

import subprocess
import sys

from helpers import SAMPLES
from test_cli import CUBE_OBJ

#: Run strokekit's main with `BLOCKED` made impossible to import, as in an install without extras.
_WITHOUT = """
import sys
BLOCKED = {blocked!r}

class Blocker:
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in BLOCKED:
            raise ModuleNotFoundError(f"No module named {{name!r}}", name=name)
        return None

sys.meta_path.insert(0, Blocker())
from strokekit_cli.main import main
main({args!r})
"""


def without(blocked: tuple[str, ...], args: list[str], cwd) -> subprocess.CompletedProcess:
    code = _WITHOUT.format(blocked=blocked, args=[str(a) for a in args])
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=cwd, timeout=600)


def test_the_readme_job_needs_no_extra(tmp_path):
    p = without(("dask", "distributed", "matplotlib"),
                ["render", SAMPLES / "still_life.glb", "--camera", SAMPLES / "orbit.json", "--frames", "1-3", "--gltf",
                 "--bands", "3", "--out", "out", "-q"], tmp_path)
    assert p.returncode == 0, p.stderr
    assert (tmp_path / "out" / "frame_0003.glb").is_file() and (tmp_path / "out" / "bands" / "frame_0003.png").is_file()


def test_a_feature_without_its_extra_says_which_to_install(tmp_path):
    (tmp_path / "cube.obj").write_text(CUBE_OBJ)
    for blocked, args, line in (
            (("dask", "distributed"), ["render", "cube.obj", "--orbit", "2", "--scheduler", "tcp://127.0.0.1:8786"],
             "strokekit: error: --scheduler needs distributed, an optional dependency: "
             "pip install 'strokekit[cluster]'"),
            (("matplotlib",), ["bench", "cube.obj", "--frames", "1", "--plot", "p.png"],
             "strokekit: error: --plot needs matplotlib, an optional dependency: pip install 'strokekit[plot]'")):
        p = without(blocked, args, tmp_path)
        assert p.returncode == 2, p.stderr
        assert p.stderr.strip().splitlines() == [line], p.stderr
        assert not (tmp_path / "out").exists() and not (tmp_path / "p.png").exists()


def test_the_report_names_the_open3d_build_installed(monkeypatch):
    """open3d's CPU-only build is the distribution open3d-cpu: the run report's open3d version
    said None for it."""
    import importlib.metadata

    from strokekit.run.report import installed_versions

    def version(name):
        if name == "open3d-cpu":
            return "0.20.0"
        raise importlib.metadata.PackageNotFoundError(name)

    monkeypatch.setattr(importlib.metadata, "version", version)
    assert installed_versions()["open3d"] == "0.20.0"
