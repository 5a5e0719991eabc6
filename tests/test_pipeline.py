"""Issue 7: a run computes only what is asked, survives failed frames, resumes after being
killed, and gives the same bytes in a process pool, inline or on a dask cluster."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from dataclasses import replace
from functools import partial
from pathlib import Path

import numpy as np
import pytest
from helpers import SAMPLES, cli_env, model_path

from strokekit.metrics.svg_reader import read_svg
from strokekit.scene.load import load_scene
from strokekit_cli.main import main


def run_cli(args, capsys):
    with pytest.raises(SystemExit) as e:
        main([str(a) for a in args])
    out = capsys.readouterr()
    return e.value.code, out.out, out.err


def tree_bytes(d: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(d.iterdir()) if p.is_file()}


def test_explain_lists_only_needed_stages_for_lines_only_one_material(tmp_path, capsys):
    code, out, _ = run_cli(["render", model_path("spot.obj"), "--orbit", "1", "--out", tmp_path, "--explain", "-q",
                            "--report", tmp_path / "run.json"], capsys)
    assert code == 0
    ran = {s["stage"].strip(): s for s in json.loads((tmp_path / "run.json").read_text())["stages"]}
    for name in ("material boundary", "raster pass", "ribbons + glTF", "tracking", "border"):
        assert ran[name]["ran"] is False, name
    for name in ("feature edges", "visibility", "chaining", "svg", "json"):
        assert ran[name]["ran"] is True and ran[name]["seconds"] > 0, name
    assert "[skip] raster pass" in out and "[skip]   material boundary" in out


def test_failed_frame_does_not_lose_the_others(tmp_path, capsys):
    cube = tmp_path / "cube.obj"
    import trimesh

    trimesh.creation.box(extents=[2, 2, 2]).export(cube)
    cam = tmp_path / "cam.json"
    cam.write_text(json.dumps({"width": 120, "height": 90, "frames": [
        {"eye": [0, 1, 6], "target": [0, 0, 0]}, {"eye": [0.1, 0.1, 0.1], "target": [1, 0, 0]},
        {"eye": [6, 1, 0], "target": [0, 0, 0]}]}))
    code, _, err = run_cli(["render", cube, "--camera", cam, "--out", tmp_path / "o", "--report",
                            tmp_path / "run.json"], capsys)
    assert code == 3
    assert "frame 2" in err and "inside the mesh" in err
    names = sorted(p.name for p in (tmp_path / "o").iterdir())
    assert names == [".strokekit-run.json", "frame_0001.json", "frame_0001.svg", "frame_0003.json", "frame_0003.svg"]
    rep = json.loads((tmp_path / "run.json").read_text())
    assert rep["frames"]["2"]["status"] == "failed" and rep["frames"]["1"]["status"] == "ok"
    assert rep["exit_code"] == 3 and list(rep["failures"]) == ["2"]
    # --fail-fast stops at the failure and still reports it.
    code, _, err = run_cli(["render", cube, "--camera", cam, "--out", tmp_path / "ff", "--fail-fast"], capsys)
    assert code == 3 and "stopped at frame 2 (--fail-fast), 1 not run" in err
    assert sorted(p.name for p in (tmp_path / "ff").iterdir()) == [".strokekit-run.json", "frame_0001.json",
                                                                   "frame_0001.svg"]


def test_report_has_versions_hashes_frames_outputs(tmp_path, capsys):
    code, _, _ = run_cli(["render", SAMPLES / "still_life.glb", "--camera", SAMPLES / "orbit.json", "--frames", "1-2",
                          "--out", tmp_path / "o", "-q", "--report", tmp_path / "r.json"], capsys)
    assert code == 0
    rep = json.loads((tmp_path / "r.json").read_text())
    assert rep["versions"]["strokekit"] and rep["versions"]["numpy"]
    assert len(rep["scene"]["sha256"]) == 64
    # Which occlusion backend drew the lines (a fallback's last digits can differ).
    from strokekit.scene.occluder import Occluder

    assert rep["ray_tracer"] == Occluder(load_scene(SAMPLES / "still_life.glb")).backend
    assert set(rep["frames"]) == {"1", "2"} and all(f["status"] == "ok" for f in rep["frames"].values())
    assert sorted(Path(p).name for p in rep["outputs"]) == sorted(p.name for p in (tmp_path / "o").iterdir())
    # Enough to render a frame again: where the cameras came from (and the file's hash), each
    # frame's camera, and every output option, not only the line options.
    assert rep["cameras"]["source"].endswith("orbit.json") and len(rep["cameras"]["sha256"]) == 64
    from strokekit.camera.paths import load_camera_path
    from strokekit.camera.view import Camera

    cam2 = load_camera_path(SAMPLES / "orbit.json").cameras[1]
    assert Camera(**{k: tuple(v) if isinstance(v, list) else v for k, v in rep["frames"]["2"]["camera"].items()}) == cam2
    assert rep["options"]["outputs"]["svg"] is True and rep["options"]["outputs"]["decimals"] == 2
    # A sequence draws brush paths by default: their options are reported, the lines are not tracked.
    assert rep["options"]["strokes"] == "brush" and rep["options"]["paths_options"]["history"] is True
    assert rep["options"]["tracking"] == "none" and rep["options"]["tracking_options"] is None
    assert {s["stage"]: s["ran"] for s in rep["stages"]}["brush paths"] is True
    # The scene's clock and the style are options too: without them a moving scene or a styled
    # run could not be drawn again from its report.
    assert (rep["options"]["animation"], rep["options"]["time_offset"], rep["options"]["style"]) == (None, 0.0, None)
    assert rep["options"]["fps"] == load_camera_path(SAMPLES / "orbit.json").fps
    code, _, _ = run_cli(["render", SAMPLES / "still_life.glb", "--camera", SAMPLES / "orbit.json", "--frames", "1",
                          "--time-offset", "0.5", "--style", SAMPLES / "five.toml", "--out", tmp_path / "s", "-q",
                          "--report", tmp_path / "s.json"], capsys)
    styled = json.loads((tmp_path / "s.json").read_text())["options"]
    assert code == 0 and styled["time_offset"] == 0.5 and styled["style"]["sets"][0]["name"] == "five"


@pytest.mark.parametrize("kind", ["threads", "processes"])
def test_pool_and_inline_give_identical_bytes(tmp_path, capsys, kind):
    """Frames drawn by two workers (threads of this process, or a process pool) give the bytes of
    one worker: brush paths and their raster passes (the bands: per-thread z-buffers)."""
    args = ["render", SAMPLES / "still_life.glb", "--camera", SAMPLES / "orbit.json", "--frames", "1-4", "-q",
            "--bands", "2"]
    assert run_cli(args + ["--out", tmp_path / "one", "--workers", "1"], capsys)[0] == 0
    assert run_cli(args + ["--out", tmp_path / "two", "--workers", "2", "--worker-kind", kind], capsys)[0] == 0
    assert tree_bytes(tmp_path / "one") == tree_bytes(tmp_path / "two")


def test_the_default_pool_is_threads_with_a_raster_pass_and_processes_for_long_line_runs(monkeypatch):
    """Unsaid --workers/--worker-kind: threads on every core with a raster pass (from 2 frames);
    without one, one worker below PROCESSES_FROM frames and processes on every core from there;
    a said kind or count is kept, and a RunSpec of kind "auto" settles on the same kind."""
    import os

    from strokekit.run.spec import PROCESSES_FROM, OutputOptions, RunSpec, pool_for

    monkeypatch.setattr(os, "cpu_count", lambda: 4)
    assert pool_for(1, True) == (1, "threads") and pool_for(12, True) == (4, "threads")
    assert pool_for(PROCESSES_FROM - 1, False) == (1, "threads")
    assert pool_for(PROCESSES_FROM, False) == (4, "processes")
    assert pool_for(PROCESSES_FROM, False, kind="threads") == (4, "threads")
    assert pool_for(24, False, workers=3) == (3, "threads") and pool_for(120, False, 2) == (2, "processes")
    assert pool_for(120, False, 1) == (1, "threads")  # (no pool: not said to be processes)
    cams = tuple((k, None) for k in range(1, PROCESSES_FROM + 1))
    spec = RunSpec(scene_path="x.obj", cameras=cams, outputs=OutputOptions(out_dir=Path("o")), workers=2)
    assert spec.worker_kind == "processes"


def test_a_closed_process_pool_leaves_no_manager_thread_for_the_exit_hook():
    """Closing a process pool joins its manager thread: one still closing its pipes when the
    interpreter exits races concurrent.futures' exit hook, which then prints a traceback."""
    from strokekit.options import LineOptions
    from strokekit.run.workers import SceneRef, make_executor

    w = make_executor(2, None, warm=SceneRef(str(SAMPLES / "still_life.glb"), "", LineOptions()), kind="processes")
    manager = w.executor._executor_manager_thread
    assert manager is not None and manager.is_alive()
    w.close()
    assert not manager.is_alive()


def test_dask_local_cluster_gives_identical_bytes(tmp_path, capsys):
    distributed = pytest.importorskip("distributed")
    args = ["render", SAMPLES / "still_life.glb", "--camera", SAMPLES / "orbit.json", "--frames", "1-3", "-q"]
    assert run_cli(args + ["--out", tmp_path / "local", "--workers", "1"], capsys)[0] == 0
    with distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=False, dashboard_address=None) as cl:
        code, _, err = run_cli(args + ["--out", tmp_path / "dask", "--scheduler", cl.scheduler_address], capsys)
    assert code == 0, err
    assert tree_bytes(tmp_path / "local") == tree_bytes(tmp_path / "dask")


def test_killed_run_resumes_to_identical_output(tmp_path):
    """Kill a run midway (SIGKILL: no cleanup at all), resume with --skip-existing: every frame is there,
    no half file anywhere, and the bytes equal an uninterrupted run."""
    scene = SAMPLES / "still_life.glb"
    base = [sys.executable, "-m", "strokekit_cli.main", "render", str(scene), "--orbit", "40", "--size", "640x480", "-q",
            "--workers", "1"]
    env = cli_env()
    full = tmp_path / "full"
    subprocess.run(base + ["--out", str(full)], check=True, env=env)
    part = tmp_path / "part"
    proc = subprocess.Popen(base + ["--out", str(part)], env=env)
    deadline = time.time() + 60
    while time.time() < deadline:
        if part.exists() and len(list(part.glob("*.svg"))) >= 8:
            break
        time.sleep(0.02)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    written = sorted(part.glob("frame_*.svg"))
    assert 0 < len(written) < 40, "the kill must land midway"
    # What is there is whole: every JSON present parses.
    for j in part.glob("frame_*.json"):
        json.loads(j.read_text())
    before = {p.name: p.stat().st_mtime_ns for p in part.glob("frame_*")}
    subprocess.run(base + ["--out", str(part), "--skip-existing"], check=True, env=env)
    assert tree_bytes(part) == tree_bytes(full)
    # Frames that were complete were not rewritten.
    complete = [n for n in before if n.endswith(".svg") and n.replace(".svg", ".json") in before]
    assert complete and all(before[n] == (part / n).stat().st_mtime_ns for n in complete)


def test_the_next_run_removes_the_temporaries_an_interrupted_one_left(tmp_path, capsys):
    """A run killed mid-write leaves `.<name>.<random>.part` files (in the output folder and in
    the pass folders); the next run into the folder removes them, also a resume with nothing
    left to write, and keeps the frames it skips as they were."""
    args = ["render", SAMPLES / "still_life.glb", "--orbit", "2", "--size", "64x48", "--bands", "3", "-q",
            "--out", tmp_path / "o"]
    out = tmp_path / "o"
    leftovers = [out / ".frame_0001.svg.k2j4h5g6.part", out / ".frame_0002.json.a1b2c3d4.part",
                 out / "bands" / ".frame_0001.png.q9w8e7r6.part", out / ".sequence.glb.z1x2c3v4.part"]

    def plant():
        for p in leftovers:
            p.parent.mkdir(parents=True, exist_ok=True)
            p.write_bytes(b"half a file")

    plant()
    assert run_cli(args, capsys)[0] == 0
    assert not [p for p in leftovers if p.exists()]
    assert (out / "bands" / "frame_0001.png").exists() and not list(out.glob("**/.*.part"))
    kept = {p: p.stat().st_mtime_ns for p in out.glob("**/frame_*")}
    plant()
    assert run_cli(args + ["--skip-existing"], capsys)[0] == 0
    assert not list(out.glob("**/.*.part"))
    assert {p: p.stat().st_mtime_ns for p in out.glob("**/frame_*")} == kept


class CountingPool:
    """A one-worker "pool" (a thread) that records the tasks submitted and how many wait in it."""

    def __init__(self):
        import threading
        from concurrent.futures import ThreadPoolExecutor

        self.ex, self.lock = ThreadPoolExecutor(1), threading.Lock()
        self.outstanding = self.max_outstanding = 0
        self.submitted = []

    def submit(self, task):
        with self.lock:
            self.outstanding += 1
            self.max_outstanding = max(self.max_outstanding, self.outstanding)
            self.submitted.append(task)

        def run():
            try:
                return task()
            finally:
                with self.lock:
                    self.outstanding -= 1
        return self.ex.submit(run)


def test_main_process_shares_the_frames_and_feeds_only_started_workers():
    """With a local pool, this process renders frames too; the pool gets at most two queued
    tasks per worker that has started, so a short run never waits for workers still importing;
    every task runs exactly once; fail-fast stops the rest."""
    import threading
    from types import SimpleNamespace

    from strokekit.run.workers import Workers

    executed = []

    def task(k):
        executed.append(k)
        if threading.current_thread() is not threading.main_thread():
            time.sleep(0.05)  # still running in the pool when the handler stops the run
        return {"k": k}

    def share(started_workers, tasks=20, stop_after=None):
        executed.clear()
        pool, ran = CountingPool(), []

        def handle(r):
            ran.append(r["k"])
            return stop_after is None or r["k"] < stop_after
        Workers(pool, lambda: None, started=SimpleNamespace(value=started_workers)).map(
            [partial(task, k) for k in range(tasks)], handle)
        return pool, ran

    pool, ran = share(0)  # the worker is still starting: everything is done here
    assert sorted(ran) == list(range(20)) and pool.submitted == []
    pool, ran = share(1)  # one worker up: it takes some, never more than two queued
    assert sorted(ran) == list(range(20))
    assert 2 <= len(pool.submitted) < 20 and pool.max_outstanding <= 2
    pool, ran = share(0, stop_after=2)  # a handler returning False (fail-fast) stops the rest
    assert ran == [0, 1, 2]
    # Stopped while the pool still runs a task: that task finishes and its result is handled too
    # (a write that completes after --fail-fast stopped the run is reported, not lost).
    pool, ran = share(1, stop_after=0)
    assert sorted(ran) == sorted(executed) and len(ran) >= 1


def test_main_process_helping_feeds_the_pool_as_results_arrive():
    """Beside a local pool, a worker's next task is sent from the pool's result callback, not
    when this process has finished its own task: while this process is busy with one long
    task, the pool runs the others, never more than two queued; near the end it gets one at a
    time. A pool whose futures are done before submit returns (the callback then runs in the
    submitting thread) does not deadlock."""
    import threading
    from concurrent.futures import Future
    from types import SimpleNamespace

    from strokekit.run.workers import Workers

    where = {}
    pool_may_go = threading.Event()

    def task(k):
        if threading.current_thread() is threading.main_thread():
            # This process's task: the pool does the rest meanwhile (fed from its callbacks).
            pool_may_go.set()
            deadline = time.monotonic() + 10
            while len(where) < 9 and time.monotonic() < deadline:
                time.sleep(0.005)
        else:
            pool_may_go.wait(10)
        where[k] = threading.current_thread() is threading.main_thread()
        return {"k": k}

    pool, ran = CountingPool(), []
    Workers(pool, lambda: None, started=SimpleNamespace(value=1)).map(
        [partial(task, k) for k in range(10)], lambda r: ran.append(r["k"]) or True)
    assert sorted(ran) == list(range(10)) and pool.max_outstanding <= 2
    assert sum(where.values()) == 1  # this process ran one task, the pool the other nine

    class DoneAtOnce:  # runs the task inside submit
        def submit(self, fn):
            fut = Future()
            fut.set_result(fn())
            return fut

    ran.clear()
    Workers(DoneAtOnce(), lambda: None, started=SimpleNamespace(value=1)).map(
        [partial(lambda k: {"k": k}, k) for k in range(10)], lambda r: ran.append(r["k"]) or True)
    assert sorted(ran) == list(range(10))


def test_a_dead_worker_ends_the_run_with_an_error_not_a_hang():
    """When a pool worker dies (segfault, OOM kill), Python >= 3.12 completes the pool's futures
    while holding the executor's _shutdown_lock, which submit() needs too. The done-callback that
    feeds the pool used to call submit() there: the pool's thread deadlocked on itself and the run
    hung for good. This stand-in pool breaks the same way on any Python; the run must raise."""
    import threading
    from concurrent.futures import Future
    from concurrent.futures.process import BrokenProcessPool
    from types import SimpleNamespace

    from strokekit.run.workers import Workers

    class BreakingPool:
        def __init__(self):
            self._shutdown_lock, self.futures = threading.Lock(), []

        def submit(self, fn):
            with self._shutdown_lock:
                fut = Future()
                self.futures.append(fut)
                if len(self.futures) == 2:  # both queued tasks' worker dies
                    threading.Thread(target=self._break, daemon=True).start()
                return fut

        def _break(self):
            time.sleep(0.05)
            with self._shutdown_lock:  # as CPython >= 3.12's terminate_broken
                for f in self.futures:
                    f.set_exception(BrokenProcessPool("a worker died"))

    def task(k):
        time.sleep(0.01)
        return {"k": k}

    raised = []

    def go():
        try:
            Workers(BreakingPool(), lambda: None, started=SimpleNamespace(value=1)).map(
                [partial(task, k) for k in range(200)], lambda r: True)
        except BaseException as e:  # noqa: BLE001 (what the run raises is the point)
            raised.append(e)

    t = threading.Thread(target=go, daemon=True)
    t.start()
    t.join(20)
    assert not t.is_alive(), "the run hung after a worker died"
    assert raised and isinstance(raised[0], BrokenProcessPool)


def test_a_run_given_the_loaded_scene_reports_its_load_and_start_time(tmp_path):
    """The command loads the scene and starts the pool before run(): the report's load stage
    and wall time still count them."""
    from strokekit.camera.paths import orbit_path
    from strokekit.run.runner import run
    from strokekit.run.spec import OutputOptions, RunSpec

    path = model_path("spot.obj")
    scene = load_scene(path)
    cams = orbit_path(scene.center, scene.radius, 1, width=64, height=64).cameras
    spec = RunSpec(scene_path=str(path), cameras=((1, cams[0]),),
                   outputs=OutputOptions(out_dir=tmp_path))
    res = run(spec, scene=scene, load_seconds=5.0, started_at=time.perf_counter() - 6.0)
    assert res.stages[0].seconds >= 5.0 and res.wall_seconds >= 6.0 and res.frames_ok == [1]


def test_tasks_added_while_mapping_run_next():
    """The run streams: a handler may add tasks (a frame's write task, once it is tracked) and
    they run before the remaining line tasks, so files appear from the first frame on. (That
    frames are still tracked in frame order whatever order their lines finish in is
    test_pool_and_inline_give_identical_bytes.)"""
    from collections import deque
    from types import SimpleNamespace

    from strokekit.run.workers import Workers, make_executor

    order = []

    def task(name):
        order.append(name)
        return {"name": name}

    pending = deque([partial(task, "lines 1"), partial(task, "lines 2")])

    def handle(r):
        if r["name"].startswith("lines"):
            pending.appendleft(partial(task, "write " + r["name"][-1]))
        return True
    make_executor(1, None, warm=None).map(pending, handle)  # --workers 1
    assert order == ["lines 1", "write 1", "lines 2", "write 2"]
    # The main process helping a pool whose workers have not started does the same.
    order.clear()
    pending.extend([partial(task, "lines 1"), partial(task, "lines 2")])
    Workers(None, lambda: None, started=SimpleNamespace(value=0)).map(pending, handle)
    assert order == ["lines 1", "write 1", "lines 2", "write 2"]


def test_scene_edited_between_two_runs_of_one_process_is_rendered_fresh(tmp_path, capsys):
    """Workers keep their renderer between runs (a dask worker lives on): a scene file changed
    since the last run is loaded again, not refused as 'changed during the run'."""
    from test_cli import CUBE_OBJ

    scene = tmp_path / "cube.obj"
    scene.write_text(CUBE_OBJ)
    args = ["render", scene, "--orbit", "2", "--size", "64x64", "-q", "--workers", "1"]
    assert run_cli([*args, "--out", tmp_path / "a"], capsys)[0] == 0
    scene.write_text(CUBE_OBJ.replace("v 1 1 1", "v 1.5 1.5 1.5"))
    code, _, err = run_cli([*args, "--out", tmp_path / "b"], capsys)
    assert code == 0, err
    assert tree_bytes(tmp_path / "a") != tree_bytes(tmp_path / "b")


def _cube(tmp_path: Path) -> Path:
    import trimesh

    p = tmp_path / "cube.obj"
    trimesh.creation.box(extents=[2, 2, 2]).export(p)
    return p


def test_interrupted_run_keeps_what_it_wrote_and_says_so(tmp_path):
    """Ctrl-C in the middle of run(): RunInterrupted (a KeyboardInterrupt) carries the result
    with the frames written so far; the temporary files of writes this run was in are removed
    (not other files); the report says 'interrupted' and exit code 130."""
    from strokekit.camera.paths import orbit_path
    from strokekit.run.report import run_report
    from strokekit.run.request import RenderRequest
    from strokekit.run.runner import run
    from strokekit.run.spec import OutputOptions, RunInterrupted, RunSpec

    cube = _cube(tmp_path)
    s = load_scene(cube)
    out = tmp_path / "o"
    spec = RunSpec(scene_path=str(cube), cameras=tuple(orbit_path(s.center, s.radius, 6, width=64, height=64)
                                                        .select(list(range(1, 7)))),
                   outputs=OutputOptions(out_dir=out), request=RenderRequest(strokes="lines", coherence="none"))
    foreign = out / ".notes.txt.k2j4h5g6.part"

    def progress(phase, done, total):
        if phase == "write" and done == 2:
            # A worker stopped in the middle of writing frame 4, and a temporary that is not ours.
            (out / ".frame_0004.svg.a1b2c3d4.part").write_text("<svg")
            foreign.write_text("x")
            raise KeyboardInterrupt

    with pytest.raises(RunInterrupted) as e:
        run(spec, progress)
    res = e.value.result
    assert isinstance(e.value, KeyboardInterrupt)
    assert res.interrupted and res.exit_code == 130 and res.frames_ok == [1, 2]
    assert sorted(p.name for p in out.iterdir()) == [foreign.name, ".strokekit-run.json", "frame_0001.json", "frame_0001.svg",
                                                     "frame_0002.json", "frame_0002.svg"]
    rep = run_report(spec, res)
    assert rep["status"] == "interrupted" and rep["exit_code"] == 130
    assert [f for f, v in rep["frames"].items() if v["status"] == "ok"] == ["1", "2"]
    assert all(v["status"] == "not run" for f, v in rep["frames"].items() if f not in ("1", "2"))
    assert run_report(spec, run(spec))["status"] == "ok"


def test_a_frame_written_whole_just_before_ctrl_c_counts_as_written(tmp_path, monkeypatch):
    """Ctrl-C between a frame's last file landing and its result coming back (a user trial saw
    every file of frame 1 on disk and 'interrupted: 0 of 20 frame(s) written', the report saying
    'not run'): the frame is whole and this run wrote it, so it counts as written and its files
    are listed; a frame with a file missing is not."""
    import strokekit.run.tasks as pl
    from strokekit.camera.paths import orbit_path
    from strokekit.run.report import run_report
    from strokekit.run.request import RenderRequest
    from strokekit.run.runner import run
    from strokekit.run.spec import OutputOptions, RunInterrupted, RunSpec

    cube = _cube(tmp_path)
    s = load_scene(cube)
    out = tmp_path / "o"
    spec = RunSpec(scene_path=str(cube), cameras=tuple(orbit_path(s.center, s.radius, 4, width=64, height=64)
                                                        .select([1, 2, 3, 4])),
                   outputs=OutputOptions(out_dir=out), request=RenderRequest(strokes="lines", coherence="none"))
    (out / "frame_0004.svg").parent.mkdir(parents=True)
    (out / "frame_0004.svg").write_text("<svg/>")  # frame 4: one file of an earlier run, not whole
    real = pl.frame_task

    def interrupted_after_writing(task):
        r = real(task)
        if task.number == 2:  # frame 2 is on disk, whole; Ctrl-C before its result is handled
            raise KeyboardInterrupt
        return r

    monkeypatch.setattr(pl, "frame_task", interrupted_after_writing)
    with pytest.raises(RunInterrupted) as e:
        run(spec)
    res = e.value.result
    assert res.frames_ok == [1, 2]
    assert sorted(Path(p).name for p in res.outputs) == [".strokekit-run.json", "frame_0001.json", "frame_0001.svg",
                                                         "frame_0002.json", "frame_0002.svg"]
    rep = run_report(spec, res)
    assert [rep["frames"][k]["status"] for k in "1234"] == ["ok", "ok", "not run", "not run"]


@pytest.mark.parametrize("kind", ["threads", "processes"])
def test_ctrl_c_during_render_stops_cleanly_with_a_report(tmp_path, kind):
    """SIGINT to `strokekit render` with two workers once frames are coming out: exit 130, one
    line saying how many frames were written, the --report written with status 'interrupted',
    the worker processes gone (with --worker-kind processes), no temporary file left, and every
    frame file there is whole."""

    psutil = pytest.importorskip("psutil")
    out, report = tmp_path / "o", tmp_path / "run.json"
    env = cli_env()
    env.pop("STROKEKIT_DEBUG", None)
    cmd = [sys.executable, "-m", "strokekit_cli.main", "render", str(SAMPLES / "still_life.glb"), "--orbit", "1000",
           "--size", "200x150", "--workers", "2", "--worker-kind", kind, "--out", str(out), "--report", str(report)]
    # SIGINT as a terminal gives it, also when this test runs where it is ignored (a background job).
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        deadline = time.time() + 60
        while time.time() < deadline and proc.poll() is None and len(list(out.glob("frame_*.svg"))) < 2:
            time.sleep(0.01)
        assert proc.poll() is None, "the run ended before it could be interrupted"
        children = psutil.Process(proc.pid).children(recursive=True)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("strokekit: interrupted: ") and "Traceback" not in err, err
    rep = json.loads(report.read_text())
    assert rep["status"] == "interrupted" and rep["exit_code"] == 130
    # The frames whose writing this process had taken note of (a file may be there whose result
    # had not come back yet: it is whole, but not counted).
    done = sorted(int(f) for f, v in rep["frames"].items() if v["status"] == "ok")
    assert len(done) < 1000 and f" {len(done)} of 1000 frame(s) written" in lines[0]
    assert not list(out.glob(".*.part"))  # no temporary file
    for f in done:  # the report's frames are there in full
        assert (out / f"frame_{f:04d}.svg").exists() and (out / f"frame_{f:04d}.json").exists()
    for p in out.glob("frame_*.svg"):  # and every file there is whole
        read_svg(p)
    for p in out.glob("frame_*.json"):
        json.loads(p.read_text())
    alive = psutil.wait_procs(children, timeout=10)[1]
    assert (bool(children) == (kind == "processes")) and not alive, "worker processes outlived the run"


# --- --skip-existing and the run manifest (.strokekit-run.json) ---------------------------------------

def _scenes(tmp_path: Path) -> tuple[Path, Path]:
    import trimesh

    other = tmp_path / "cylinder.obj"
    # (standing on Y, as the orbit's default up: no Z-up hint among the lines checked)
    upright = trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0])
    trimesh.creation.cylinder(radius=1.0, height=2.0, sections=12, transform=upright).export(other)
    return _cube(tmp_path), other


def _stamps(d: Path) -> dict[str, int]:
    return {p.name: p.stat().st_mtime_ns for p in d.iterdir()}


SMALL = ["--size", "64x64", "--workers", "1"]


@pytest.mark.parametrize("change,part", [
    ("scene", "scene"), (["--kinds", "silhouette"], "options"), (["--stroke-width", "2"], "options"),
    (["--quality", "draft"], "options"),
    (["--pattern", "f{frame:03d}", "--no-svg"], None)])
def test_skip_existing_refuses_frames_of_another_run(tmp_path, capsys, change, part):
    """The user trial: spot then cow into the same folder with --skip-existing said '4 already
    there, skipped' and left spot's frames. Now: exit 2, one line saying what differs, nothing
    touched. (Another --pattern names other files: nothing to skip, nothing refused.)"""
    cube, other = _scenes(tmp_path)
    out = tmp_path / "o"
    assert run_cli(["render", cube, "--orbit", "3", "--out", out, "-q"] + SMALL, capsys)[0] == 0
    before, stamps = tree_bytes(out), _stamps(out)
    args = ["render", other if change == "scene" else cube, "--orbit", "3", "--out", out, "--skip-existing"] + SMALL
    code, _, err = run_cli(args + ([] if change == "scene" else change), capsys)
    if part is None:
        assert code == 0, err
        return
    assert code == 2, err
    assert len(err.strip().splitlines()) == 1, err
    assert "--skip-existing" in err and f".strokekit-run.json differs: {part}" in err, err
    assert "remove them or render without --skip-existing" in err
    assert tree_bytes(out) == before and _stamps(out) == stamps
    # Without --skip-existing the run overwrites them and records itself.
    assert run_cli(args[:-len(SMALL) - 1] + SMALL + ([] if change == "scene" else change) + ["-q"], capsys)[0] == 0
    assert tree_bytes(out) != before


def test_the_refused_resume_says_what_differs_in_one_line():
    """not_a_resume, the line a refused --skip-existing prints: no manifest, another scene, other
    options, both, or the cameras of some frames (as ranges, only frames present in both runs)."""
    from strokekit.run.manifest import not_a_resume

    out, fix = Path("out"), "remove them or render without --skip-existing"
    new = {"scene": "s1", "options": "o1", "frames": {f: f"c{f}" for f in range(1, 10)}}

    def said(**old):
        return not_a_resume(out, {**new, **old}, new, {1, 2, 3, 5, 7, 9})

    assert not_a_resume(out, None, new, {1}) == (
        f"--skip-existing: out/ holds frames but no readable .strokekit-run.json to tell what they were rendered from; "
        f"{fix}")
    assert said(scene="s0") == f"--skip-existing: out/ holds frames of another scene (.strokekit-run.json differs: scene); {fix}"
    assert said(options="o0") == (
        f"--skip-existing: out/ holds frames of other options (.strokekit-run.json differs: options); {fix}")
    assert said(scene="s0", options="o0") == (f"--skip-existing: out/ holds frames of another scene or other options "
                                              f"(.strokekit-run.json differs: scene, options); {fix}")
    moved = {**new["frames"], 1: "x", 2: "x", 3: "x", 7: "x", 8: "x"}
    moved.pop(9)
    assert said(frames=moved) == (f"--skip-existing: out/ holds frames of another run (.strokekit-run.json differs: "
                                  f"cameras of frames 1-3, 7); {fix}")


def test_skip_existing_sees_a_brush_image_whose_bytes_changed(tmp_path, capsys):
    """A user's brush PNG goes into every GLB: the same file name with other pixels is another run."""
    from PIL import Image

    cube, _ = _scenes(tmp_path)
    brush = tmp_path / "brush.png"
    Image.new("RGBA", (8, 4), (0, 0, 0, 255)).save(brush)
    args = ["render", cube, "--orbit", "2", "--out", tmp_path / "o", "--gltf", "--brush", brush, "-q"] + SMALL
    assert run_cli(args, capsys)[0] == 0
    assert run_cli(args + ["--skip-existing"], capsys)[0] == 0  # the same image: nothing to do
    Image.new("RGBA", (8, 4), (0, 0, 0, 128)).save(brush)
    code, _, err = run_cli(args + ["--skip-existing"], capsys)
    assert code == 2 and ".strokekit-run.json differs: options" in err, err


def test_skip_existing_names_the_option_that_differs(tmp_path, capsys):
    """'differs: options' left the user to guess which: the manifest keeps the settings, and the
    line names each changed one as it was given (its flag) with both values."""
    cube, _ = _scenes(tmp_path)
    out = tmp_path / "o"
    assert run_cli(["render", cube, "--orbit", "3", "--out", out, "-q"] + SMALL, capsys)[0] == 0
    code, _, err = run_cli(["render", cube, "--orbit", "3", "--out", out, "--skip-existing", "--stroke-width", "2",
                            "--kinds", "silhouette,crease"] + SMALL, capsys)
    assert code == 2, err
    assert ".strokekit-run.json differs: options (--kinds silhouette,border,crease,material,nonmanifold there, " \
           "silhouette,crease now; --stroke-width 1.5 there, 2.0 now)" in err, err


def _files(d: Path) -> dict[str, tuple[bytes, int]]:
    """{path under d: (bytes, mtime_ns)} of every file in d, its pass folders' too."""
    return {str(p.relative_to(d)): (p.read_bytes(), p.stat().st_mtime_ns) for p in sorted(d.rglob("*")) if p.is_file()}


def test_skip_existing_keeps_the_frames_of_a_run_with_an_output_more(tmp_path, capsys):
    """A long render with --gltf stopped after 2 of 4 frames, restarted without --gltf: the 2
    frames are kept (every file of them untouched: bytes and mtime, their GLBs too) and the
    other 2 rendered without GLBs; the folder but its GLBs equals one run without --gltf, its
    manifest included. Turning --gltf off while changing a shared option (the stroke width:
    every writer's) is refused naming that option alone, nothing touched; so is turning --gltf
    on again (the manifest no longer holds the ribbons' options)."""
    cube, _ = _scenes(tmp_path)
    base = ["render", cube, "--orbit", "4", "--bands", "3"] + SMALL
    out, ref = tmp_path / "o", tmp_path / "ref"
    assert run_cli(base + ["--out", ref, "-q"], capsys)[0] == 0
    assert run_cli(base + ["--out", out, "--frames", "1-2", "--gltf", "-q"], capsys)[0] == 0
    first = _files(out)
    assert "frame_0002.glb" in first and "shade/frame_0002.png" in first
    code, _, err = run_cli(base + ["--out", out, "--skip-existing", "--stroke-width", "2"], capsys)
    assert code == 2 and "differs: options (--stroke-width 1.5 there, 2.0 now)); remove them" in err, err
    assert _files(out) == first
    code, _, err = run_cli(base + ["--out", out, "--skip-existing"], capsys)
    assert code == 0 and "wrote 2 frame(s)" in err and "(2 already there, skipped)" in err, err
    now = _files(out)
    assert all(now[n] == v for n, v in first.items() if n != ".strokekit-run.json")
    assert sorted(n for n in now if n.endswith(".glb")) == ["frame_0001.glb", "frame_0002.glb"]
    assert {n: b for n, (b, _) in now.items() if not n.endswith(".glb")} == {n: b for n, (b, _) in _files(ref).items()}
    code, _, err = run_cli(base + ["--out", out, "--skip-existing", "--gltf"], capsys)
    assert code == 2 and "differs: options (--gltf false there, true now)); remove them" in err, err


def test_skip_existing_refuses_frames_without_a_manifest(tmp_path, capsys):
    cube, _ = _scenes(tmp_path)
    out = tmp_path / "o"
    assert run_cli(["render", cube, "--orbit", "2", "--out", out, "-q"] + SMALL, capsys)[0] == 0
    (out / ".strokekit-run.json").unlink()
    before = tree_bytes(out)
    code, _, err = run_cli(["render", cube, "--orbit", "2", "--out", out, "--skip-existing"] + SMALL, capsys)
    assert code == 2 and "no readable .strokekit-run.json" in err and len(err.strip().splitlines()) == 1, err
    assert tree_bytes(out) == before


def test_skip_existing_resumes_the_same_run_and_extends_its_frame_range(tmp_path, capsys):
    """The same run again skips every frame (same bytes, not rewritten); a longer range of the
    same orbit (tracking on: a frame's digest chains the frames before it) renders only the new
    frames, and the folder, manifest included, equals one uninterrupted run."""
    cube, _ = _scenes(tmp_path)
    base = ["render", cube, "--orbit", "5"] + SMALL
    assert run_cli(base + ["--out", tmp_path / "full", "-q"], capsys)[0] == 0
    part = tmp_path / "part"
    assert run_cli(base + ["--out", part, "--frames", "1-3", "-q"], capsys)[0] == 0
    before, stamps = tree_bytes(part), _stamps(part)
    code, _, err = run_cli(base + ["--out", part, "--frames", "1-3", "--skip-existing"], capsys)
    assert code == 0 and "wrote 0 frame(s)" in err and "(3 already there, skipped)" in err, err
    assert tree_bytes(part) == before
    assert all(_stamps(part)[n] == t for n, t in stamps.items() if not n.startswith("."))
    code, _, err = run_cli(base + ["--out", part, "--skip-existing", "--report", tmp_path / "r.json"], capsys)
    assert code == 0 and "wrote 2 frame(s)" in err and "(3 already there, skipped)" in err, err
    assert all(_stamps(part)[n] == t for n, t in stamps.items() if not n.startswith("."))
    assert tree_bytes(part) == tree_bytes(tmp_path / "full")
    rep = json.loads((tmp_path / "r.json").read_text())
    assert Path(rep["outputs"][0]).name == ".strokekit-run.json"  # the report lists the manifest it wrote
    # Starting the tracked range later changes what frames 3-5 hold: they are rendered again, not skipped.
    code, _, err = run_cli(base + ["--out", part, "--frames", "3-5", "--skip-existing"], capsys)
    assert code == 0 and "wrote 3 frame(s)" in err and "skipped" not in err, err


def test_skip_existing_renders_frames_whose_camera_changed(tmp_path, capsys):
    cube, _ = _scenes(tmp_path)
    base = ["render", cube, "--orbit", "3", "--no-coherence"] + SMALL
    assert run_cli(base + ["--out", tmp_path / "o", "-q"], capsys)[0] == 0
    assert run_cli(base + ["--out", tmp_path / "high", "--elevation", "40", "-q"], capsys)[0] == 0
    code, _, err = run_cli(base + ["--out", tmp_path / "o", "--elevation", "40", "--skip-existing"], capsys)
    assert code == 0 and "wrote 3 frame(s)" in err and "skipped" not in err, err
    assert tree_bytes(tmp_path / "o") == tree_bytes(tmp_path / "high")


def test_stopped_rerun_with_new_cameras_never_leaves_an_old_frame_looking_done(tmp_path):
    """Same options, other cameras, no --skip-existing, stopped after two frames: the frames
    not rewritten yet still hold the old cameras' drawings, so the manifest (written before the
    first frame) must not claim them; a resume then renders them and matches a fresh run."""
    from strokekit.camera.paths import orbit_path
    from strokekit.run.manifest import read_run_manifest
    from strokekit.run.request import RenderRequest
    from strokekit.run.runner import run
    from strokekit.run.spec import OutputOptions, RunInterrupted, RunSpec

    cube, _ = _scenes(tmp_path)
    s = load_scene(cube)

    def spec(out, elevation, **kw):
        cams = orbit_path(s.center, s.radius, 4, elevation=elevation, width=64, height=64).select([1, 2, 3, 4])
        return RunSpec(scene_path=str(cube), cameras=tuple(cams), outputs=OutputOptions(out_dir=out),
                       request=RenderRequest(strokes="lines", coherence="none"), **kw)

    out = tmp_path / "o"
    run(spec(out, 15.0))
    old = read_run_manifest(out)["frames"]

    def stop(phase, done, total):
        if phase == "write" and done == 2:
            raise KeyboardInterrupt

    with pytest.raises(RunInterrupted):
        run(spec(out, 40.0), stop)
    run(spec(tmp_path / "fresh", 40.0))
    new = read_run_manifest(tmp_path / "fresh")["frames"]
    got = read_run_manifest(out)["frames"]
    assert got == {1: new[1], 2: new[2]} and all(old[f] != new[f] for f in (3, 4))
    res = run(spec(out, 40.0, skip_existing=True))
    assert res.frames_skipped == [1, 2] and res.frames_ok == [3, 4]
    assert tree_bytes(out) == tree_bytes(tmp_path / "fresh")


def test_coherence_metrics_ignore_the_run_manifest(tmp_path, capsys):
    """A --pattern like {frame:04d} makes the frame glob *.json, which matches the dotfile too."""
    from strokekit.metrics.coherence import frame_files

    cube, _ = _scenes(tmp_path)
    out = tmp_path / "o"
    assert run_cli(["render", cube, "--orbit", "2", "--out", out, "--pattern", "{frame:04d}", "-q"] + SMALL,
                   capsys)[0] == 0
    assert [p.name for p in frame_files(out, "{frame:04d}")] == ["0001.json", "0002.json"]


def test_resume_after_a_failed_frame_with_tracking_gives_the_uninterrupted_bytes(tmp_path, capsys, monkeypatch):
    """Frame 3 of a tracked run fails once: the frames after it were tracked without it, so the
    resume must render them again (they stayed in the manifest as done and kept their wrong ids).
    After the resume every file equals an uninterrupted run's."""
    import strokekit.run.tasks as pl
    from strokekit.run.tasks import FrameResult

    args = ["render", model_path("spot.obj"), "--orbit", "6", "--size", "160x160", "--workers", "1", "-q", "--no-svg"]
    ref, part = tmp_path / "ref", tmp_path / "part"
    assert run_cli([*args, "--out", ref], capsys)[0] == 0
    real = pl.frame_task

    def failing(task):
        if task.number == 3:
            return FrameResult(3, error="frame 3: simulated failure")
        return real(task)

    monkeypatch.setattr(pl, "frame_task", failing)
    assert run_cli([*args, "--out", part], capsys)[0] == 3
    monkeypatch.setattr(pl, "frame_task", real)
    assert tree_bytes(part) != tree_bytes(ref)
    assert run_cli([*args, "--out", part, "--skip-existing"], capsys)[0] == 0
    assert tree_bytes(part) == tree_bytes(ref)


def test_gltf_sequence_after_a_resume_holds_every_frame(tmp_path, capsys):
    """Without tracking, a --skip-existing resume wrote sequence.glb from the re-rendered frames
    only (one node), and none when every frame was there: it is always the whole run's."""
    args = ["render", model_path("spot.obj"), "--orbit", "4", "--size", "160x160", "--workers", "1", "-q",
            "--gltf-sequence", "--no-coherence"]
    out = tmp_path / "o"
    assert run_cli([*args, "--out", out], capsys)[0] == 0
    whole = (out / "sequence.glb").read_bytes()
    (out / "frame_0003.svg").unlink()
    assert run_cli([*args, "--out", out, "--skip-existing"], capsys)[0] == 0
    assert (out / "sequence.glb").read_bytes() == whole
    (out / "sequence.glb").unlink()
    assert run_cli([*args, "--out", out, "--skip-existing"], capsys)[0] == 0
    assert (out / "sequence.glb").read_bytes() == whole


@pytest.mark.parametrize("kind", ["processes", "threads"])
def test_fail_fast_in_a_pool_writes_the_frames_before_the_failure_whole(tmp_path, kind):
    """--fail-fast with pool workers, tracking and raster outputs: a worker's lines may be done
    for frames before the failed one while their (tracked) writes still wait in line. Those
    frames are still written, each whole (SVG, JSON and both PNGs); nothing after the failure is
    written, and no frame is left with its PNGs alone. A process pool has taken every frame
    before the failure by then; a thread pool drops the ones still queued (they are not written:
    a --skip-existing run draws them)."""
    from strokekit.camera.paths import orbit_path
    from strokekit.options import LineOptions
    from strokekit.raster.bands import RasterOptions
    from strokekit.run.request import RenderRequest
    from strokekit.run.runner import run
    from strokekit.run.spec import OutputOptions, RunSpec
    from strokekit.run.workers import SceneRef, make_executor

    path = model_path("spot.obj")
    s = load_scene(path)
    cams = [(i + 1, c) for i, c in enumerate(orbit_path(s.center, s.radius, 16, width=256, height=256).cameras)]
    inside = replace(cams[9][1], eye=tuple(s.center), target=tuple(s.center + [0.0, 0.0, -1.0]))
    cams[9] = (10, inside)  # frame 10: the eye inside the mesh
    out = tmp_path / "o"
    spec = RunSpec(scene_path=str(path), cameras=tuple(cams),
                   outputs=OutputOptions(out_dir=out),
                   request=RenderRequest(strokes="lines", raster=RasterOptions(bands=2)), workers=2, fail_fast=True)
    pool = make_executor(2, None, SceneRef(str(path), "", LineOptions()), kind=kind)
    try:
        while pool.started.value < 1:
            time.sleep(0.02)
        res = run(spec, workers=pool, scene=s)
    finally:
        pool.close()
    assert list(res.failures) == [10]
    if kind == "processes":
        assert res.frames_ok == list(range(1, 10))
    else:
        assert set(res.frames_ok) <= set(range(1, 10)) and len(res.frames_ok) >= 7
    by_frame: dict[str, set] = {}
    for p in out.rglob("frame_*"):
        by_frame.setdefault(p.name[:10], set()).add(str(p.relative_to(out))[:-len(p.name)] + p.name[10:])
    assert sorted(by_frame) == [f"frame_{f:04d}" for f in res.frames_ok]
    assert all(v == {".svg", ".json", "bands/.png", "shade/.png"} for v in by_frame.values()), by_frame


def test_kinds_in_another_order_are_the_same_run(tmp_path, capsys):
    """--kinds crease,silhouette draws what silhouette,crease draws: a resume with the other
    order is the same run (it was refused as 'other options')."""
    args = ["render", SAMPLES / "still_life.glb", "--camera", SAMPLES / "orbit.json", "--frames", "1-2", "--out",
            tmp_path / "k", "-q"]
    assert run_cli(args + ["--kinds", "silhouette,crease"], capsys)[0] == 0
    code, _, err = run_cli(args + ["--kinds", "crease,silhouette", "--skip-existing"], capsys)
    assert code == 0, err


def test_report_naming_the_out_folder_is_refused_before_any_frame(tmp_path, capsys):
    out = tmp_path / "o3"
    for report in (out, out / ".." / "o3"):  # (the same folder by another spelling)
        code, _, err = run_cli(["render", SAMPLES / "still_life.glb", "--camera", SAMPLES / "orbit.json", "--frames",
                                "1-2", "--out", out, "--report", report], capsys)
        assert code == 2 and "--report" in err and "--out folder" in err
    assert not out.exists() or not any(out.iterdir())


def test_coherence_pattern_takes_only_the_names_it_gives(tmp_path, capsys):
    """shot_{frame:04d} must not take shot_0001_draft.json (another render in the same folder) nor
    a report saved there: the pairs would mix two renders."""
    base = ["render", SAMPLES / "still_life.glb", "--camera", SAMPLES / "orbit.json", "--frames", "1-3", "--out",
            tmp_path, "-q"]
    assert run_cli(base + ["--pattern", "shot_{frame:04d}"], capsys)[0] == 0
    assert run_cli(base + ["--pattern", "shot_{frame:04d}_draft", "--quality", "draft", "--report",
                           tmp_path / "shot_report.json"], capsys)[0] == 0
    from strokekit.metrics.coherence import frame_files

    assert [p.name for p in frame_files(tmp_path, "shot_{frame:04d}")] == [f"shot_000{i}.json" for i in (1, 2, 3)]
    # Any integer format render takes: hex past 9, padding, thousands separators.
    for pattern, names in (("h_{frame:x}", [f"h_{i:x}.json" for i in range(1, 21)]),
                           ("p_{frame:<4}", [f"p_{i:<4}.json" for i in (1, 2)]),
                           ("c_{frame:,}", [f"c_{i:,}.json" for i in (999, 1000)]),
                           ("s_{frame:*>4}", [f"s_{i:*>4}.json" for i in (1, 2)]),
                           ("e_{frame:=+5}", [f"e_{i:=+5}.json" for i in (1, 2)])):
        for n in names:
            (tmp_path / n).write_text("{}")
        assert sorted(p.name for p in frame_files(tmp_path, pattern)) == sorted(names)


def test_a_failed_run_removes_only_what_it_wrote(tmp_path):
    """Frames 5-8 written whole by one run stay when the next run into the folder (frames 1-8,
    --fail-fast, frame 2 failing) stops before them, even within the same second: 'written by
    this run' is a file that was missing at its start or has changed since, not a file time."""
    from strokekit.camera.paths import orbit_path
    from strokekit.run.request import RenderRequest
    from strokekit.run.runner import run
    from strokekit.run.spec import OutputOptions, RunSpec

    path = model_path("spot.obj")
    s = load_scene(path)
    cams = [(i + 1, c) for i, c in enumerate(orbit_path(s.center, s.radius, 8, width=96, height=96).cameras)]
    out = tmp_path / "o"
    first = run(RunSpec(scene_path=str(path), cameras=tuple(cams[4:]), outputs=OutputOptions(out_dir=out),
                        request=RenderRequest(strokes="lines", coherence="none")), scene=s)
    assert first.frames_ok == [5, 6, 7, 8]
    kept = {p.name: p.read_bytes() for p in out.iterdir() if not p.name.startswith(".")}
    inside = replace(cams[1][1], eye=tuple(s.center), target=tuple(s.center + [0.0, 0.0, -1.0]))
    cams2 = list(cams)
    cams2[1] = (2, inside)
    second = run(RunSpec(scene_path=str(path), cameras=tuple(cams2), outputs=OutputOptions(out_dir=out),
                         request=RenderRequest(strokes="lines", coherence="none"), fail_fast=True), scene=s)
    assert list(second.failures) == [2] and second.frames_ok == [1]
    now = {p.name: p.read_bytes() for p in out.iterdir() if not p.name.startswith(".")}
    assert {k: v for k, v in now.items() if k in kept} == kept
    assert sorted(now) == sorted([*kept, "frame_0001.json", "frame_0001.svg"])


def test_an_interrupted_rewrite_leaves_no_frame_of_two_runs(tmp_path, monkeypatch):
    """Frames 1-6 rendered, then rendered again and interrupted between frame 3's SVG and its
    JSON: frame 3 must not be left as this run's SVG beside the earlier run's JSON. It goes
    whole (a resume renders it again); frames 4-6, which this run never touched, stay."""
    import strokekit.run as P
    from strokekit.camera.paths import orbit_path

    path = model_path("spot.obj")
    s = load_scene(path)
    cams = tuple((i + 1, c) for i, c in enumerate(orbit_path(s.center, s.radius, 6, width=96, height=96).cameras))
    out = tmp_path / "o"
    spec = P.RunSpec(scene_path=str(path), cameras=cams, outputs=P.OutputOptions(out_dir=out),
                     request=P.RenderRequest(strokes="lines", coherence="none"))
    assert P.run(spec, scene=s).frames_ok == [1, 2, 3, 4, 5, 6]
    earlier = {p.name: p.read_bytes() for p in out.iterdir() if p.name[-6] in "456"}
    import strokekit.run.tasks as T
    real = T.atomic_write_bytes

    def interrupted(p, data):
        if str(p).endswith("frame_0003.json"):
            raise KeyboardInterrupt
        return real(p, data)

    monkeypatch.setattr(T, "atomic_write_bytes", interrupted)
    with pytest.raises(P.RunInterrupted) as e:
        P.run(spec, scene=s)
    assert e.value.result.frames_ok == [1, 2]
    names = {p.name for p in out.iterdir()}
    assert not {"frame_0003.svg", "frame_0003.json"} & names
    assert {n: (out / n).read_bytes() for n in earlier} == earlier


def test_an_output_over_an_input_or_the_report_is_a_usage_error(tmp_path, capsys):
    """A run whose outputs would overwrite its scene, its camera file, the run manifest or the
    --report file stops before any work (exit 2, one line naming the file); nothing is changed."""
    import shutil

    scene = tmp_path / "clob" / "frame_0001.glb"
    scene.parent.mkdir()
    shutil.copy(SAMPLES / "still_life.glb", scene)
    before = scene.read_bytes()
    code, _, err = run_cli(["render", scene, "--orbit", "2", "--size", "64x64", "--gltf", "--out", scene.parent],
                           capsys)
    assert code == 2 and str(scene) in err and "scene" in err and scene.read_bytes() == before
    assert sorted(p.name for p in scene.parent.iterdir()) == ["frame_0001.glb"]
    cam = tmp_path / "c" / "frame_0001.json"
    cam.parent.mkdir()
    shutil.copy(SAMPLES / "orbit.json", cam)
    code, _, err = run_cli(["render", SAMPLES / "still_life.glb", "--camera", cam, "--frames", "1", "--out",
                            cam.parent], capsys)
    assert code == 2 and "camera file" in err and cam.read_bytes() == (SAMPLES / "orbit.json").read_bytes()
    for name in ("frame_0001.svg", ".strokekit-run.json"):
        out = tmp_path / f"r{name}"
        code, _, err = run_cli(["render", SAMPLES / "still_life.glb", "--orbit", "2", "--size", "64x64", "--out", out,
                                "--report", out / name], capsys)
        assert code == 2 and "--report" in err and not out.exists()
    # A report beside the frames is fine.
    assert run_cli(["render", SAMPLES / "still_life.glb", "--orbit", "2", "--size", "64x64", "-q", "--out",
                    tmp_path / "ok", "--report", tmp_path / "ok" / "report.json"], capsys)[0] == 0
