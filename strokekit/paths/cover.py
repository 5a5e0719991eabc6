"""What the brush paths draw over: a piece of contour line running beside a line of higher rank
is covered by it, not drawn (`covering_samples`: the shingles of a mesh contour share one path);
a bridge between pieces is drawn only where it lies on the lines (`on_drawing`); a new short
path beside the drawn ones is held back a frame (`held_back`); the covered runs of samples each
path stands for (`covered_runs`). Loops compiled (`cover_kernels`)."""

from __future__ import annotations

import numpy as np

from strokekit.lines.strokeops import join_arrays, query_tree
from strokekit.model import KINDS, N_KINDS, Strokes, row_norm
from strokekit.numba_cache import LazyKernels
from strokekit.paths.options import PathOptions
from strokekit.paths.votes import CONTOUR
from strokekit.sampling import Samples
from strokekit.tracking.grid import SampleGrid
from strokekit.tracking.votes import unique_inverse

kernels = LazyKernels("strokekit.paths.cover_kernels").kernels

_CREASE, _SILHOUETTE = KINDS.index("crease"), KINDS.index("silhouette")

#: A run of a crease line at least this long (px) is covered by a silhouette beside it: a sharp
#: edge next to the outline, 0-2 px apart while the face between them turns edge on, is one line
#: drawn twice. Shorter crease runs stay drawn (covering them too shrinks the drawn length more
#: than it steadies it; docs/kernels.md).
CREASE_COVER_MIN_PX = 10.0

#: A strand covers another only where their tangents agree within 26 degrees (|t.t'| >= 0.9):
#: shingles run side by side, two lines meeting at a junction diverge.
_COVER_DOT = 0.9

#: The keywords of a neighbour search whose order does not matter (SampleGrid.query; a k-d tree
#: has none).
_AS_SET = {SampleGrid: {"as_set": True}}

#: A bridge between two pieces is drawn only where every point of it lies within this many px of a
#: line sample (the brush paths invent nothing).
ON_DRAWING_PX = 1.0

def on_drawing(tree, pa: np.ndarray, pb: np.ndarray, step_px: float = 0.5, D: Samples | None = None) -> np.ndarray:
    """(K,) whether the segments pa -> pb (K, 2) lie within ON_DRAWING_PX of the line samples in
    `tree` at every point (tested every `step_px`). With D (the samples of the tree, their
    tangents and lengths): within ON_DRAWING_PX of the lines themselves, the piece of line each
    sample stands for (a point beside a line lies up to half a sample spacing further from the
    nearest sample than from the line: bridges 0.9 px from a line were refused)."""
    if D is not None and isinstance(tree, SampleGrid) and tree.ok:
        reach = ON_DRAWING_PX + 0.5 * float(D.w.max()) + 1e-9
        ok, unsure = tree.bridges(pa, pb, step_px, D.t, D.w, 2, reach, ON_DRAWING_PX)
        redo = np.flatnonzero(unsure)
        if len(redo):  # (as the tree chooses among samples at equal distances)
            ok[redo] = on_drawing(tree.tree(), pa.take(redo, axis=0), pb.take(redo, axis=0), step_px, D)
        return ok
    d = row_norm(pb - pa)
    n = np.maximum(1, np.ceil(d / step_px)).astype(np.int64)
    owner = np.repeat(np.arange(len(pa)), n - 1)
    k = np.arange(len(owner)) - np.repeat(np.cumsum(n - 1) - (n - 1), n - 1) + 1
    f = (k / n[owner])[:, None]
    q = pa[owner] * (1 - f) + pb[owner] * f
    if D is None:
        dist, _ = tree.query(q, distance_upper_bound=ON_DRAWING_PX + 1e-9)
        far = dist > ON_DRAWING_PX
    else:
        far = _far_from_lines(tree, q, D, ON_DRAWING_PX + 0.5 * float(D.w.max()) + 1e-9 if len(D) else ON_DRAWING_PX)
    bad = np.bincount(owner, weights=far, minlength=len(pa))
    return bad == 0

def _far_from_lines(tree, q: np.ndarray, D: Samples, reach: float) -> np.ndarray:
    """(M,) whether the points q (M, 2) lie further than ON_DRAWING_PX from the pieces of line of
    their two nearest samples in `tree` within `reach` (see on_drawing)."""
    dist, idx = tree.query(q, k=2, distance_upper_bound=reach)
    far = np.ones(len(q), bool)
    for c in range(2):
        ok = dist[:, c] < np.inf
        j = np.where(ok, idx[:, c], 0)
        dq = q - D.p.take(j, axis=0)
        along = np.einsum("ij,ij->i", dq, D.t.take(j, axis=0))
        beyond = np.maximum(np.abs(along) - 0.5 * D.w[j], 0.0)
        d2 = np.maximum(dist[:, c] ** 2 - along * along, 0.0) + beyond * beyond
        far &= ~(ok & (d2 <= ON_DRAWING_PX ** 2))
    return far

def run_cover(D: Samples, kind: np.ndarray, run: np.ndarray, r_line: np.ndarray, r_label: np.ndarray,
              r_len: np.ndarray, radius_px: float, tree: SampleGrid) -> np.ndarray:
    """covering_samples of the runs of one label (run (N,) of every line sample D, per run its
    line, label and length, `kind` per line): ranked by the total length of their label (a
    persisting path keeps its place against a newcomer), then their own length; a crease run of
    CREASE_COVER_MIN_PX or more is covered by a silhouette beside it."""
    R = len(r_line)
    glen = r_len.copy()
    lab = r_label >= 0
    if lab.any():
        _, inv = unique_inverse(r_label[lab])
        glen[lab] = np.bincount(inv, weights=r_len[lab])[inv]
    rank = np.empty(R, np.int64)
    rank[np.lexsort((np.arange(R), -np.round(r_len, 6), -np.round(glen, 6)))] = np.arange(R)
    crease_run = (kind[r_line] % N_KINDS == _CREASE) & (r_len >= CREASE_COVER_MIN_PX)
    return covering_samples(D, kind, run, rank, radius_px, tree, crease_run=crease_run)


def covering_samples(D: Samples, kind: np.ndarray, run: np.ndarray, rank: np.ndarray, radius_px: float,
                     tree=None, crease_run: np.ndarray | None = None) -> np.ndarray:
    """(N,) for every line sample the index of a drawn sample of a higher-ranked run that covers
    it (see module doc, step 4; `by_drawn_samples`), or -1. Only contour kinds are covered, each
    by its own kind: creases and borders are mesh edges, two of them close together are two
    lines. `rank` (R,): 0 is first.
    `tree`: a k-d tree of D.p, when the caller has one (the pairs of other samples are left out).
    `crease_run` (R,): runs of crease lines that a contour (silhouette) beside them covers too,
    whatever the ranks (a crease never covers)."""
    out = np.full(len(D), -1, np.int64)
    if radius_px <= 0 or len(D) < 2:
        return out
    sk = kind[D.stroke]
    if crease_run is not None and crease_run.any():
        # The crease taken as a contour of the last rank: covered by a silhouette of its level,
        # covering nothing (no rank is lower than the last; creases of one rank cover no other).
        cr = crease_run[run]
        sk = np.where(cr, sk - _CREASE + _SILHOUETTE, sk)
        rank = np.where(crease_run, len(rank), rank)
        contour = CONTOUR[sk % N_KINDS]
    else:
        contour = CONTOUR[kind % N_KINDS].take(D.stroke)  # (per stroke, then per sample)
    if contour.sum() < 2:
        return out
    if isinstance(tree, SampleGrid) and tree.ok and not tree.index[2] > kernels().COVER_CELL * radius_px:
        tree = SampleGrid(tree.data, 2.0 * radius_px)  # (the cover's cells must be wider than its radius)
    if isinstance(tree, SampleGrid) and tree.ok:
        if kernels().cover(tree.data, np.ascontiguousarray(D.t), np.ascontiguousarray(D.w, dtype=np.float64),
                           np.ascontiguousarray(sk, dtype=np.int64), contour, np.ascontiguousarray(run, dtype=np.int64),
                           np.ascontiguousarray(rank, dtype=np.int64), *tree.index, float(radius_px), _COVER_DOT,
                           out):
            return by_drawn_samples(out, D, run, rank, radius_px)
        out[:] = -1
        tree = tree.tree()  # (a pair at the radius, within rounding: as the tree counts it)
    if tree is not None:
        pr = tree.query_pairs(radius_px, output_type="ndarray")
        a, b = pr[:, 0], pr[:, 1]
        keep = contour[a] & contour[b]
        a, b = a[keep], b[keep]
    else:
        cand = np.flatnonzero(contour)
        pr = query_tree(D.p.take(cand, axis=0)).query_pairs(radius_px, output_type="ndarray")
        a, b = cand[pr[:, 0]], cand[pr[:, 1]]
    if len(a) == 0:
        return out
    keep = (run[a] != run[b]) & (sk[a] == sk[b]) & (rank[run[a]] != rank[run[b]])  # (crease_run: one rank)
    a, b = a[keep], b[keep]
    swap = rank[run[a]] < rank[run[b]]
    a, b = np.where(swap, b, a), np.where(swap, a, b)  # b: the sample of the higher-ranked run
    dp = D.p.take(b, axis=0) - D.p.take(a, axis=0)
    ta = D.t.take(a, axis=0)
    along = np.abs(np.einsum("ij,ij->i", dp, ta))
    ok = along <= 0.5 * (D.w[a] + D.w[b]) - 0.25  # beside, not one line continuing the other
    ok &= np.abs(np.einsum("ij,ij->i", D.t.take(b, axis=0), ta)) >= _COVER_DOT
    a, b = a[ok], b[ok]
    # Of several covering samples the one of the highest-ranked run, then the nearest.
    d2 = np.einsum("ij,ij->i", dp[ok], dp[ok])
    o = np.lexsort((b, d2, rank[run[b]], a))
    first = o[join_arrays(True, a[o][1:] != a[o][:-1])] if len(o) else o
    out[a[first]] = b[first]
    return by_drawn_samples(out, D, run, rank, radius_px)


def by_drawn_samples(out: np.ndarray, D: Samples, run: np.ndarray, rank: np.ndarray, radius_px: float) -> np.ndarray:
    """`out` (covering_samples') with every sample covered by a drawn one: where the sample that
    covers x is covered in turn (a fan of shingles wider than the radius), x is covered by that
    one's cover if it lies within the radius of x, else x is drawn. So every line stays within
    the radius of a drawn sample (a cover of a cover was taken for drawn: a fan's far strand
    went undrawn 3-4 px from the path). Settled rank by rank, the highest first (a cover's rank
    is higher than what it covers: it is settled before)."""
    cov = out >= 0
    second = np.flatnonzero(cov & (out.take(np.where(cov, out, 0)) >= 0))
    if not len(second):
        return out
    r = rank.take(run.take(second))
    o = np.argsort(r, kind="stable")
    second, r = second[o], r[o]
    for x in np.split(second, np.flatnonzero(np.diff(r)) + 1):
        z = out.take(out.take(x))
        x, z = x[z >= 0], z[z >= 0]  # (those whose cover is drawn now keep it)
        dp = D.p.take(z, axis=0) - D.p.take(x, axis=0)
        out[x] = np.where(np.einsum("ij,ij->i", dp, dp) <= radius_px * radius_px, z, -1)
    return out


#: A new path is held back only where all of it lies within this many px of the paths drawn: the
#: lines stay within 3 px of a path everywhere.
HOLD_RADIUS_PX = 3.0

def held_back(paths: Strokes, first_fresh: int, o: PathOptions, p: np.ndarray, owner: np.ndarray, tree,
              k: int = 16) -> np.ndarray:
    """(S,) the paths held back this frame: new (a fresh id, >= first_fresh), shorter than
    o.hold_px and within HOLD_RADIUS_PX of the other paths all along (a strand beside a path, a
    piece left at a junction). They are not drawn; carried to the next frame, one that is still
    there takes its id back and is drawn from then on. A piece that shows for one frame then
    changes no id (else its id is lost, and its length, in both pairs of frames it is in).
    The paths are seen through the line samples they draw: p (N, 2), owner (N,) the path drawing
    each (-1: none), `tree` a SampleGrid (or a k-d tree) of p; a sample of a candidate is near another path when one
    of its k nearest samples within reach is drawn by a path that stays (in a crowd of strands
    that may be missed: the path is then drawn)."""
    S = len(paths)
    hold = np.zeros(S, bool)
    if o.hold_px <= 0 or S < 2:
        return hold
    cand = (paths.ids >= first_fresh) & (paths.lengths < o.hold_px)
    if not cand.any() or cand.all():
        return hold
    mine = np.flatnonzero((owner >= 0) & cand[np.maximum(owner, 0)])
    if len(mine) == 0:
        return hold
    _, idx = tree.query(p.take(mine, axis=0), k=k, distance_upper_bound=HOLD_RADIUS_PX + 1e-9,
                        **_AS_SET.get(type(tree), {}))
    ok = idx < len(p)  # (the tree marks "none within reach" with n)
    ow = owner[np.where(ok, idx, 0)]
    # (Against the paths that stay: two new strands side by side do not hold each other back.)
    near = (ok & (ow >= 0) & ~cand[np.maximum(ow, 0)]).any(axis=1)
    far = np.bincount(owner[mine], weights=~near, minlength=S)
    seen = np.bincount(owner[mine], minlength=S) > 0
    hold[cand & seen & (far == 0)] = True
    return hold


def covered_runs(cover: np.ndarray, smp_piece: np.ndarray, path_of: np.ndarray, D: Samples, p_line: np.ndarray,
                 p_s0: np.ndarray, p_s1: np.ndarray, S: int):
    """The covers of S paths (BrushPaths' cover_offsets, line, s0, s1, drawn): by path, the pieces
    each draws (piece k of line p_line[k] from p_s0[k] to p_s1[k], path path_of[k]), then the
    runs of covered samples beside it (the samples `cover` points to a sample of one of its
    pieces, smp_piece; same line, consecutive samples), by line and start."""
    K = kernels()
    cl, c0, c1, cp = K.cover_runs(cover, smp_piece, path_of, D.stroke, D.s, D.w)
    return K.cover_table(path_of, np.asarray(p_line, np.int64), p_s0, p_s1, cl, c0, c1, cp, S)

