"""Start-up as a user meets it: `--help` of every command imports the option declarations alone
(not numpy, scipy, open3d, trimesh, numba or the stages), a render on a terminal says what it
waits for from its start until the progress bar, and its summary counts from the process start."""

from __future__ import annotations

import json
import os
import re
import select
import subprocess
import sys
import time
from pathlib import Path

import pytest
from test_cli import CUBE_OBJ

#: What a command's --help must not load: the numeric and geometry backends, and the stages.
HEAVY = ("numpy", "scipy", "open3d", "trimesh", "numba", "shapely", "PIL", "pygltflib", "dask", "distributed",
         "matplotlib", "rich", "strokekit.model", "strokekit.scene.load", "strokekit.lines.renderer",
         "strokekit.run.runner", "strokekit.run.resume", "strokekit.metrics", "strokekit.style.widths", "strokekit.style.joins")

COMMANDS = [[], ["render"], ["camera"], ["camera", "orbit"], ["camera", "dolly"], ["camera", "parallel"], ["info"],
            ["diff"], ["coherence"], ["bench"]]


@pytest.mark.parametrize("command", COMMANDS, ids=lambda c: " ".join(c) or "strokekit")
def test_help_loads_no_backend_nor_stage(command):
    """`strokekit --help` took 0.7 s quiet (3.5 s loaded): every command imported the whole
    library, open3d and scipy first."""
    code = ("import sys\nfrom strokekit_cli.main import main\ntry:\n    main(sys.argv[1:])\nexcept SystemExit:\n"
            "    pass\nprint(' '.join(sorted(sys.modules)))")
    p = subprocess.run([sys.executable, "-c", code, *command, "--help"], capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    loaded = set(p.stdout.strip().splitlines()[-1].split())
    assert "Usage:" in p.stdout
    heavy = sorted(m for m in loaded if m in HEAVY or m.startswith(tuple(h + "." for h in HEAVY)))
    assert not heavy, f"--help of {' '.join(command) or 'strokekit'} imports {heavy}"


def test_the_summary_counts_from_the_process_start(tmp_path):
    """The summary's time ('in 2.67 s', 4.6 s by the clock) left out the start: the imports, the
    scene's load. A process that waits 3 s before it imports anything reports, in its summary and
    its run report, the time from its start to the end of the run, the wait included (within
    what the report's own writing takes)."""
    (tmp_path / "cube.obj").write_text(CUBE_OBJ)
    code = ("import time\ntime.sleep(3.0)\nfrom strokekit_cli.main import main\n"
            "main(['render', 'cube.obj', '--orbit', '1', '--size', '64x64', '--out', 'o', '--report', 'r.json'])")
    t0 = time.time()
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path, timeout=300)
    assert p.returncode == 0, p.stderr
    by_the_clock = (tmp_path / "r.json").stat().st_mtime - t0
    report = json.loads((tmp_path / "r.json").read_text())
    said = float(p.stderr.rsplit(" in ", 1)[1].split()[0])
    # (wall_seconds is rounded to 0.01 s: up to 0.005 s over the clock's time.)
    assert by_the_clock - 1.0 <= report["wall_seconds"] <= by_the_clock + 0.005, (report["wall_seconds"], by_the_clock)
    assert abs(said - report["wall_seconds"]) < 0.01, p.stderr


def _on_a_terminal(args: list[str], cwd: Path) -> list[tuple[float, str]]:
    """[(seconds since the start, text)] the command writes to a terminal (a pseudo-terminal
    as its stderr and stdout), as it comes."""
    pty = pytest.importorskip("pty")
    main_fd, child_fd = pty.openpty()
    env = {**os.environ, "COLUMNS": "100", "TERM": "xterm"}
    t0 = time.perf_counter()
    p = subprocess.Popen([sys.executable, "-m", "strokekit_cli.main", *args], stdin=child_fd, stdout=child_fd,
                         stderr=child_fd, cwd=cwd, env=env, close_fds=True)
    os.close(child_fd)
    got = []
    try:
        while True:
            ready, _, _ = select.select([main_fd], [], [], 0.05)
            if ready:
                try:
                    data = os.read(main_fd, 4096)
                except OSError:  # the child closed the terminal
                    break
                if not data:
                    break
                got.append((time.perf_counter() - t0, data.decode("utf-8", "replace")))
            elif p.poll() is not None:
                break
    finally:
        os.close(main_fd)
        p.wait(timeout=300)
    assert p.returncode == 0, "".join(t for _, t in got)
    return got


def test_a_render_on_a_terminal_says_what_it_waits_for_until_the_bar(tmp_path):
    """Nothing showed for the first seconds of a render. On a terminal a status line says it is
    loading the scene, then building the BVH, before the progress bar; --quiet shows none."""
    (tmp_path / "cube.obj").write_text(CUBE_OBJ)
    got = _on_a_terminal(["render", "cube.obj", "--orbit", "2", "--size", "64x64", "--out", "o"], tmp_path)
    text = "".join(t for _, t in got)
    loading = text.find("loading cube.obj")
    bvh = text.find("building the BVH")
    assert 0 <= loading < bvh, text
    assert text.rfind("wrote 2 frame(s) to o/") > bvh, text
    # (the first words come before the library's imports: well inside the first second on a quiet machine)
    first = next(t for t, chunk in got if "loading" in chunk)
    print(f"status line after {first:.2f} s")
    got = _on_a_terminal(["render", "cube.obj", "--orbit", "2", "--size", "64x64", "--out", "q", "-q"], tmp_path)
    assert re.sub(r"\x1b\[[0-9;?]*[A-Za-z]", "", "".join(t for _, t in got)).strip() == ""  # (codes aside)


def test_a_frame_tasks_workspace_does_not_load_the_raster_kernels():
    """A frame task asks for its z-buffer workspace before its lines: making one loaded the raster
    kernels (numba's import and set-up), so the first frame's lines waited for the warm-up
    thread. The workspace is made without numba; the kernels load when the raster pass starts."""
    code = ("import sys\nfrom strokekit.raster.hits import thread_workspace\nw = thread_workspace()\n"
            "a = w.get('face', (4, 4), 'int32')\nassert w.get('face', (4, 4), 'int32') is a\n"
            "print('numba' in sys.modules)")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    assert p.stdout.strip() == "False"
