"""The previous frame's paths as votes on this frame's line samples (`carried_votes`): each line
sample looks back for the nearest previous path sample (its surface point projected with the
previous camera, the correspondence the metrics use) and takes its id and its u; the u the votes carry at
the pieces' ends (`EndVotes`); the ids of the paths from the votes they hold (`path_ids`); u
made continuous where a path's votes jump by whole periods (`heal_jumps`). Loops compiled
(`votes_kernels`)."""

from __future__ import annotations

import numpy as np

from strokekit.lines.strokeops import CONTOUR_KINDS, join_arrays
from strokekit.model import KINDS, N_KINDS, Strokes, carry_points
from strokekit.numba_cache import LazyKernels
from strokekit.paths.options import PathOptions
from strokekit.sampling import Samples
from strokekit.tracking.grid import match_pieces
from strokekit.tracking.strokeops import resample
from strokekit.tracking.votes import assign_ids, first_max_per_group, unique_inverse

kernels = LazyKernels("strokekit.paths.votes_kernels").kernels

#: Kind class of each kind: the contour kinds share one (a silhouette path may take over a
#: smooth contour's votes), every other kind is its own.
CONTOUR = np.array([k in CONTOUR_KINDS for k in KINDS])


def hidden_as_one(codes: np.ndarray) -> np.ndarray:
    """Kind codes (kind + N_KINDS x occlusion level) with every hidden level (>= 1) made 1. A brush
    path runs on along a hidden line where another surface's outline changes how many surfaces
    hide it: the drawing shows every hidden level alike (one dashed `hidden-<kind>` layer), and a
    path cut there would hand its length to another id as the outline slides along it."""
    codes = np.asarray(codes)
    return codes % N_KINDS + N_KINDS * np.minimum(codes // N_KINDS, 1)


def kind_class(codes: np.ndarray) -> np.ndarray:
    """The kind class of kind codes (kind + N_KINDS x occlusion level): one for the contour kinds
    of the visible lines and one for those of the hidden lines, the code with its hidden levels
    as one (hidden_as_one) for every other kind; visible and hidden never share a class."""
    codes = hidden_as_one(codes)
    level = codes // N_KINDS
    return np.where(CONTOUR[codes % N_KINDS], -1 - level, codes)


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
    point projected with the previous camera, the correspondence the metrics use: within
    `search_radius_px`, tangents agreeing, of a compatible kind) and takes its id and its u,
    refined along the old tangent by the local slope of u. (Votes the other way, old samples
    landing on the nearest new one, change nothing once every line sample looks back.)"""
    to = o.tracking
    V = resample(prev, to.vote_spacing_px, with_surface=False)  # (their surface points are not used)
    if len(V) == 0 or len(D) == 0:
        return Votes.none()
    step = max(1, int(round(o.reverse_px / o.sample_px)))
    sub = np.arange(0, len(D), step)
    X = D.X
    if lines.pose is not None or prev.pose is not None:
        # A moving scene: the line samples' surface points where their objects were in the
        # previous frame, before they are projected with its camera.
        X = resample(lines, o.sample_px, surface=carry_points(lines.surface, lines.face, lines.pose, prev.pose)).X
    back = Samples(p=D.p.take(sub, axis=0), X=X.take(sub, axis=0), u=None, t=D.t.take(sub, axis=0), ids=None,
                   stroke=None, s=None, w=None) if step > 1 or X is not D.X else D
    rm, rq = match_pieces(back, prev.camera, V, to.search_radius_px, to.min_tangent_dot, k=2)
    # (Kind classes (_kind_class) per stroke, then per sample, in the kernel; int64 codes: its one
    # compiled signature, whatever the codes' dtype.) The matches of another kind class: a claim
    # on the id only (Votes.other).
    m, vid, u, w, sign, om, oid, ow = kernels().carried(
        rm, rq, sub, np.asarray(lines.kind, np.int64), D.stroke, np.asarray(prev.kind, np.int64), CONTOUR, N_KINDS,
        V.p, V.t, V.w, V.u, V.s, V.stroke, V.ids, D.w, D.t, step)
    return Votes(m=m, vid=vid, u=u, w=w, sign=sign, other=(om, oid, ow))


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


#: Ids (step 6): the weight of a path's label length against that of the votes it holds.
LABEL_ID_WEIGHT = 0.25


def landing(m: np.ndarray, cover: np.ndarray, smp_piece: np.ndarray, D: Samples, p_s0: np.ndarray,
            p_s1: np.ndarray):
    """Where the votes on line samples m (V,) land: (ok (V,) whether on a drawn piece, vk the
    piece of each that does, s_in its arc length within the piece, px). A vote on a covered
    sample lands where the covering sample lies."""
    return kernels().votes_landing(m, cover, smp_piece, D.s, p_s0, p_s1)


def path_ids(S: int, path_of: np.ndarray, p_label: np.ndarray, plen: np.ndarray, votes: "Votes", vk: np.ndarray,
              vid: np.ndarray, vw: np.ndarray, cover: np.ndarray, smp_piece: np.ndarray, D: Samples, p_s0: np.ndarray,
              p_s1: np.ndarray, known: np.ndarray, next_id: int) -> tuple[np.ndarray, int]:
    """(S,) the ids of the paths and the next unused id. Each previous id goes to one path, the
    heaviest claims first (assign_ids): a path's claim on an id is the weight of the votes of
    that id it holds (landing on its pieces, vk (V,) the piece of each vote of weight vw and id
    vid), of the other kind class too (votes.other: a crease edge drawn as outline in the last
    frame, or the other way round, keeps its path's id), plus LABEL_ID_WEIGHT times the length of
    its pieces labelled with the id (a piece grown along its line holds no votes). Without the
    other class's votes, a path whose kind changed would take a fresh id and its old id end.
    `known`: the ids of the previous paths, sorted. Paths without a claim get fresh ids from
    next_id."""
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
    return assign_ids(S, cs, ci, cw, next_id)


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
