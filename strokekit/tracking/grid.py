"""Neighbours among a frame's samples on a uniform grid (`SampleGrid`): the k-d tree queries the
tracker and the brush paths make every frame, with the same answers, from compiled loops
(`grid_kernels`); and the match of one frame's samples to another's (`match_pieces`). Where the
tree's answer depends on its own traversal (neighbours tied at the distance that decides), the
tree is built and asked."""

from __future__ import annotations

import numpy as np

from strokekit.lines.strokeops import query_tree
from strokekit.numba_cache import LazyKernels
from strokekit.sampling import Samples, match_samples

kernels = LazyKernels("strokekit.tracking.grid_kernels").kernels


class SampleGrid:
    """The points p (N, 2) (px) in square cells of `cell_px`, for searches within about that
    distance. `query` answers as query_tree(p).query does; where the tree's answer depends on its
    own traversal (ties) the tree is built and asked (rare)."""

    def __init__(self, p: np.ndarray, cell_px: float):
        self.data = np.ascontiguousarray(p, dtype=np.float64)
        self._tree = None
        # (Not finite, a spread or a cell the grid cannot count, or no points: the tree answers everything.)
        self.ok = 0 < cell_px < np.inf and bool(kernels().grid_ok(self.data.reshape(-1, 2)))
        if self.ok:
            self.index = kernels().grid_index(self.data, float(cell_px))

    def tree(self):
        """The k-d tree of the points (query_tree), built on first use."""
        if self._tree is None:
            self._tree = query_tree(self.data)
        return self._tree

    def query(self, q: np.ndarray, k: int = 1, distance_upper_bound: float = np.inf, as_set: bool = False):
        """query_tree(p).query(q, k, distance_upper_bound=...): (dist, idx), (M,) for k = 1, else
        (M, k); dist inf and idx N where fewer points lie within the bound. as_set: for callers
        to whom the order of the k does not matter; neighbours at equal distances may then come
        in another order than the tree's (the same ones)."""
        q = np.ascontiguousarray(q, dtype=np.float64).reshape(-1, 2)
        if not self.ok or not np.isfinite(distance_upper_bound):
            return self.tree().query(q, k=k, distance_upper_bound=distance_upper_bound)
        M = len(q)
        d2 = np.empty((M, k))
        idx = np.empty((M, k), np.int64)
        unsure = np.zeros(M, bool)
        kernels().knn(q, len(self.data), *self.index, k, float(distance_upper_bound), as_set, d2,
                      idx, unsure)
        dist = np.sqrt(d2)
        redo = np.flatnonzero(unsure)
        if len(redo):
            dt, it = self.tree().query(q[redo], k=k, distance_upper_bound=distance_upper_bound)
            dist[redo] = dt.reshape(len(redo), k)
            idx[redo] = it.reshape(len(redo), k)
        return (dist[:, 0], idx[:, 0]) if k == 1 else (dist, idx)

    def bridges(self, pa: np.ndarray, pb: np.ndarray, step_px: float, t: np.ndarray, w: np.ndarray, k: int,
                bound: float, limit: float) -> tuple[np.ndarray, np.ndarray]:
        """(ok, unsure), (K,) each: whether every point of the segments pa -> pb (K, 2), tested
        every `step_px` (see paths.cover.on_drawing), passes its test (grid_kernels._near_one); `unsure` where the
        tree's choice among points at equal distances decides for one of them (ok is then False:
        the caller asks the tree)."""
        ok = np.zeros(len(pa), bool)
        unsure = np.zeros(len(pa), bool)
        kernels().bridges(np.ascontiguousarray(pa, dtype=np.float64), np.ascontiguousarray(pb, dtype=np.float64),
                          float(step_px), self.data, np.ascontiguousarray(t, dtype=np.float64),
                          np.ascontiguousarray(w, dtype=np.float64), *self.index, k, float(bound), float(limit), ok,
                          unsure)
        return ok, unsure


def match_pieces(src: Samples, camera, V: Samples, radius_px: float, min_tangent_dot: float,
                 k: int) -> tuple[np.ndarray, np.ndarray]:
    """For every sample of `src` (its surface point projected with `camera`): the sample of V
    whose piece of line passes nearest, among its k nearest within `radius_px` whose tangent
    agrees, or -1; and the (M, 2) projected points. match_samples(src, camera, V, query_tree(V.p),
    radius_px=radius_px, min_tangent_dot=min_tangent_dot, k=k, return_projected=True,
    piece_distance=True), searched on a grid of V's samples."""
    out = np.full(len(src), -1, np.int64)
    if len(src) == 0 or len(V) == 0:
        return out, np.full((len(src), 2), np.nan)
    q, z = camera.project(src.X)
    fin = np.isfinite(q)
    ok = fin[:, 0] & fin[:, 1] & ((z > 0) | camera.is_ortho)
    if not ok.any():
        return out, q
    grid = SampleGrid(V.p, radius_px)
    if grid.ok:
        every = ok.all()
        qq = q if every else q[ok]
        st = src.t if every else src.t[ok]
        m = np.empty(len(qq), np.int64)
        unsure = np.zeros(len(qq), bool)
        kernels().match_pieces(np.ascontiguousarray(qq), np.ascontiguousarray(st, dtype=np.float64), grid.data,
                               np.ascontiguousarray(V.t, dtype=np.float64), V.w * 0.5, *grid.index, min(k, len(V)),
                               float(radius_px), float(min_tangent_dot), m, unsure)
        if not unsure.any():
            out[ok] = m
            return out, q
    # (Samples tied at the distance that decides: as the tree orders them.)
    return match_samples(src, camera, V, grid.tree(), radius_px=radius_px, min_tangent_dot=min_tangent_dot, k=k,
                         return_projected=True, piece_distance=True)
