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


def countersunk_plate(tiles=(2, 2), n: int = 48, hole: float = 0.3, sink: float = 0.6, thickness: float = 0.4):
    """(vertices, faces) of a CAD part, Z-up: a plate of `tiles` squares of side 2, each with a
    through hole of radius `hole` countersunk at 90 degrees (its rim, radius `sink`, 45 degrees
    from the plate's top) about the square's centre. The plate's top between a rim and its
    square is long thin triangles from the rim's `n` vertices out to the square (as CAD exports
    are): what a smooth normal at the rim is interpolated across. Watertight, outward normals."""
    import trimesh

    assert n % 8 == 0  # (a sample at each corner of a square, the same along a shared side)
    t = 2 * np.pi * np.arange(n) / n
    ring = np.column_stack([np.cos(t), np.sin(t)])
    square = ring / np.abs(ring).max(axis=1, keepdims=True)
    square[np.isclose(np.abs(square), 1.0)] = np.sign(square[np.isclose(np.abs(square), 1.0)])  # exact corners
    depth = sink - hole  # 45 degrees
    verts, faces = [], []
    nx, ny = tiles
    for i in range(nx):
        for j in range(ny):
            c = np.array([2.0 * i, 2.0 * j])
            loops = [(c + square, thickness), (c + sink * ring, thickness), (c + hole * ring, thickness - depth),
                     (c + hole * ring, 0.0), (c + square, 0.0)]
            base = sum(len(v) for v in verts)
            verts.append(np.concatenate([np.column_stack([xy, np.full(n, z)]) for xy, z in loops]))
            k, k1 = np.arange(n), (np.arange(n) + 1) % n
            for a in range(len(loops) - 1):  # the top, the countersink, the bore, the bottom
                p, q = base + a * n, base + (a + 1) * n
                faces += [np.column_stack([p + k, p + k1, q + k1]), np.column_stack([p + k, q + k1, q + k])]
            top, bottom = base, base + 4 * n
            side = square + c
            for s in range(n):  # the plate's outer walls, where the square's side is the plate's edge
                a, b = side[s], side[(s + 1) % n]
                for axis, lo, hi in ((0, 0.0, 2.0 * nx - 2), (1, 0.0, 2.0 * ny - 2)):
                    for edge in (lo - 1, hi + 1):
                        if a[axis] == edge and b[axis] == edge:
                            faces.append(np.array([[top + s, bottom + s, bottom + (s + 1) % n],
                                                   [top + s, bottom + (s + 1) % n, top + (s + 1) % n]]))
    mesh = trimesh.Trimesh(np.concatenate(verts), np.concatenate(faces), process=True)
    trimesh.repair.fix_normals(mesh)
    assert mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0
    return np.asarray(mesh.vertices), np.asarray(mesh.faces)
