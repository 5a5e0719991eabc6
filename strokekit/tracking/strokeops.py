"""Operations on a frame's strokes that the tracker and the brush paths make every frame, compiled
(`strokeops_kernels`): arc lengths, samples, pieces, points inserted, hairpins dropped, strokes
selected. Each gives, to the bit, what the numpy operation of the line pass gives
(`strokekit.lines.strokeops`, `strokekit.sampling`, `Strokes`), which numba-free runs use.
Matrix products (surface depths) stay numpy's: their rounding is the BLAS kernel's."""

from __future__ import annotations

import numpy as np

from strokekit.lines import strokeops as numpy_ops
from strokekit.model import Strokes
from strokekit.numba_cache import LazyKernels
from strokekit.sampling import Samples, resample_strokes
from strokekit.sampling import surface_between as numpy_surface_between

kernels = LazyKernels("strokekit.tracking.strokeops_kernels").kernels


def with_arcs(strokes: Strokes) -> Strokes:
    """`strokes` with its arc caches (segment_lengths, arc_length, lengths, global_arc) filled in
    one compiled pass where none is yet (the properties' own bits); returns it."""
    d = strokes.__dict__
    if "segment_lengths" in d or len(strokes) == 0:
        return strokes
    P, off = strokes.points, strokes.offsets
    if not (P.dtype == np.float64 and P.ndim == 2 and P.shape[1] == 2 and P.flags.c_contiguous
            and off.dtype == np.int64 and off.flags.c_contiguous):
        return strokes
    N, S = len(P), len(off) - 1
    seg, arc, L, base, G = np.zeros(N), np.empty(N), np.empty(S), np.empty(S), np.empty(N)
    if kernels().arcs(P, off, seg, arc, L, base, G):
        d["segment_lengths"], d["arc_length"], d["lengths"], d["global_arc"] = seg, arc, L, (base, G)
    return strokes


def surface_between(strokes: Strokes, i: np.ndarray, j: np.ndarray, a: np.ndarray,
                    values: np.ndarray | None = None) -> np.ndarray:
    """World points under the screen points p_i + a (p_j - p_i), interpolated
    perspective-correctly (sampling.surface_between; `values`: its per-point values mixed instead)."""
    cam = strokes.camera
    if cam is None or cam.is_ortho or len(i) == 0:
        return numpy_surface_between(strokes, i, j, a, values)
    X = strokes.surface
    Xi, Xj = X.take(i, axis=0), X.take(j, axis=0)
    fwd, eye = cam.basis[2], cam.eye_array
    Vi, Vj = (Xi, Xj) if values is None else (values.take(i, axis=0), values.take(j, axis=0))
    return kernels().surface_mix(Vi, Vj, (Xi - eye) @ fwd, (Xj - eye) @ fwd, np.asarray(a, float))


def resample(strokes: Strokes, step_px: float, with_surface: bool = True, surface: np.ndarray | None = None
             ) -> Samples:
    """Samples every `step_px` along the strokes (sampling.resample_strokes; `surface`: their X
    from these per-point values, the surface points carried to another frame)."""
    if len(strokes) == 0 or len(strokes.points) == 0:
        return resample_strokes(strokes, step_px, with_surface)
    base, G = with_arcs(strokes).global_arc
    stroke, s, w, i, j, a = kernels().resample_at(strokes.lengths, float(step_px), base, G, strokes.offsets)
    X = surface_between(strokes, i, j, a, surface) if with_surface else np.zeros((len(i), 3))
    p, t, u = kernels().resample_points(strokes.points, strokes.u, i, j, a)
    return Samples(p=p, X=X, u=u, t=t, ids=strokes.ids[stroke], stroke=stroke, s=s, w=w)


def cut_pieces(strokes: Strokes, stroke: np.ndarray, s0: np.ndarray, s1: np.ndarray,
               reverse: np.ndarray | None = None) -> Strokes:
    """Piece k: stroke[k] between arc lengths s0[k] < s1[k] (px), reversed where `reverse`
    (lines.strokeops.cut_pieces)."""
    K = len(stroke)
    if K < 2:  # (a single piece's two ends are found one at a time: other rounding)
        return numpy_ops.cut_pieces(strokes, stroke, s0, s1, reverse)
    base, G = strokes.global_arc
    stroke = np.asarray(stroke, np.int64)
    rev = np.zeros(K, bool) if reverse is None else np.asarray(reverse, bool)
    lo, n_in, i, j, a = kernels().cut_ends(G, base, strokes.offsets, stroke, np.asarray(s0, float),
                                           np.asarray(s1, float))
    Xe = surface_between(strokes, i, j, a)  # (both ends in one batch)
    p, x, f, off = kernels().cut_assemble(strokes.points, strokes.surface, strokes.face, lo, n_in, i, j, a, Xe, rev)
    out = Strokes(points=p, surface=x, face=f, offsets=off, kind=strokes.kind[stroke], ids=np.arange(K, dtype=np.int64),
                  u=None, level=strokes.level[stroke], level_weight=strokes.level_weight[stroke],
                  camera=strokes.camera, frame=strokes.frame, period_px=strokes.period_px)
    return out.replace(u=with_arcs(out).arc_length / out.period_px)


def insert_points(strokes: Strokes, stroke: np.ndarray, s: np.ndarray) -> Strokes:
    """Strokes with extra points at arc lengths s (px) of strokes `stroke` (same polylines; the
    new points interpolate position, surface point and u). Points closer than 1e-6 px to an
    existing point are not added."""
    if len(stroke) == 0:
        return strokes
    K = kernels()
    base, G = strokes.global_arc
    i, j, a, g, st = K.insert_at(base, G, strokes.offsets, np.asarray(stroke, np.int64), np.asarray(s, float))
    if len(i) == 0:
        return strokes
    Xn = surface_between(strokes, i, j, a)
    if (np.diff(g) < 0).any():  # (merged by global arc: in its order, equal ones as given)
        o = np.argsort(g, kind="stable")
        i, j, a, g, st, Xn = i[o], j[o], a[o], g[o], st[o], Xn[o]
    P, X, F, U, off = K.insert_merge(strokes.points, strokes.surface, strokes.face, strokes.u, G, strokes.offsets,
                                     i, j, a, g, st, Xn)
    return strokes.replace(points=P, surface=X, face=F, u=U, offsets=off)


def drop_hairpins(strokes: Strokes, angle_deg: float, max_px: float, at: np.ndarray | None = None,
                  return_kept: bool = False):
    """Strokes less the points where the line turns by more than `angle_deg` beside a segment of
    at most `max_px` (px): the sub-pixel back-and-forth where two strands that overlap at their
    ends were joined (a ribbon folds there). Only the points `at` (indices: the joints and their
    neighbours) are looked at, all when None; ends are kept; of two neighbouring such points the
    first goes, then the rest are looked at again. The same object when nothing is dropped.
    return_kept: also the (N,) mask of the points kept."""
    n = len(strokes.points)
    if n < 3 or max_px <= 0:
        return (strokes, np.ones(n, bool)) if return_kept else strokes
    at = np.arange(1, n - 1) if at is None else np.asarray(at, np.int64)
    kept = kernels().hairpin_points(strokes.points, strokes.offsets, at, np.cos(np.radians(angle_deg)), float(max_px))
    out = strokes
    if not kept.all():
        u = np.zeros(n) if strokes.u is None else strokes.u
        P, X, F, U, off = kernels().keep_rows(strokes.points, strokes.surface, strokes.face, u, strokes.offsets, kept)
        out = strokes.replace(points=P, surface=X, face=F, u=None if strokes.u is None else U, offsets=off)
    return (out, kept) if return_kept else out


def select(strokes: Strokes, mask: np.ndarray) -> Strokes:
    """strokes.select(mask) (the same strokes), its gathers compiled."""
    P, X, F, U, off = kernels().take_strokes(strokes.points, strokes.surface, strokes.face, strokes.u,
                                             strokes.offsets, np.flatnonzero(mask))
    return strokes.replace(points=P, surface=X, face=F, u=U, offsets=off, kind=strokes.kind[mask],
                           ids=strokes.ids[mask], level=strokes.level[mask], level_weight=strokes.level_weight[mask])
