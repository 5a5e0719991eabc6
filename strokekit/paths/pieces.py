"""The pieces a frame's brush paths are made of, and the paths they make: the uncovered parts of
the runs of one label, cut where their line turns past the join angle (`line_pieces`); joined end
to end into paths (`link_pieces`, `one_label_per_path`, `interior_paths`, `concat`); closed into
loops where the ends meet (`close_loops`). Loops compiled (`pieces_kernels`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from strokekit.lines.strokeops import join_arrays
from strokekit.model import Strokes, row_norm
from strokekit.numba_cache import LazyKernels
from strokekit.paths.cover import on_drawing
from strokekit.paths.votes import EndVotes
from strokekit.sampling import Samples
from strokekit.tracking.joins import gather_paths, walk_links
from strokekit.tracking.strokeops import drop_hairpins, with_arcs
from strokekit.tracking.votes import unique_inverse

kernels = LazyKernels("strokekit.paths.pieces_kernels").kernels

#: Pieces shorter than this left over between covered samples are not drawn (px).
MIN_PIECE_PX = 1.0

#: Where two joined pieces overlap by a fraction of a pixel the joint turns back on itself: the
#: joint point goes when a segment beside it is at most this long (px). (Longer spurs stay: the
#: chord that would replace them could leave the drawing by more than 1 px.)
HAIRPIN_PX = 1.0


def line_pieces(lines: Strokes, D: Samples, cover: np.ndarray, run: np.ndarray, r_line: np.ndarray, r_s0: np.ndarray,
                r_s1: np.ndarray, join_angle_deg: float):
    """The pieces of the runs (run (D,) of every line sample, per run its line r_line and
    extent r_s0..r_s1 px): their uncovered parts of at least MIN_PIECE_PX, cut where their line
    turns past `join_angle_deg` at a vertex (a brush stroke ends at a corner, whether one line
    rounds it or two lines meet there: a corner turning 89 degrees in one frame and 91 in the
    next no longer splits the path that ran round it). Returns (p_run, p_s0, p_s1, smp_piece):
    per piece its run and extent (px along its line), and per sample its piece (-1: covered)."""
    K = kernels()
    p_run, p_s0, p_s1, smp_piece = K.pieces_of_runs(cover, run, D.s, D.w, r_s0, r_s1, MIN_PIECE_PX)
    owner, p_s0, p_s1, smp_piece = K.corner_cuts(
        lines.points, lines.offsets, lines.arc_length, float(np.cos(np.radians(join_angle_deg))),
        r_line[p_run], p_s0, p_s1, smp_piece, D.s)
    return p_run[owner], p_s0, p_s1, smp_piece


def link_labels(p_label: np.ndarray, p_s0: np.ndarray, p_s1: np.ndarray, prev: Strokes | None,
                merge_px: float) -> np.ndarray:
    """The labels the pieces link by: short paths give way. The pieces of a label that adds up to
    less than `merge_px` (in this frame, and in the previous frame's paths `prev` when given) link
    like pieces no path claims (-1), so the path they join takes them over (its id goes to the
    path with most of its length); alone, they keep their id. Without this, every split leaves an
    id behind for good and the paths crumble over the frames. A path short for one frame, half
    hidden, keeps its id."""
    lk = np.flatnonzero(p_label >= 0)
    if len(lk) == 0 or merge_px <= 0:
        return p_label
    ul, inv = unique_inverse(p_label[lk])
    tot = np.bincount(inv, weights=p_s1[lk] - p_s0[lk])
    small = tot < merge_px
    if prev is not None:
        srt = np.argsort(prev.ids)
        k = np.minimum(np.searchsorted(prev.ids, ul, sorter=srt), len(srt) - 1)
        was = np.where(prev.ids[srt[k]] == ul, prev.lengths[srt[k]], 0.0)
        small &= was < merge_px
    out = p_label.copy()
    out[lk[small[inv]]] = -1
    return out


@dataclass(frozen=True)
class LinkPairs:
    """The candidate links of a frame's pieces whatever their labels (paths.pieces_kernels.link_pairs):
    the open pieces' ends (e_run (2n,) their piece, pt their points), the pairs of ends a < b within
    `reach_px`, their turn's cosine `straight`, their gap and whether they may link at all (`fits`);
    `bridged` (int8, one per pair) the bridge test's verdicts, filled as links ask for them (-1: not
    asked yet): a frame links its pieces twice (orphans) and the second linking tests only its new
    bridges."""

    n: int
    e_run: np.ndarray
    pt: np.ndarray
    a: np.ndarray
    b: np.ndarray
    straight: np.ndarray
    gap: np.ndarray
    fits: np.ndarray
    bridged: np.ndarray

    @classmethod
    def of(cls, pieces: Strokes, reach_px: float, angle_deg: float) -> LinkPairs:
        n, e_run, pt, a, b, straight, gap, fits = kernels().link_pairs(
            pieces.points, pieces.offsets, np.asarray(pieces.kind, np.int64), float(reach_px),
            float(np.cos(np.radians(angle_deg))))
        return cls(n, e_run, pt, a, b, straight, gap, fits, np.full(len(a), -1, np.int8))


def link_pieces(pieces: Strokes, tol_px: float, angle_deg: float, label: np.ndarray, other_tol_px: float,
                 bridge_ok, free_px: float = 2.0, ends: EndVotes | None = None,
                 pairs: LinkPairs | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The pieces joined end to end into paths: (group (K,) the lowest piece of each path, rev
    (K,) whether it runs backwards, pos (K,) its place in the path). Pieces of two labels >= 0
    never join; two of one label join within tol_px, a piece of label -1 (unclaimed) joins any
    within other_tol_px, turning at most angle_deg. Links within one label come first, then those
    to an unclaimed piece, then between unclaimed ones; within each, with `ends` (the votes at the
    pieces' ends) those that continue the previous path first, then the cheapest (the gap plus
    10 px per radian of turn), then of the longer piece: at a junction of shingles the straight
    continuation wins over a turn onto a longer piece. Ends more than free_px apart join only
    where bridge_ok(pa, pb) says the bridge may be drawn. Each end is in one link at most.
    `pairs`: the pieces' LinkPairs within max(tol_px, other_tol_px) at angle_deg, when made
    already (their bridge verdicts are reused and filled)."""
    S = len(pieces)
    if pairs is None:
        pairs = LinkPairs.of(pieces, max(tol_px, other_tol_px), angle_deg)
    n, e_run, a, b, gap = pairs.n, pairs.e_run, pairs.a, pairs.b, pairs.gap
    if len(a) == 0:
        return np.arange(S), np.zeros(S, bool), np.zeros(S, np.int64)
    la, lb = label[e_run[a]], label[e_run[b]]
    same = (la == lb) & (la >= 0)
    tier = 2 * same + ((la < 0) != (lb < 0))
    ok = pairs.fits & np.where(same, gap <= tol_px, ((la < 0) | (lb < 0)) & (gap <= other_tol_px))
    far = np.flatnonzero(ok & (gap > free_px))
    if len(far):
        ask = far[pairs.bridged[far] < 0]
        if len(ask):
            pairs.bridged[ask] = bridge_ok(pairs.pt.take(a[ask], axis=0), pairs.pt.take(b[ask], axis=0))
        ok[far] = pairs.bridged[far] > 0
    if not ok.any():
        return np.arange(S), np.zeros(S, bool), np.zeros(S, np.int64)
    a, b, straight, gap, tier = a[ok], b[ok], pairs.straight[ok], gap[ok], tier[ok]
    heavy = np.maximum(pieces.lengths[e_run[a]], pieces.lengths[e_run[b]])
    # The cost of a link: its gap plus 10 px per radian of turn.
    cost = gap + 10.0 * np.arccos(np.clip(straight, -1.0, 1.0))
    keys = (e_run[b], e_run[a], -np.round(heavy, 6), np.round(cost, 6))
    if ends is not None:
        # (Where a path meets two pieces of its own at a junction: the one it ran on into last frame.)
        keys += (~ends.continues(e_run[a], a >= n, e_run[b], b >= n, gap, tier),)
    o = np.lexsort(keys + (-tier,))
    return walk_links(a[o], b[o], e_run, n, S)


def one_label_per_path(group: np.ndarray, pos: np.ndarray, label: np.ndarray) -> np.ndarray:
    """Groups (paths of pieces, in the order `pos`) cut where the label of their pieces changes, so
    that no path holds two labels: unlabelled pieces (-1) go with the labelled piece before them
    (before the first labelled piece: with the one after). Two paths never merge through a piece
    that joined both. (The fills and cuts compiled: one_label.)"""
    out, cuts = kernels().one_label(np.lexsort((pos, group)), group, np.asarray(label, np.int64))
    return out if cuts else group


def interior_paths(group: np.ndarray, rev: np.ndarray, pos: np.ndarray, label: np.ndarray, plen: np.ndarray,
                   pairs: LinkPairs) -> np.ndarray:
    """(K,) per piece the label its path gives way to, -1 where none. A path of pieces (group,
    rev, pos as link_pieces gives them, one label each, `plen` (K,) their lengths) whose two ends
    each meet an end of a longer path of one other label (within 2 px, fit to link by `pairs`)
    lies within that label's line: a strand of shingles the contour has moved onto, or the part
    a gap cut off a loop, now closed. Drawn apart it would keep that line cut for good."""
    K = len(group)
    out = np.full(K, -1, np.int64)
    if K < 2 or len(pairs.a) == 0:
        return out
    n, e_run = pairs.n, pairs.e_run
    glen = np.bincount(group, weights=plen, minlength=K)
    glab = np.full(K, -1, np.int64)
    np.maximum.at(glab, group, label)
    # The two ends of each path: its first piece's start (end if reversed), its last piece's end.
    last_pos = np.full(K, -1, np.int64)
    np.maximum.at(last_pos, group, pos)
    end_of_piece = np.full((K, 2), -1, np.int64)  # (the LinkPairs end of each piece's start, end)
    j = np.arange(2 * n)
    end_of_piece[e_run[j], (j >= n).astype(np.int64)] = j
    k = np.arange(K)
    first, last = pos == 0, pos == last_pos[group]
    t = np.r_[end_of_piece[k[first], rev[first].astype(np.int64)],
              end_of_piece[k[last], (~rev[last]).astype(np.int64)]]
    terminal = np.zeros(2 * n, bool)
    terminal[t[t >= 0]] = True
    a, b = pairs.a, pairs.b
    ok = pairs.fits & (pairs.gap <= 2.0) & terminal[a] & terminal[b]
    ga, gb = group[e_run[a]], group[e_run[b]]
    ok &= (ga != gb) & (glab[ga] >= 0) & (glab[gb] >= 0) & (glab[ga] != glab[gb])
    a, b, ga, gb = a[ok], b[ok], ga[ok], gb[ok]
    # Each end of a short path: the label of the longest path it meets.
    e_small = np.r_[a, b]
    g_small = np.r_[ga, gb]
    g_other = np.r_[gb, ga]
    keep = glen[g_other] > glen[g_small]
    e_small, g_small, g_other = e_small[keep], g_small[keep], g_other[keep]
    if len(e_small) == 0:
        return out
    o = np.lexsort((-glen[g_other], e_small))
    head = np.r_[True, e_small[o][1:] != e_small[o][:-1]]
    e_small, g_small, g_other = e_small[o][head], g_small[o][head], g_other[o][head]
    met = glab[g_other]
    # Both ends meet one label.
    o = np.lexsort((met, g_small))
    gs, lab = g_small[o], met[o]
    same = (gs[1:] == gs[:-1]) & (lab[1:] == lab[:-1])
    gz = np.full(K, -1, np.int64)
    gz[gs[1:][same]] = lab[1:][same]
    return gz[group]


def reverse(strokes: Strokes, which: np.ndarray) -> Strokes:
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


def concat(pieces: Strokes, group: np.ndarray, rev: np.ndarray, pos: np.ndarray, angle_deg: float, tol_px: float):
    """The pieces joined into paths (group, rev, pos of tracking.joins.touching_paths): the points of
    each path in order (reversed pieces backwards; a joint point that repeats the previous one is
    dropped, a bridge between two ends apart is drawn), hairpins at the joints dropped. Returns
    (paths, path (K,) the path of each piece, offset (K,) the arc length (px) of each piece's
    first point along its path (in the order the piece is drawn))."""
    K = len(pieces)
    g = gather_paths(pieces, group, rev, pos)
    order, c0, src, joint, drop = g.order, g.c0, g.src, g.joint, g.drop
    path_sorted, first, n_path = g.path_sorted, g.first, g.n_path
    P = pieces.points
    paths = Strokes(points=P.take(src, axis=0), surface=pieces.surface.take(src, axis=0), face=pieces.face[src],
                    offsets=join_arrays(0, n_path.cumsum()).astype(np.int64), kind=pieces.kind[first],
                    ids=np.arange(len(first), dtype=np.int64), u=np.zeros(len(src)), level=np.zeros(len(first)),
                    level_weight=np.ones(len(first)), camera=pieces.camera, frame=pieces.frame,
                    period_px=pieces.period_px)
    j = joint - np.searchsorted(drop, joint)
    paths, kept = drop_hairpins(paths, angle_deg, tol_px, join_arrays(j - 1, j), return_kept=True)
    # Where each piece starts in the output (a point dropped as a repeat or a hairpin: the kept
    # point before it, or the path's first point).
    at = c0 - np.searchsorted(drop, c0, side="right")
    at = np.maximum(np.cumsum(kept)[at] - 1, paths.offsets[:-1][path_sorted])
    offset = np.empty(K)
    offset[order] = with_arcs(paths).arc_length[at]
    path = np.empty(K, np.int64)
    path[order] = path_sorted
    return paths, path, offset


def close_loops(paths: Strokes, tol_px: float, angle_deg: float, line_grid, D: Samples) -> Strokes:
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


def seams(S: int, closed: np.ndarray, L: np.ndarray, st: np.ndarray, s: np.ndarray, u: np.ndarray,
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
