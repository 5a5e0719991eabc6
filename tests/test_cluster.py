"""A render on a dask cluster whose scheduler and worker are separate processes, the worker
started in another folder (as on a real cluster): relative paths mean the caller's folder, and a
worker that does not see the caller's files is named before any frame."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest
from test_cli import CUBE_OBJ, run_cli

from strokekit.run.cluster import WorkerCheck

distributed = pytest.importorskip("distributed")

pytestmark = pytest.mark.slow


def _stop(proc: subprocess.Popen) -> None:
    proc.terminate()
    try:
        proc.wait(20)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


@pytest.fixture
def cluster(tmp_path):
    """start(worker_folder, hide=None) -> the scheduler's address: a scheduler and one worker
    process on 127.0.0.1, the worker started in `worker_folder`; `hide`: a folder the worker
    sees empty (an empty file system mounted over it in the worker's own mount namespace: the
    caller's disk is not the worker's)."""
    procs: list[subprocess.Popen] = []

    def start(worker_folder: Path, hide: Path | None = None) -> str:
        info = tmp_path / "scheduler.json"
        procs.append(subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
                                       "--port", "0", "--no-dashboard", "--scheduler-file", str(info)],
                                      cwd=worker_folder, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        worker = [sys.executable, "-m", "distributed.cli.dask_worker", "--scheduler-file", str(info),
                  "--nthreads", "1", "--no-dashboard"]
        if hide is not None:
            if shutil.which("unshare") is None or subprocess.run(
                    ["unshare", "-m", "--propagation", "private", "mount", "-t", "tmpfs", "none", str(hide)],
                    capture_output=True).returncode != 0:
                pytest.skip("no mount namespaces here (unshare -m needs root)")
            worker = ["unshare", "-m", "--propagation", "private", "sh", "-c",
                      f'mount -t tmpfs none "{hide}" && exec "$0" "$@"', *worker]
        deadline = time.monotonic() + 120
        while not info.exists():
            assert time.monotonic() < deadline, "the dask scheduler did not start"
            time.sleep(0.2)
        time.sleep(0.2)  # (written whole)
        address = json.loads(info.read_text())["address"]
        procs.append(subprocess.Popen(worker, cwd=worker_folder, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        with distributed.Client(address, timeout=60) as client:
            client.wait_for_workers(1, timeout=120)
        return address

    yield start
    for proc in reversed(procs):
        _stop(proc)


@pytest.fixture
def folders(tmp_path, monkeypatch):
    """(caller's folder, holding cube.obj: the current folder; the worker's folder)."""
    caller, worker = tmp_path / "caller", tmp_path / "worker"
    caller.mkdir()
    worker.mkdir()
    (caller / "cube.obj").write_text(CUBE_OBJ)
    monkeypatch.chdir(caller)
    return caller, worker


def test_relative_paths_on_a_cluster_are_the_callers(cluster, folders, capsys):
    """A relative scene and --out: the worker, started elsewhere, reads the caller's scene and
    writes the frames into the caller's folder, where the command says it wrote them (it used to
    fail every frame with "cube.obj: file not found", or write them in the worker's folder)."""
    caller, worker = folders
    address = cluster(worker)
    code, _, err = run_cli(["render", "cube.obj", "--orbit", "2", "--size", "64x64", "--out", "out",
                            "--scheduler", address], capsys)
    assert code == 0, err
    assert err.startswith("wrote 2 frame(s) to out/ in ")
    assert sorted(p.name for p in (caller / "out").iterdir()) == [
        ".strokekit-run.json", "frame_0001.json", "frame_0001.svg", "frame_0002.json", "frame_0002.svg"]
    code, _, err = run_cli(["render", caller / "cube.obj", "--orbit", "1", "--size", "64x64", "--out", "out2",
                            "--scheduler", address], capsys)
    assert code == 0 and (caller / "out2" / "frame_0001.svg").is_file(), err
    assert not any(worker.rglob("frame_*"))


def test_a_worker_that_does_not_see_the_callers_files_is_named(cluster, folders, tmp_path, capsys):
    """The worker's disk is not the caller's: one line naming the worker and the path it cannot
    see, exit 1, before any frame (no output folder left behind)."""
    caller, worker = folders
    address = cluster(worker, hide=caller)
    code, _, err = run_cli(["render", "cube.obj", "--orbit", "2", "--size", "64x64", "--out", "out",
                            "--scheduler", address], capsys)
    assert code == 1
    assert len(err.strip().splitlines()) == 1, err
    assert err.startswith(f"strokekit: error: dask worker {address.rsplit(':', 1)[0]}:"), err
    assert f"cannot read the scene {caller / 'cube.obj'}" in err and "--report" not in err
    assert not (caller / "out").exists()
    # the scene where the worker sees it, the output folder where it does not
    shutil.copy(caller / "cube.obj", tmp_path / "cube.obj")
    code, _, err = run_cli(["render", tmp_path / "cube.obj", "--orbit", "2", "--size", "64x64", "--out", "out/a",
                            "--scheduler", address], capsys)
    assert code == 1 and f"does not see the output folder {caller / 'out' / 'a'}" in err, err
    assert not (caller / "out").exists()


def test_the_worker_check_says_what_a_worker_lacks(tmp_path):
    """Each problem a worker can have with the caller's paths, said with the path."""
    scene = tmp_path / "s.obj"
    scene.write_text(CUBE_OBJ)
    (tmp_path / ".mark").write_text("")
    size = os.path.getsize(scene)
    assert WorkerCheck(str(scene), size, str(tmp_path), ".mark")() is None
    assert "cannot read the scene" in WorkerCheck(str(tmp_path / "no.obj"), size, str(tmp_path), ".mark")()
    assert f"reads another file at {scene} ({size} bytes" in WorkerCheck(str(scene), size + 1, str(tmp_path), ".mark")()
    assert "does not see the output folder" in WorkerCheck(str(scene), size, str(tmp_path), ".other")()


def test_a_cluster_run_names_every_file_by_its_absolute_path(tmp_path, monkeypatch):
    """The scene, the output folder and a brush image of one's own, as a cluster's tasks name
    them; a bundled brush stays a name, and a local run keeps the names as given."""
    from strokekit.run.spec import OutputOptions, RunSpec
    from strokekit.writers.gltf import GltfOptions

    monkeypatch.chdir(tmp_path)
    outputs = OutputOptions(out_dir=Path("out"), gltf=True, gltf_options=GltfOptions(brush="brushes/mine.png"))
    spec = RunSpec(scene_path="scene.obj", cameras=(), outputs=outputs, scheduler="tcp://127.0.0.1:8786")
    assert spec.scene_path == str(tmp_path / "scene.obj") and spec.outputs.out_dir == tmp_path / "out"
    assert spec.outputs.gltf_options.brush == str(tmp_path / "brushes" / "mine.png")
    ink = RunSpec(scene_path="scene.obj", cameras=(), scheduler="tcp://127.0.0.1:8786",
                  outputs=OutputOptions(out_dir=Path("out"), gltf=True, gltf_options=GltfOptions(brush="ink")))
    assert ink.outputs.gltf_options.brush == "ink"
    local = RunSpec(scene_path="scene.obj", cameras=(), outputs=outputs)
    assert local.scene_path == "scene.obj" and local.outputs.out_dir == Path("out")
