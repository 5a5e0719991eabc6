"""Helpers for tests: where the shared models are (skipped with a reason when absent) and small
generated scenes that always exist. Import as `from helpers import ...`."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
MODELS = ROOT.parent / "shared" / "models"
SAMPLES = ROOT / "samples"


def model_path(name: str) -> Path:
    p = MODELS / name
    if not p.exists():
        pytest.skip(f"shared model {name} not found at {MODELS} (shared/ is expected beside the repo)")
    return p


def box_mesh(lo, hi):
    """(vertices, faces) of an axis-aligned box with outward winding."""
    import trimesh

    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    m = trimesh.creation.box(extents=hi - lo)
    return np.asarray(m.vertices) + (lo + hi) / 2, np.asarray(m.faces)


def run_cli(args, capsys):
    """(exit code, stdout, stderr) of `strokekit ARGS` run in this process."""
    from strokekit_cli.main import main

    with pytest.raises(SystemExit) as e:
        main([str(a) for a in args])
    out = capsys.readouterr()
    return e.value.code, out.out, out.err


def cli_env(**extra: str) -> dict[str, str]:
    """The environment for a `python -m strokekit_cli.main` subprocess: this interpreter's own
    (its venv, PYTHONPATH and all: the package may be installed in any of them), with the folder
    of the strokekit this process imported first on PYTHONPATH, so that both run the same code."""
    import strokekit

    src = str(Path(strokekit.__file__).resolve().parent.parent)
    env = dict(os.environ, **extra)
    env["PYTHONPATH"] = os.pathsep.join([src, *filter(None, [os.environ.get("PYTHONPATH")])])
    return env
