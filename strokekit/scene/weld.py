"""The weld that makes a scene of a triangle soup: vertices welded by exact position, degenerate
and duplicate faces dropped (`weld`), as every scene is built, static or posed."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from strokekit.errors import InputError


@dataclass(frozen=True, eq=False)
class Welded:
    """A welded triangle soup: vertices (V, 3), faces (F, 3) into them; kept (F,) the input face
    of each face (input order kept); vertex_of (Vi,) the welded vertex of each input vertex (-1:
    not used by a kept face); how many faces were dropped as degenerate and as duplicates."""

    vertices: np.ndarray
    faces: np.ndarray
    kept: np.ndarray
    vertex_of: np.ndarray
    dropped_degenerate: int
    dropped_duplicate: int


def weld(vertices: np.ndarray, faces: np.ndarray, source: str = "") -> Welded:
    """Weld vertices (V, 3) by exact position and drop degenerate faces (a repeated vertex, or no
    area relative to the scene's size) and duplicates (the same three vertices in any order; the
    first one stays). InputError (naming `source`) for no faces, a face naming a vertex that does
    not exist, NaN or infinite coordinates, or no face left."""
    v = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    if len(f) == 0:
        raise InputError("scene has no triangle faces", source or None)
    if f.min() < 0 or f.max() >= len(v):
        raise InputError("face refers to a vertex that does not exist", source or None)
    used = np.unique(f)
    if not np.all(np.isfinite(v[used])):
        bad = int((~np.isfinite(v[used]).all(axis=1)).sum())
        raise InputError(f"{bad} {'vertex has' if bad == 1 else 'vertices have'} NaN or infinite coordinates",
                         source or None)
    # Weld by exact position: seams duplicate vertices with identical coordinates.
    uniq, inverse = np.unique(v[used], axis=0, return_inverse=True)
    remap = np.full(len(v), -1, np.int64)
    remap[used] = inverse.ravel()
    f = remap[f]
    # Degenerate: repeated vertex or zero area (relative to the scene's size).
    a, b, c = uniq[f[:, 0]], uniq[f[:, 1]], uniq[f[:, 2]]
    area2 = np.linalg.norm(np.cross(b - a, c - a), axis=1)
    extent = float(np.max(uniq.max(axis=0) - uniq.min(axis=0))) or 1.0
    degenerate = (f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 0] == f[:, 2]) | (area2 <= (1e-14 * extent) ** 2)
    keep = ~degenerate
    # Duplicates: the same three vertices (any order or winding); the first one stays.
    s = np.sort(f, axis=1)
    _, first = np.unique(s[keep], axis=0, return_index=True)
    keep_idx = np.flatnonzero(keep)
    dup = np.ones(len(keep_idx), bool)
    dup[first] = False
    n_dup = int(dup.sum())
    keep_idx = np.sort(keep_idx[~dup])
    if len(keep_idx) == 0:
        raise InputError("every face is degenerate (zero area)", source or None)
    f = f[keep_idx]
    # Drop vertices no face uses any more, keeping order.
    used2, f2 = np.unique(f, return_inverse=True)
    final = np.full(len(uniq), -1, np.int64)
    final[used2] = np.arange(len(used2))
    vertex_of = np.where(remap >= 0, final[np.maximum(remap, 0)], -1)
    return Welded(uniq[used2], f2.reshape(-1, 3).astype(np.int64), keep_idx, vertex_of,
                  int(degenerate.sum()), n_dup)
