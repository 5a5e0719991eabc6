"""Render the set of outputs a change of form must keep byte for byte (issue 29), into OUT.

    python benchmarks/same_bytes.py OUT            # then: diff -r OUT_BEFORE OUT

The set: the still life with --gltf --bands 3 --exr, a 24-frame bunny orbit with brush paths and
GLB, the fandisk in isometric with --hidden, spot with --strokes lines, a --scheduler run on a
local dask cluster. Every file of every run folder is compared, the run manifest included.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "samples"
MODELS = ROOT.parent / "shared" / "models"


def strokekit(*args, quiet: bool = True) -> None:
    cmd = [sys.executable, "-m", "strokekit_cli.main", *map(str, args), *(["-q"] if quiet else [])]
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        raise SystemExit(f"failed ({p.returncode}): {' '.join(cmd)}\n{p.stderr}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--skip-scheduler", action="store_true", help="leave out the dask run")
    a = ap.parse_args()
    out = a.out.resolve()
    still = SAMPLES / "still_life.glb"
    strokekit("render", still, "--camera", SAMPLES / "orbit.json", "--frames", "1-6", "--gltf", "--bands", "3",
              "--exr", "--out", out / "still_life")
    strokekit("render", MODELS / "stanford-bunny.obj", "--orbit", "24", "--gltf", "--out", out / "bunny_brush")
    with tempfile.TemporaryDirectory() as tmp:
        iso = Path(tmp) / "iso.json"
        strokekit("camera", "parallel", MODELS / "fandisk.obj", "--projection", "isometric", "--width", "800",
                  "--height", "600", "-o", iso, quiet=False)
        strokekit("render", MODELS / "fandisk.obj", "--camera", iso, "--hidden", "--out", out / "fandisk_hidden")
    strokekit("render", MODELS / "spot.obj", "--orbit", "12", "--strokes", "lines", "--out", out / "spot_lines")
    if not a.skip_scheduler:
        import distributed

        with distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=True,
                                      dashboard_address=None) as cl:
            strokekit("render", still, "--camera", SAMPLES / "orbit.json", "--frames", "1-4", "--gltf",
                      "--scheduler", cl.scheduler_address, "--out", out / "still_life_dask")
    print(f"wrote {sum(1 for p in out.rglob('*') if p.is_file())} files to {out}")


if __name__ == "__main__":
    main()
