"""How long the command line takes to start: `--help` of each command, and the time from the
process start to the first frame's files of a one-frame spot render and of the README's sample,
for one or more Python environments measured in turns (old and new code alternating).

    python benchmarks/bench_startup.py [--runs 5] [PYTHON ...]   # default: this interpreter

Each PYTHON runs `PYTHON -m strokekit_cli.main ...` (its own installed strokekit). Reported: the
median wall time, and the median CPU time (user + system, the process and its children: less
sensitive than the wall time to a loaded machine), after one untimed run of each (warm cache).
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "samples"
MODELS = ROOT.parent / "shared" / "models"

HELPS = [[], ["render"], ["camera", "orbit"], ["diff"], ["info"], ["coherence"], ["bench"]]


def _cases(out: Path) -> list[tuple[str, list[str], list[str]]]:
    """(name, arguments, the first frame's files) of each timed command."""
    cases = [(f"{' '.join(['strokekit', *h, '--help'])}", [*h, "--help"], []) for h in HELPS]
    spot = MODELS / "spot.obj"
    if spot.exists():
        cases.append(("spot, one frame: its files", ["render", str(spot), "--orbit", "1", "--out", str(out)],
                      ["frame_0001.svg", "frame_0001.json"]))
    cases.append(("README sample: frame 1's files",
                  ["render", str(SAMPLES / "still_life.glb"), "--camera", str(SAMPLES / "orbit.json"), "--frames",
                   "1-12", "--gltf", "--bands", "3", "--out", str(out)],
                  ["frame_0001.svg", "frame_0001.json", "frame_0001.glb", "bands/frame_0001.png"]))
    return cases


def timed(python: str, args: list[str], out: Path, files: list[str]) -> tuple[float, float]:
    """(wall seconds to the files, or to the exit when none; CPU seconds of the whole run)."""
    for f in out.rglob("*"):
        if f.is_file():
            f.unlink()
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    p = subprocess.Popen([python, "-m", "strokekit_cli.main", *args], stdout=subprocess.DEVNULL,
                         stderr=subprocess.PIPE, cwd=out.parent)
    wall = None
    while files and p.poll() is None:
        if all((out / f).exists() for f in files):
            wall = time.perf_counter() - t0
            break
        time.sleep(0.002)
    _, err = p.communicate()
    if wall is None:
        wall = time.perf_counter() - t0
    if p.returncode != 0:
        raise SystemExit(f"{python} {' '.join(args)}: exit {p.returncode}\n{err.decode()}")
    if files and not all((out / f).exists() for f in files):
        raise SystemExit(f"{python} {' '.join(args)}: missing {files}")
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def _label(python: str) -> str:
    """A column's name: the environment's folder, or the folder holding it when that is `.venv`."""
    env = Path(python).parent.parent
    return (env.parent.name if env.name.startswith(".") else env.name) or python


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("pythons", nargs="*", default=[sys.executable])
    ap.add_argument("--runs", type=int, default=5)
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "out"
        out.mkdir()
        cases = _cases(out)
        results = {(c[0], py): [] for c in cases for py in a.pythons}
        for _, args, files in cases:
            for py in a.pythons:
                timed(py, args, out, files)  # warm: the file cache, numba's cache, the scene cache
        for _ in range(a.runs):
            for name, args, files in cases:
                for py in a.pythons:
                    results[(name, py)].append(timed(py, args, out, files))
    print(f"load average {os.getloadavg()[0]:.2f}; medians of {a.runs} runs in turns (wall s / CPU s)")
    width = max(len(c[0]) for c in cases)
    print(" " * width + "".join(f"  {_label(py):>22}" for py in a.pythons))
    for name, _, _ in cases:
        cells = []
        for py in a.pythons:
            r = results[(name, py)]
            cells.append(f"{statistics.median(w for w, _ in r):9.3f} / {statistics.median(c for _, c in r):6.3f}")
        print(f"{name:<{width}}" + "".join(f"  {c:>22}" for c in cells))


if __name__ == "__main__":
    main()
