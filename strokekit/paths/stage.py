"""One frame's brush paths from its exact lines and the previous frame's paths (`brush_step`).

The steps, all vectorized over the frame's samples:

1. The lines are sampled every `sample_px` (position, tangent, surface point).
2. Votes (with history): the previous paths, sampled every `vote_spacing_px`, are advected with
   the surface (their surface points projected with the new camera: every line sample projected
   with the previous camera looks for the nearest one within `search_radius_px` whose tangent
   agrees and whose kind is compatible, BRIEF 3's correspondence). A vote carries the path's id
   and its u.
3. Labels: each line sample takes the id of most vote weight; samples no vote reached take the
   label of the nearest labelled sample of their line (a path grows along its line); runs of one
   label shorter than `min_run_px` go to their neighbours (tracking.votes.segment_by_votes).
4. Cover: a piece of contour line running beside a line of higher rank within `cover_px` is
   covered by it, not drawn (the shingles of a mesh contour share one path). Rank: the total
   length of the run's label (a persisting path keeps its place against a newcomer), then the
   run's own length. A crease run of CREASE_COVER_MIN_PX or more beside a silhouette is covered
   by it too (a sharp edge along the outline).
5. Pieces (the uncovered runs, cut where their line turns past `join_angle_deg` at a vertex:
   a stroke ends at a corner, whether one line rounds it or two meet there) are joined end to
   end into paths: pieces of one label within
   `join_px`, a piece no path claims to a path or to another such piece within `new_join_px`,
   turning at most `join_angle_deg`; links within one label first, of those the links that continue
   the previous path first (the u its votes carry at the two ends differ by what the gap
   explains), the cheapest first (gap + 10 px per radian of turn), then of the longest piece; two
   paths never join (a path that would hold two labels through an unclaimed piece is cut where
   the label changes). The bridges between pieces are drawn, so a bridge longer than 2 px is only
   made where every point of it lies within 1 px of a line (`on_drawing`: the paths invent
   nothing). A path whose ends meet is closed into a loop.
   Pieces of a path shorter than `merge_px` (this frame and the last) join like unclaimed
   pieces: a sliver merges into the path it touches instead of cutting it.
6. Ids: each previous id goes to one path, the heaviest claims first: the votes of that id a
   path holds, those of the other kind classes too (a crease edge drawn as outline last frame
   keeps its path's id), and a quarter of the length of its pieces of that label; the other
   paths get fresh ids.
   Each path is turned so that its carried u increases along it, a closed path to start at its
   old seam, and u is fitted to the votes as the Kalnins tracker does (tracking.kalnins.fit_u),
   with its self-similar level. A new path shorter than `hold_px` lying beside the drawn ones is
   held back one frame (`held_back`): a piece that shows for a frame costs no id.
"""

from __future__ import annotations

import numpy as np

from strokekit.lines.strokeops import (
    CONTOUR_KINDS,
    cut_pieces,
    join_arrays,
    keep_points,
    query_tree,
    sorted_unique,
)
from strokekit.model import KINDS, N_KINDS, BrushPaths, Strokes, row_norm
from strokekit.numba_cache import keyboard_interrupts
from strokekit.paths.grid import SampleGrid
from strokekit.paths.kernels import kernels
from strokekit.paths.options import PathOptions
from strokekit.sampling import Samples, match_samples, resample_strokes, surface_between
from strokekit.tracking.joins import GatheredPaths, insert_points, rotate_closed
from strokekit.tracking.kalnins import fit_u
from strokekit.tracking.ufit import PiecewiseU, levels_from_slope, solve_banded
from strokekit.tracking.votes import first_max_per_group, unique_inverse, unwrap_loop_votes

#: Kind class of each kind: the contour kinds share one (a silhouette path may take over a
#: smooth contour's votes), every other kind is its own.
_CONTOUR = np.array([k in CONTOUR_KINDS for k in KINDS])


def hidden_as_one(codes: np.ndarray) -> np.ndarray:
    """Kind codes (kind + N_KINDS x occlusion level) with every hidden level (>= 1) made 1. A brush
    path runs on along a hidden line where another surface's outline changes how many surfaces
    hide it: the drawing shows every hidden level alike (one dashed `hidden-<kind>` layer), and a
    path cut there would hand its length to another id as the outline slides along it."""
    codes = np.asarray(codes)
    return codes % N_KINDS + N_KINDS * np.minimum(codes // N_KINDS, 1)


def _kind_class(codes: np.ndarray) -> np.ndarray:
    """The kind class of kind codes (kind + N_KINDS x occlusion level): one for the contour kinds
    of the visible lines and one for those of the hidden lines, the code with its hidden levels
    as one (hidden_as_one) for every other kind; visible and hidden never share a class."""
    codes = hidden_as_one(codes)
    level = codes // N_KINDS
    return np.where(_CONTOUR[codes % N_KINDS], -1 - level, codes)


_CREASE, _SILHOUETTE = KINDS.index("crease"), KINDS.index("silhouette")
#: Step 4: a run of a crease line at least this long (px) is covered by a silhouette beside it
#: (a sharp edge next to the outline, 0-2 px apart while the face between them turns edge on: one
#: line drawn twice, and a strand new to the metrics when the outline moves onto the crease or
#: off it; fandisk, 120-frame orbit, M1 0.9742 -> 0.9796). Shorter crease runs stay drawn: all
#: runs covered, fandisk 0.9799 but the bunny's M2 0.0099 -> 0.0101 (its drawn length shrinks
#: more than what pops); 5 px, 0.9799 and 0.00993; 20 px, 0.9793.
CREASE_COVER_MIN_PX = 10.0

#: Pieces shorter than this left over between covered samples are not drawn (px).
_MIN_PIECE_PX = 1.0
#: A strand covers another only where their tangents agree within 26 degrees (|t.t'| >= 0.9):
#: shingles run side by side, two lines meeting at a junction diverge (the still life's handle:
#: its inner contour meets a chord at 30 degrees, and stays one path).
_COVER_DOT = 0.9
#: Where two joined pieces overlap by a fraction of a pixel the joint turns back on itself: the
#: joint point goes when a segment beside it is at most this long (px). (Longer spurs stay: the
#: chord that would replace them could leave the drawing by more than 1 px.)
_HAIRPIN_PX = 1.0


def _labels(D: int, votes: "Votes") -> np.ndarray:
    """sample_labels(D, votes.m, votes.vid, votes.w) (the same labels), its sums compiled."""
    if len(votes) == 0:
        return np.full(D, -1, np.int64)
    M = int(votes.vid.max()) + 1
    key = votes.m.astype(np.int64) * M + votes.vid
    return kernels().vote_labels(D, key.argsort(kind="stable"), key, M, votes.w)


def _assign_ids(n_strokes: int, cand_stroke: np.ndarray, cand_id: np.ndarray, cand_w: np.ndarray,
                next_id: int) -> tuple[np.ndarray, int]:
    """assign_ids(n_strokes, cand_stroke, cand_id, cand_w, next_id) (the same ids), its greedy
    pass compiled."""
    keep = cand_w >= 1e-12
    cs, ci, cw = cand_stroke[keep], cand_id[keep], cand_w[keep]
    order = np.lexsort((ci, cs, -np.round(cw, 9)))
    ids, next_id = kernels().greedy_ids(order, cs, ci, n_strokes, next_id)
    return ids, int(next_id)


def _arcs(strokes: Strokes) -> Strokes:
    """`strokes` with its arc caches (segment_lengths, arc_length, lengths, global_arc) filled in one
    compiled pass (Strokes' own, the same bits) where none is yet; returns it."""
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


def _surface_between(strokes: Strokes, i: np.ndarray, j: np.ndarray, a: np.ndarray) -> np.ndarray:
    """surface_between(strokes, i, j, a) (the same points), its steps after the depths compiled."""
    cam = strokes.camera
    if cam is None or cam.is_ortho or len(i) == 0:
        return surface_between(strokes, i, j, a)
    X = strokes.surface
    Xi, Xj = X.take(i, axis=0), X.take(j, axis=0)
    fwd, eye = cam.basis[2], cam.eye_array
    return kernels().surface_mix(Xi, Xj, (Xi - eye) @ fwd, (Xj - eye) @ fwd, np.asarray(a, float))


#: Ids (step 6): the weight of a path's label length against that of the votes it holds.
LABEL_ID_WEIGHT = 0.25


def _path_ids(S: int, path_of: np.ndarray, p_label: np.ndarray, plen: np.ndarray, votes: "Votes", vk: np.ndarray,
              vid: np.ndarray, vw: np.ndarray, cover: np.ndarray, smp_piece: np.ndarray, D: Samples, p_s0: np.ndarray,
              p_s1: np.ndarray, known: np.ndarray, next_id: int) -> tuple[np.ndarray, int]:
    """(S,) the ids of the paths and the next unused id. Each previous id goes to one path, the
    heaviest claims first (_assign_ids): a path's claim on an id is the weight of the votes of
    that id it holds (landing on its pieces, vk (V,) the piece of each vote of weight vw and id
    vid), of the other kind class too (votes.other: a crease edge drawn as outline in the last
    frame, or the other way round, keeps its path's id), plus LABEL_ID_WEIGHT times the length of
    its pieces labelled with the id (a piece grown along its line holds no votes). Without the
    other class's votes, a path whose kind changed takes a fresh id and its old id ends: fandisk,
    120-frame orbit, M1 0.9717 -> 0.9742; the per-pair best assignment of ids to these paths
    gives 0.9744. `known`: the ids of the previous paths, sorted. Paths without a claim get fresh
    ids from next_id."""
    om, oid, ow = votes.other
    ok, ok_k, _ = kernels().votes_landing(om, cover, smp_piece, D.s, p_s0, p_s1) if len(om) else (
        np.zeros(0, bool), np.zeros(0, np.int64), None)
    # (Every claimed id is one of the previous paths' `known` (sorted): sums over S x K cells.)
    i64 = np.int64
    cs, ci, cw = kernels().id_claims(np.asarray(path_of, i64), np.asarray(p_label, i64), plen, LABEL_ID_WEIGHT,
                                     np.asarray(vk, i64), np.asarray(vid, i64), vw, ok, np.asarray(ok_k, i64),
                                     np.asarray(oid, i64), np.asarray(ow, float), np.asarray(known, i64))
    if len(cs) == 0:
        return np.arange(next_id, next_id + S, dtype=np.int64), next_id + S
    return _assign_ids(S, cs, ci, cw, next_id)


def _insert_points(strokes: Strokes, stroke: np.ndarray, s: np.ndarray) -> Strokes:
    """insert_points(strokes, stroke, s) (the same strokes), its loops compiled."""
    if len(stroke) == 0:
        return strokes
    K = kernels()
    base, G = strokes.global_arc
    i, j, a, g, st = K.insert_at(base, G, strokes.offsets, np.asarray(stroke, np.int64), np.asarray(s, float))
    if len(i) == 0:
        return strokes
    Xn = _surface_between(strokes, i, j, a)
    ok, P, X, F, U, off = K.insert_merge(strokes.points, strokes.surface, strokes.face, strokes.u, G,
                                         strokes.offsets, i, j, a, g, st, Xn)
    if not ok:
        return insert_points(strokes, stroke, s)
    return strokes.replace(points=P, surface=X, face=F, u=U, offsets=off)


class _FitKernels:
    """fit_u's compiled steps (its `compiled`): the linear fit, the piecewise fit's sums and the
    knots made points."""

    def __init__(self, K):
        self.line_fit, self.band_terms, self.insert_points = K.line_fit, K.band_terms, _insert_points


def _fit_u(prev: Strokes, cur: Strokes, st: np.ndarray, s: np.ndarray, u: np.ndarray, vid: np.ndarray,
           w: np.ndarray, o) -> tuple[Strokes, np.ndarray, np.ndarray]:
    """fit_u(prev, cur, st, s, u, vid, w, o) less its vote groups (the same strokes, u and
    slopes), its steps compiled: the vote groups and their shift to the primary one, the
    piecewise fit's system (PiecewiseU.fit: its fixed terms too; the banded solve stays LAPACK's
    pbsv) and its evaluation."""
    if len(st) == 0 or o.knot_spacing_px <= 0:
        return fit_u(prev, cur, st, s, u, vid, w, o, compiled=_FitKernels(kernels()))[:3]
    K = kernels()
    P = cur.period_px
    L = _arcs(cur).lengths
    gkeys, ginv, gw, primary = K.vote_groups(st, vid, w)
    u = unwrap_loop_votes(prev, u, vid, s, ginv, w, P, o.vote_spacing_px)
    b0 = 1.0 / P
    lam = o.stretch_weight * P * P * L  # see TrackingOptions.stretch_weight
    a, b, ok = K.line_fit(st, s, u, w, primary[ginv].astype(float), lam, b0)
    # Other groups join the primary one shifted by whole periods (periodic texture).
    u = K.to_primary(st, s, u, w, ginv, gw, primary, a, b)
    a, b, ok = K.line_fit(st, s, u, w, np.ones(len(st)), lam, b0)
    pw = PiecewiseU(L, o.knot_spacing_px)
    k, f = K.knot_intervals(pw.n, pw.h, pw.base, st, s)
    inlier = np.ones(len(st))
    for _ in range(2):
        band, rhs = K.piecewise_system(k, f, w, inlier, u, pw.n, pw.h, pw.base, L, a, b, b0,
                                       o.stretch_weight * P * P, o.bend_weight)
        knots = solve_banded(band, rhs)
        inlier = K.piecewise_inliers(knots, k, f, u, P, o.outlier_px)
    b = np.where(ok, np.maximum(b, 1e-3 * b0), b0)  # never fold the texture back
    # u is interpolated linearly between points downstream: give it the knots as points.
    cur = _insert_points(cur, *K.inner_knots(pw.n, pw.h))
    u_new = K.piecewise_at(knots, pw.n, pw.h, pw.base, cur.offsets, _arcs(cur).arc_length)
    b = np.where((L > 0) & ok, (knots[pw.base[1:] - 1] - knots[pw.base[:-1]]) / np.maximum(L, 1e-9), b)
    return cur, u_new, b


def _cut_pieces(strokes: Strokes, stroke: np.ndarray, s0: np.ndarray, s1: np.ndarray) -> Strokes:
    """cut_pieces(strokes, stroke, s0, s1) (the same pieces), its loops compiled."""
    K = len(stroke)
    if K < 2:  # (cut_pieces finds a single piece's surface points one end at a time)
        return cut_pieces(strokes, stroke, s0, s1)
    base, G = strokes.global_arc
    stroke = np.asarray(stroke, np.int64)
    lo, n_in, i, j, a = kernels().cut_ends(G, base, strokes.offsets, stroke, np.asarray(s0, float),
                                           np.asarray(s1, float))
    Xe = _surface_between(strokes, i, j, a)  # (both ends in one batch, as cut_pieces takes them)
    p, x, f, off = kernels().cut_assemble(strokes.points, strokes.surface, strokes.face, lo, n_in, i, j, a, Xe)
    out = Strokes(points=p, surface=x, face=f, offsets=off, kind=strokes.kind[stroke], ids=np.arange(K, dtype=np.int64),
                  u=None, level=strokes.level[stroke], level_weight=strokes.level_weight[stroke],
                  camera=strokes.camera, frame=strokes.frame, period_px=strokes.period_px)
    return out.replace(u=_arcs(out).arc_length / out.period_px)


def _resample(strokes: Strokes, step_px: float, with_surface: bool = True) -> Samples:
    """resample_strokes(strokes, step_px, with_surface) (the same samples), its loops compiled."""
    if len(strokes) == 0 or len(strokes.points) == 0:
        return resample_strokes(strokes, step_px, with_surface)
    base, G = _arcs(strokes).global_arc
    stroke, s, w, i, j, a = kernels().resample_at(strokes.lengths, float(step_px), base, G, strokes.offsets)
    X = _surface_between(strokes, i, j, a) if with_surface else np.zeros((len(i), 3))
    p, t, u = kernels().resample_points(strokes.points, strokes.u, i, j, a)
    return Samples(p=p, X=X, u=u, t=t, ids=strokes.ids[stroke], stroke=stroke, s=s, w=w)


class Votes:
    """Votes of the previous paths on the line samples: sample index m, carried id, u, weight w
    and sign of the tangents' agreement. `other` (m, id, w): the line samples whose match is a
    path sample of another kind class; they label nothing, but count for the ids (a path whose
    lines changed kind, a crease edge now on the outline, keeps its id)."""

    def __init__(self, m, vid, u, w, sign, other=None):
        self.m, self.vid, self.u, self.w, self.sign = m, vid, u, w, sign
        if other is None:
            zi = np.zeros(0, np.int64)
            other = (zi, zi, np.zeros(0))
        self.other = other

    @staticmethod
    def none() -> "Votes":
        z = np.zeros(0)
        zi = np.zeros(0, np.int64)
        return Votes(zi, zi, z, z, z)

    def __len__(self) -> int:
        return len(self.m)


def carried_votes(prev: Strokes, lines: Strokes, D: Samples, o: PathOptions) -> Votes:
    """Votes of `prev` (the previous frame's paths) on the line samples D of `lines`: every
    `reverse_px`-th line sample looks back for the nearest previous path sample (its surface
    point projected with the previous camera, BRIEF 3's correspondence: within
    `search_radius_px`, tangents agreeing, of a compatible kind) and takes its id and its u,
    refined along the old tangent by the local slope of u. (Votes the other way, old samples
    landing on the nearest new one, change nothing measurable once every line sample looks back:
    bunny M1 0.9489 either way over 48 frames.)"""
    to = o.tracking
    V = _resample(prev, to.vote_spacing_px, with_surface=False)  # (their surface points are not used)
    if len(V) == 0 or len(D) == 0:
        return Votes.none()
    step = max(1, int(round(o.reverse_px / o.sample_px)))
    sub = np.arange(0, len(D), step)
    back = Samples(p=D.p.take(sub, axis=0), X=D.X.take(sub, axis=0), u=None, t=D.t.take(sub, axis=0), ids=None,
                   stroke=None, s=None, w=None) if step > 1 else D
    rm, rq = _lookback(back, prev.camera, V, to.search_radius_px, to.min_tangent_dot)
    # (Kind classes (_kind_class) per stroke, then per sample, in the kernel; int64 codes: its one
    # compiled signature, whatever the codes' dtype.) The matches of another kind class: a claim
    # on the id only (Votes.other).
    m, vid, u, w, sign, om, oid, ow = kernels().carried(
        rm, rq, sub, np.asarray(lines.kind, np.int64), D.stroke, np.asarray(prev.kind, np.int64), _CONTOUR, N_KINDS,
        V.p, V.t, V.w, V.u, V.s, V.stroke, V.ids, D.w, D.t, step)
    return Votes(m=m, vid=vid, u=u, w=w, sign=sign, other=(om, oid, ow))


def _lookback(src: Samples, camera, V: Samples, radius_px: float, min_tangent_dot: float,
              k: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """match_samples(src, camera, V, radius_px=radius_px, min_tangent_dot=min_tangent_dot, k=k,
    return_projected=True, piece_distance=True) (the same (M,) matches and (M, 2) projected
    points), searched on a grid of V's samples."""
    q, z = camera.project(src.X)
    out = np.full(len(src), -1, np.int64)
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


#: The keywords of a neighbour search whose order does not matter (SampleGrid.query; a k-d tree
#: has none).
_AS_SET = {SampleGrid: {"as_set": True}}

#: A bridge between two pieces is drawn only where every point of it lies within this many px of a
#: line sample (BRIEF 2's 1 px: the brush paths invent nothing).
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


def covering_samples(D: Samples, kind: np.ndarray, run: np.ndarray, rank: np.ndarray, radius_px: float,
                     tree=None, crease_run: np.ndarray | None = None) -> np.ndarray:
    """(N,) for every line sample the index of a sample of a higher-ranked run that covers it (see
    module doc, step 4), or -1. Only contour kinds are covered, each by its own kind: creases and
    borders are mesh edges, two of them close together are two lines. `rank` (R,): 0 is first.
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
        contour = _CONTOUR[sk % N_KINDS]
    else:
        contour = _CONTOUR[kind % N_KINDS].take(D.stroke)  # (per stroke, then per sample)
    if contour.sum() < 2:
        return out
    if isinstance(tree, SampleGrid) and tree.ok and not tree.index[2] > kernels().COVER_CELL * radius_px:
        tree = SampleGrid(tree.data, 2.0 * radius_px)  # (the cover's cells must be wider than its radius)
    if isinstance(tree, SampleGrid) and tree.ok:
        if kernels().cover(tree.data, np.ascontiguousarray(D.t), np.ascontiguousarray(D.w, dtype=np.float64),
                           np.ascontiguousarray(sk, dtype=np.int64), contour, np.ascontiguousarray(run, dtype=np.int64),
                           np.ascontiguousarray(rank, dtype=np.int64), *tree.index, float(radius_px), _COVER_DOT,
                           out):
            return out
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
    return out


#: A link continues the previous path where the u its two ends carry differ by at most the gap,
#: plus the ends' distances to their votes, plus this many px (times u's slope).
CONTINUE_TOL_PX = 3.0
#: The u of a piece's end: its own vote nearest the end, if within this many px of it.
END_VOTE_PX = 4.0


class EndVotes:
    """The u the previous paths carry at the pieces' ends: per piece (K,) and end (0: start, 1:
    end), u (K, 2) the u of the piece's own vote (of its label's id) nearest the end, d (K, 2) its
    distance from the end (px; inf: none within END_VOTE_PX), slope (K,) |du/ds| x P along the
    piece between its first and last own vote (1 where they are under 4 px apart, or it lies
    outside 1/4..4: a seam or a fold between them), P the period (px)."""

    def __init__(self, u: np.ndarray, d: np.ndarray, slope: np.ndarray, P: float):
        self.u, self.d, self.slope, self.P = u, d, slope, P

    @staticmethod
    def of(vk: np.ndarray, s_in: np.ndarray, vu: np.ndarray, vid: np.ndarray, label: np.ndarray, plen: np.ndarray,
           P: float) -> "EndVotes":
        """From the votes landing on piece vk (V,) at arc length s_in (px) with u vu and id vid; label
        (K,) the pieces' labels (-1: none; a piece's own votes are those of its label), plen (K,)
        their lengths (px)."""
        u, d, slope = kernels().end_votes(vk, s_in, vu, vid, np.asarray(label, np.int64), plen, float(P),
                                          END_VOTE_PX)
        return EndVotes(u, d, slope, P)

    def continues(self, ra: np.ndarray, end_a: np.ndarray, rb: np.ndarray, end_b: np.ndarray, gap: np.ndarray,
                  tier: np.ndarray) -> np.ndarray:
        """(L,) whether the links of one label (tier 2) between an end of piece ra and one of piece rb
        (end_a, end_b (L,): the piece's end, else its start) `gap` px apart continue a previous path:
        the u of the two ends' votes differ by at most slope x (gap + their distances from the ends
        + CONTINUE_TOL_PX) / P."""
        return kernels().continuing_links(ra, end_a, rb, end_b, gap, tier, self.u, self.d, self.slope, float(self.P),
                                          CONTINUE_TOL_PX)


def _link_pieces(pieces: Strokes, tol_px: float, angle_deg: float, label: np.ndarray, other_tol_px: float,
                 bridge_ok, free_px: float = 2.0,
                 ends: EndVotes | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """_touching_paths(pieces, tol_px, angle_deg, label=label, other_tol_px=other_tol_px,
    bridge_ok=bridge_ok, free_px=free_px, link=kernels().link_paths) (the same group, rev, pos),
    its candidate links compiled (link_candidates). With `ends` (the votes at the pieces' ends), the
    links within one label that continue the previous path (EndVotes.continues) come first among
    those of their tier."""
    S = len(pieces)
    K = kernels()
    n, e_run, pt, a, b, ok, straight, gap, tier, far = K.link_candidates(
        pieces.points, pieces.offsets, np.asarray(pieces.kind, np.int64), np.asarray(label, np.int64),
        float(tol_px), float(other_tol_px), float(np.cos(np.radians(angle_deg))), float(free_px))
    if len(a) == 0:
        return np.arange(S), np.zeros(S, bool), np.zeros(S, np.int64)
    far = np.flatnonzero(far)
    if len(far):
        ok[far] = bridge_ok(pt.take(a[far], axis=0), pt.take(b[far], axis=0))
    if not ok.any():
        return np.arange(S), np.zeros(S, bool), np.zeros(S, np.int64)
    a, b, straight, gap, tier = a[ok], b[ok], straight[ok], gap[ok], tier[ok]
    heavy = np.maximum(pieces.lengths[e_run[a]], pieces.lengths[e_run[b]])
    # The cost of a link: its gap plus 10 px per radian of turn (seed 000's rule).
    cost = gap + 10.0 * np.arccos(np.clip(straight, -1.0, 1.0))
    keys = (e_run[b], e_run[a], -np.round(heavy, 6), np.round(cost, 6))
    if ends is not None:
        # (Where a path meets two pieces of its own at a junction, the one it ran on into last frame:
        # bunny, 120-frame orbit, M1 0.9556 -> 0.9560, M2 0.0099 -> 0.0097.)
        keys += (~ends.continues(e_run[a], a >= n, e_run[b], b >= n, gap, tier),)
    o = np.lexsort(keys + (-tier,))
    return K.link_paths(a[o], b[o], e_run, n, S)


def _one_label_per_path(group: np.ndarray, pos: np.ndarray, label: np.ndarray) -> np.ndarray:
    """Groups (paths of pieces, in the order `pos`) cut where the label of their pieces changes, so
    that no path holds two labels: unlabelled pieces (-1) go with the labelled piece before them
    (before the first labelled piece: with the one after). Two paths never merge through a piece
    that joined both. (The fills and cuts compiled: one_label.)"""
    out, cuts = kernels().one_label(np.lexsort((pos, group)), group, np.asarray(label, np.int64))
    return out if cuts else group


def _reverse(strokes: Strokes, which: np.ndarray) -> Strokes:
    """The strokes with the point order of those where `which` is true reversed (u reset later)."""
    if not which.any():
        return strokes
    off = strokes.offsets
    sop = strokes.stroke_of_point
    idx = np.arange(len(strokes.points))
    flip = which[sop]
    src = np.where(flip, off[:-1][sop] + off[1:][sop] - 1 - idx, idx)
    return strokes.replace(points=strokes.points.take(src, axis=0), surface=strokes.surface.take(src, axis=0),
                           face=strokes.face[src], u=strokes.u[src])


def _drop_hairpins(strokes: Strokes, angle_deg: float, max_px: float, at: np.ndarray) -> tuple[Strokes, np.ndarray]:
    """drop_hairpins(strokes, angle_deg, max_px, at, return_kept=True), its loop compiled."""
    n = len(strokes.points)
    if n < 3 or max_px <= 0:
        return strokes, np.ones(n, bool)
    kept = kernels().hairpin_points(strokes.points, strokes.offsets, np.asarray(at, np.int64),
                                    np.cos(np.radians(angle_deg)), float(max_px))
    if kept.all():
        return strokes, kept
    if strokes.u is None:
        return keep_points(strokes, kept), kept
    P, X, F, U, off = kernels().keep_rows(strokes.points, strokes.surface, strokes.face, strokes.u, strokes.offsets,
                                          kept)
    return strokes.replace(points=P, surface=X, face=F, u=U, offsets=off), kept


def _gather_paths(strokes: Strokes, group: np.ndarray, rev: np.ndarray, pos: np.ndarray) -> GatheredPaths:
    """tracking.joins.gather_paths(strokes, group, rev, pos) (the same), its steps after the sort
    compiled."""
    S = len(strokes)
    # (group, pos) pairs are distinct: one stable sort of group * S + pos is lexsort((pos, group)).
    order = (group * S + pos).argsort(kind="stable")
    c0, src, new_g, joint, drop, path, first, n_path = kernels().gather(strokes.offsets, order, np.asarray(rev, bool),
                                                                        np.asarray(group, np.int64), strokes.points)
    return GatheredPaths(order, c0, src, new_g, joint, drop, path, first, n_path)


def _concat(pieces: Strokes, group: np.ndarray, rev: np.ndarray, pos: np.ndarray, angle_deg: float, tol_px: float):
    """The pieces joined into paths (group, rev, pos of tracking.joins._touching_paths): the points of
    each path in order (reversed pieces backwards; a joint point that repeats the previous one is
    dropped, a bridge between two ends apart is drawn), hairpins at the joints dropped. Returns
    (paths, path (K,) the path of each piece, offset (K,) the arc length (px) of each piece's
    first point along its path (in the order the piece is drawn))."""
    K = len(pieces)
    g = _gather_paths(pieces, group, rev, pos)
    order, c0, src, joint, drop = g.order, g.c0, g.src, g.joint, g.drop
    path_sorted, first, n_path = g.path_sorted, g.first, g.n_path
    P = pieces.points
    paths = Strokes(points=P.take(src, axis=0), surface=pieces.surface.take(src, axis=0), face=pieces.face[src],
                    offsets=join_arrays(0, n_path.cumsum()).astype(np.int64), kind=pieces.kind[first],
                    ids=np.arange(len(first), dtype=np.int64), u=np.zeros(len(src)), level=np.zeros(len(first)),
                    level_weight=np.ones(len(first)), camera=pieces.camera, frame=pieces.frame,
                    period_px=pieces.period_px)
    j = joint - np.searchsorted(drop, joint)
    paths, kept = _drop_hairpins(paths, angle_deg, tol_px, join_arrays(j - 1, j))
    # Where each piece starts in the output (a point dropped as a repeat or a hairpin: the kept
    # point before it, or the path's first point).
    at = c0 - np.searchsorted(drop, c0, side="right")
    at = np.maximum(np.cumsum(kept)[at] - 1, paths.offsets[:-1][path_sorted])
    offset = np.empty(K)
    offset[order] = _arcs(paths).arc_length[at]
    path = np.empty(K, np.int64)
    path[order] = path_sorted
    return paths, path, offset


def _close_loops(paths: Strokes, tol_px: float, angle_deg: float, line_grid, D: Samples) -> Strokes:
    """Paths whose two ends meet (within tol_px, turning by at most angle_deg at the joint, the
    bridge on the drawing, see on_drawing, beyond 2 px) closed into loops: their first point is
    repeated at their end. A ring of pieces, or one piece whose chaining stopped short of its own
    start, is a loop; drawn open, its u would fold where the previous loop's seam lies."""
    S = len(paths)
    if S == 0:
        return paths
    off = paths.offsets
    n = off[1:] - off[:-1]
    first, last = off[:-1], off[1:] - 1
    P = paths.points
    gap = row_norm(P.take(first, axis=0) - P.take(last, axis=0))
    cand = np.flatnonzero((n >= 3) & (gap > 1e-9) & (gap <= tol_px) & (paths.lengths >= 4.0 * tol_px))
    if len(cand) == 0:
        return paths
    # The turns at the joint: out of the end into the bridge, out of the bridge into the start.
    a = P[last[cand]] - P[last[cand] - 1]
    br = P[first[cand]] - P[last[cand]]
    c = P[first[cand] + 1] - P[first[cand]]

    def cos(x, y):
        return np.einsum("ij,ij->i", x, y) / np.maximum(row_norm(x) * row_norm(y), 1e-12)

    cmin = np.cos(np.radians(angle_deg))
    # (A bridge under half a pixel has no direction to speak of: the turn is taken across it.)
    tiny = gap[cand] < 0.5
    ok = np.where(tiny, cos(a, c) >= cmin, (cos(a, br) >= cmin) & (cos(br, c) >= cmin))
    far = gap[cand] > 2.0
    if far.any():
        ok[far] &= on_drawing(line_grid, P[last[cand[far]]], P[first[cand[far]]], D=D)
    cand = cand[ok]
    if len(cand) == 0:
        return paths
    # One point more at the end of each closed path: a copy of its first point.
    add = np.zeros(S, np.int64)
    add[cand] = 1
    counts = n + add
    new_off = join_arrays(0, counts.cumsum()).astype(np.int64)
    src = np.arange(len(P))
    dst = src + (new_off[:-1] - off[:-1])[paths.stroke_of_point]
    N = int(new_off[-1])
    idx = np.empty(N, np.int64)
    idx[dst] = src
    idx[new_off[1:][cand] - 1] = first[cand]
    return paths.replace(points=P.take(idx, axis=0), surface=paths.surface.take(idx, axis=0), face=paths.face[idx],
                         u=paths.u[idx], offsets=new_off)


def _seams(S: int, closed: np.ndarray, L: np.ndarray, st: np.ndarray, s: np.ndarray, u: np.ndarray,
           own: np.ndarray, P: float) -> tuple[np.ndarray, np.ndarray]:
    """Closed paths whose own votes (`own`) show the seam of an old loop (consecutive votes whose u
    jumps by more than half the loop), and the arc length of that seam on each."""
    sel = np.flatnonzero(own & closed[st])
    if len(sel) < 2:
        return np.zeros(0, np.int64), np.zeros(0)
    o = sel[np.lexsort((s[sel], st[sel]))]
    stq, sq, uq = st[o], s[o], u[o]
    jump = np.abs(np.diff(uq))
    ok = (stq[1:] == stq[:-1]) & (jump > np.maximum(0.5 * L[stq[:-1]] / P, 1.0))
    if not ok.any():
        return np.zeros(0, np.int64), np.zeros(0)
    k = np.flatnonzero(ok)
    k = k[np.lexsort((-jump[k], stq[k]))]
    k = k[join_arrays(True, stq[k][1:] != stq[k][:-1])]
    return stq[k], 0.5 * (sq[k] + sq[k + 1])


def _trend(run: np.ndarray, vid: np.ndarray, label: np.ndarray, pos: np.ndarray, u: np.ndarray, R: int) -> np.ndarray:
    """tracking.votes._u_trend (the same (R,) px), its sort and sums compiled."""
    keep = np.flatnonzero(vid == label.take(run))
    if len(keep) < 2:
        return np.zeros(R)
    pk = pos.take(keep)
    return kernels().u_trend(run.take(keep), pk - pk.min(), u.take(keep), R)


def heal_jumps(st: np.ndarray, s: np.ndarray, u: np.ndarray, vid: np.ndarray, w: np.ndarray, P: float,
               min_jump: float = 2.0) -> np.ndarray:
    """Votes u (V,) made continuous where a path's votes of one id jump: along path st[k] at arc
    length s[k] (px), a step between two votes of one id whose u differs by at least `min_jump`
    periods more than their distance explains (du - ds / P) is where the previous path's ends
    now meet, or its seam lies (a path that was open along most of a loop and now runs through
    its old ends); fitted through, u would fold there. Every such step is undone by a whole
    number of periods (the texture is periodic: no mark moves), and the group keeps the offset
    of most of its weight `w`."""
    if len(u) < 2:
        return u
    o, jumps = kernels().jump_order(st, vid, s, u, float(P), float(min_jump))  # (np.lexsort((s, vid, st)))
    if not jumps:
        return u
    sq, uq, stq, idq = s[o], u[o], st[o], vid[o]
    same = (stq[1:] == stq[:-1]) & (idq[1:] == idq[:-1])
    step = np.diff(uq) - np.diff(sq) / P
    turns = np.where(same & (np.abs(step) >= min_jump), np.round(step), 0.0)
    if not turns.any():
        return u
    # Periods added so far within the group (a cumulative sum restarted at each group).
    c = join_arrays(0.0, np.cumsum(turns))
    start = join_arrays(True, ~same)
    c -= c[np.maximum.accumulate(np.where(start, np.arange(len(c)), 0))]
    group = np.cumsum(start) - 1
    ci = c.astype(np.int64)
    base = ci.min()
    n_off = int(ci.max() - base) + 1
    ukey, kinv = unique_inverse(group * n_off + (ci - base))
    kgroup = ukey // n_off
    keep = first_max_per_group(kgroup, np.bincount(kinv, weights=w[o]))
    keep_c = np.zeros(int(group.max()) + 1, np.int64)
    keep_c[kgroup[keep]] = ukey[keep] % n_off + base
    out = u.copy()
    out[o] = uq - (ci - keep_c[group])
    return out


def _empty(lines: Strokes) -> BrushPaths:
    zi = np.zeros(0, np.int64)
    z = np.zeros(0)
    return BrushPaths(Strokes.empty(lines.camera, lines.frame, lines.period_px), lines, np.zeros(1, np.int64), zi, z,
                      z, np.zeros(0, bool))


def brush_step(prev: Strokes | None, lines: Strokes, o: PathOptions, next_id: int) -> tuple[BrushPaths, int]:
    """The brush paths of a frame's `lines` given the previous frame's paths (None: no history),
    and the next unused id (see module doc)."""
    if len(lines) == 0 or len(lines.points) == 0:
        return _empty(lines), next_id
    P = lines.period_px
    to = o.tracking
    first_fresh = next_id
    D = _resample(lines, o.sample_px)
    history = prev is not None and len(prev) > 0 and lines.camera is not None and prev.camera is not None
    votes = carried_votes(prev, lines, D, o) if history else Votes.none()
    # 3. Labels: runs of one carried id along the lines.
    run, r_line, r_s0, r_s1, r_label = kernels().segment_runs(
        _labels(len(D), votes), D.stroke, D.s, D.w, lines.lengths, o.min_run_px)
    R = len(r_line)
    r_len = r_s1 - r_s0
    # 4. Cover. Rank: the total length of the run's label, then its own length.
    glen = r_len.copy()
    lab = r_label >= 0
    if lab.any():
        _, inv = unique_inverse(r_label[lab])
        glen[lab] = np.bincount(inv, weights=r_len[lab])[inv]
    rank = np.empty(R, np.int64)
    rank[np.lexsort((np.arange(R), -np.round(r_len, 6), -np.round(glen, 6)))] = np.arange(R)
    # One grid of the line samples: for the cover, the bridges (on_drawing) and held_back.
    line_grid = SampleGrid(D.p, HOLD_RADIUS_PX)
    drawn_kind = hidden_as_one(lines.kind)
    crease_run = (drawn_kind[r_line] % N_KINDS == _CREASE) & (r_len >= CREASE_COVER_MIN_PX)
    cover = covering_samples(D, drawn_kind, run, rank, o.cover_px, line_grid, crease_run=crease_run)
    # 5. Pieces: the uncovered parts of the runs.
    p_run, p_s0, p_s1, smp_piece = kernels().pieces_of_runs(cover, run, D.s, D.w, r_s0, r_s1, _MIN_PIECE_PX)
    # A brush stroke ends at a corner: a piece is cut where its line turns past the join angle, as
    # two lines meeting there are not joined (a corner turning 89 degrees in one frame, one line,
    # and 91 in the next, two lines, no longer splits the path that ran round it).
    owner, p_s0, p_s1, smp_piece = kernels().corner_cuts(
        lines.points, lines.offsets, lines.arc_length, float(np.cos(np.radians(o.join_angle_deg))),
        r_line[p_run], p_s0, p_s1, smp_piece, D.s)
    p_run = p_run[owner]
    if len(p_run) == 0:
        return _empty(lines), next_id
    p_line, p_label = r_line[p_run], r_label[p_run]
    # Short paths give way: the pieces of a label that adds up to less than merge_px (in this
    # frame and the one before) link like pieces no path claims, so the path they join takes
    # them over (its id goes to the path with most of its length); alone, they keep their id.
    # Without this, every split leaves an id behind for good and the paths crumble over the
    # frames (spot, 120 frames: 102 paths a frame where the lines are 34 strokes).
    link_label = p_label
    lk = np.flatnonzero(p_label >= 0)
    if len(lk) and o.merge_px > 0:
        ul, inv = unique_inverse(p_label[lk])
        tot = np.bincount(inv, weights=p_s1[lk] - p_s0[lk])
        small = tot < o.merge_px
        if history:
            # ... and was short in the previous frame too (a path that is short for one frame,
            # half hidden, keeps its id).
            srt = np.argsort(prev.ids)
            k = np.minimum(np.searchsorted(prev.ids, ul, sorter=srt), len(srt) - 1)
            was = np.where(prev.ids[srt[k]] == ul, prev.lengths[srt[k]], 0.0)
            small &= was < o.merge_px
        link_label = p_label.copy()
        link_label[lk[small[inv]]] = -1
    pieces = _cut_pieces(_with_kind(lines, drawn_kind), p_line, p_s0, p_s1)
    plen = p_s1 - p_s0
    # Where every vote lands: its piece and arc length within it (on a covered sample, where the
    # covering sample lies).
    ok, vk, s_in = kernels().votes_landing(votes.m, cover, smp_piece, D.s, p_s0, p_s1)
    vu, vid, vw = votes.u[ok], votes.vid[ok], votes.w[ok]
    # 5b. Join the pieces into paths.
    ends = EndVotes.of(vk, s_in, vu, vid, link_label, plen, P) if len(votes) else None
    group, rev, pos = _link_pieces(pieces, o.join_px, o.join_angle_deg, link_label, o.new_join_px,
                                   lambda pa, pb: on_drawing(line_grid, pa, pb, D=D), free_px=2.0, ends=ends)
    group = _one_label_per_path(group, pos, link_label)
    paths, path_of, offset = _concat(pieces, group, rev, pos, o.join_angle_deg, _HAIRPIN_PX)
    paths = _close_loops(paths, o.join_px, o.join_angle_deg, line_grid, D)
    S = len(paths)
    # A hidden path's level: the fewest surfaces that hide any piece of it.
    occ_level = np.full(S, np.iinfo(np.int64).max)
    np.minimum.at(occ_level, path_of, lines.kind[p_line] // N_KINDS)
    paths = paths.replace(kind=paths.kind % N_KINDS + N_KINDS * occ_level)
    # 6. Ids: by the votes each path holds and the length of its pieces of each label.
    known = sorted_unique(prev.ids) if history else np.zeros(0, np.int64)  # (np.unique, by a sort)
    ids, next_id = _path_ids(S, path_of, p_label, plen, votes, vk, vid, vw, cover, smp_piece, D, p_s0, p_s1, known,
                             next_id)
    paths = paths.replace(ids=ids)
    if len(votes) == 0:
        paths = paths.replace(u=paths.arc_length / P)
        return _finish(paths, lines, pieces, p_line, p_s0, p_s1, path_of, D, cover, smp_piece), next_id
    # Where every vote lands along its path.
    vst = path_of[vk]
    L = paths.lengths
    vs = np.clip(offset[vk] + np.where(rev[vk], plen[vk] - s_in, s_in), 0.0, L[vst])
    vsign = votes.sign[ok] * np.where(rev[vk], -1.0, 1.0)
    vu = heal_jumps(vst, vs, vu, vid, vw, P)
    # Each path turned so that its own carried u increases along it (or, where u does not tell,
    # the way the old tangents ran).
    trend = _trend(vst, vid, ids, vs, vu, S)
    r_sign = np.bincount(vst, weights=vw * vsign, minlength=S)
    flip = np.where(np.abs(trend) >= 2.0 * o.sample_px, trend, r_sign) < 0
    if flip.any():
        paths = _reverse(paths, flip)
        vs = np.where(flip[vst], L[vst] - vs, vs)
    # Closed paths start at their old seam.
    fst, lst = paths.offsets[:-1], paths.offsets[1:] - 1
    closed = (L > 0) & (row_norm(paths.points.take(fst, axis=0) - paths.points.take(lst, axis=0)) < 1e-6)
    if closed.any():
        which, seam = _seams(S, closed, L, vst, vs, vu, vid == ids[vst], P)
        if len(which):
            paths = rotate_closed(paths, which, seam)
            shift = np.zeros(S)
            shift[which] = seam
            vs = np.mod(vs - shift[vst], np.where(L > 0, L, 1.0)[vst])
    paths, u_new, b = _fit_u(prev, paths, vst, vs, vu, vid, vw, to)
    level, weight = levels_from_slope(b, P)
    paths = paths.replace(u=u_new, level=level, level_weight=weight)
    owner = np.where(smp_piece >= 0, path_of[np.maximum(smp_piece, 0)], -1)
    hold = held_back(paths, first_fresh, o, D.p, owner, line_grid)
    return _finish(paths, lines, pieces, p_line, p_s0, p_s1, path_of, D, cover, smp_piece, hold), next_id


#: A new path is held back only where all of it lies within this many px of the paths drawn: the
#: lines stay within 3 px of a path everywhere.
HOLD_RADIUS_PX = 3.0


def held_back(paths: Strokes, first_fresh: int, o: PathOptions, p: np.ndarray, owner: np.ndarray, tree,
              k: int = 16) -> np.ndarray:
    """(S,) the paths held back this frame: new (a fresh id, >= first_fresh), shorter than
    o.hold_px and within HOLD_RADIUS_PX of the other paths all along (a strand beside a path, a
    piece left at a junction). They are not drawn; carried to the next frame, one that is still
    there takes its id back and is drawn from then on. A piece that shows for one frame then
    changes no id (without this, each costs M1 its length in both pairs of frames it is in).
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


def _finish(paths: Strokes, lines: Strokes, pieces: Strokes, p_line, p_s0, p_s1, path_of, D: Samples, cover,
            smp_piece, hold: np.ndarray | None = None) -> BrushPaths:
    """BrushPaths with the covers: the pieces each path draws, and the covered runs of samples
    beside it. Paths where `hold` is true are left out (BrushPaths.held)."""
    held = None
    if hold is not None and hold.any():
        held = _select(paths, hold)
        paths = _select(paths, ~hold)
        new = np.cumsum(~hold) - 1
        keep = ~hold[path_of]
        # (Samples covered by a piece of a held path are left to no path: their piece goes.)
        pmap = np.full(len(path_of) + 1, -1, np.int64)
        pmap[np.flatnonzero(keep)] = np.arange(int(keep.sum()))
        smp_piece = pmap[smp_piece]
        p_line, p_s0, p_s1, path_of = p_line[keep], p_s0[keep], p_s1[keep], new[path_of[keep]]
    # Covered samples in runs: same line, same covering path, consecutive samples.
    K = kernels()
    cl, c0, c1, cp = K.cover_runs(cover, smp_piece, path_of, D.stroke, D.s, D.w)
    # By path, the drawn pieces first, then by line and start.
    off, line, s0, s1, drawn = K.cover_table(path_of, np.asarray(p_line, np.int64), p_s0, p_s1, cl, c0, c1, cp,
                                              len(paths))
    return BrushPaths(strokes=paths, lines=lines, cover_offsets=off, cover_line=line, cover_s0=s0, cover_s1=s1,
                      cover_drawn=drawn, held=held)


def _select(strokes: Strokes, mask: np.ndarray) -> Strokes:
    """strokes.select(mask) (the same strokes), its gathers compiled."""
    P, X, F, U, off = kernels().take_strokes(strokes.points, strokes.surface, strokes.face, strokes.u,
                                             strokes.offsets, np.flatnonzero(mask))
    return strokes.replace(points=P, surface=X, face=F, u=U, offsets=off, kind=strokes.kind[mask],
                           ids=strokes.ids[mask], level=strokes.level[mask], level_weight=strokes.level_weight[mask])


def _with_kind(strokes: Strokes, kind: np.ndarray) -> Strokes:
    """strokes.replace(kind=kind), its global arc kept (it depends on the points and offsets
    alone, which Strokes.replace keeps the other geometry for)."""
    out = strokes.replace(kind=kind)
    if "global_arc" in strokes.__dict__:
        out.__dict__["global_arc"] = strokes.__dict__["global_arc"]
    return out


def _concat_two(a: Strokes, b: Strokes) -> Strokes:
    """Strokes.concat([a, b]) (the same strokes), its arrays joined directly."""
    if len(a) == 0 or len(b) == 0:
        return Strokes.concat([a, b])
    cat = np.concatenate
    return a.replace(points=cat((a.points, b.points)), surface=cat((a.surface, b.surface)), face=cat((a.face, b.face)),
                     u=cat((a.u, b.u)), offsets=cat((a.offsets, b.offsets[1:] + a.offsets[-1])).astype(np.int64),
                     kind=cat((a.kind, b.kind)), ids=cat((a.ids, b.ids)), level=cat((a.level, b.level)),
                     level_weight=cat((a.level_weight, b.level_weight)))


class PathTracker:
    """Brush paths carried from frame to frame. Call `step` on the frames' lines in order."""

    def __init__(self, options: PathOptions | None = None):
        self.options = options or PathOptions()
        self.prev: Strokes | None = None
        self.next_id = 0

    def reset(self) -> None:
        self.prev, self.next_id = None, 0

    def step(self, lines: Strokes) -> BrushPaths:
        """The brush paths of one frame's lines (as LineRenderer gives them)."""
        with keyboard_interrupts():  # (a Ctrl-C in a compiled loop stays a KeyboardInterrupt)
            return self._step(lines)

    def _step(self, lines: Strokes) -> BrushPaths:
        o = self.options
        if not np.isfinite(lines.points).all():  # (the compiled loops assume finite samples)
            raise ValueError("brush paths: the lines have non-finite points")
        if not o.history:
            out, _ = brush_step(None, lines, o, 0)
            return out
        out, self.next_id = brush_step(self.prev, lines, o, self.next_id)
        # The held paths vote with the drawn ones: one still there next frame takes its id back.
        self.prev = out.strokes if out.held is None else _concat_two(out.strokes, out.held)
        return out


def brush_frames(frames: list[Strokes], options: PathOptions | None = None) -> list[BrushPaths]:
    """Brush paths of a list of frames in order (convenience for tests and benchmarks)."""
    tr = PathTracker(options)
    return [tr.step(f) for f in frames]
