"""Strokes that persist along the camera path: ids, a parametrization that does not slide, and
self-similar texture levels. The tracking pass is the only stage that walks the frames in order;
everything before it (features, visibility, chaining) is per frame and independent.

`Tracker(options).step(strokes) -> strokes` takes one frame's strokes (as LineRenderer gives them)
and returns them with persistent `ids`, a coherent `u` (texture periods of `period_px` px) and the
self-similar `level` / `level_weight`. Three methods:

- "kalnins" (default; Kalnins et al. 2003, "Coherent Stylized Silhouettes"): the previous frame's
  strokes are sampled every `vote_spacing_px`; each sample carries its surface point X, its u and
  its stroke id. X is projected with the new camera and votes on the nearest new sample within
  `search_radius_px` whose tangent agrees (the same correspondence the metrics of BRIEF 3 use);
  with `reverse_votes` every new sample also looks back for the nearest old sample. First,
  chains of one kind whose ends meet within `join_tol_px` are joined into one path
  (`chain_touching`; where two strands overlap at their ends, the joint point that would make
  the path turn back is dropped): where the chaining stops changes from frame to frame. Each path is then
  cut into segments where the id its votes carry changes (Kalnins' brush path segments; runs
  shorter than `min_segment_px` are absorbed), so ids, not this frame's chain ends, decide where
  strokes begin and end. A cut between two ids goes where the previous frame's stroke end
  projects (`snap_boundaries`: the boundary between two ids does not wander with the sample
  spacing from frame to frame). Closed loops are turned to start at the old loop's seam, and
  where an open stroke runs across an old loop's seam the votes are unwrapped by the loop's u
  span (no fold there). Each segment is oriented so that u increases along it: the way its
  carried u increases, or, where the votes do not tell, the way the old tangents ran (an edge
  turning through edge-on turns its image around while u keeps its order). With
  `chain_touching` off, segments with the same id whose chains end within `join_tol_px` are
  healed into one stroke afterwards, a short chain that no vote landed on carrying the id of
  the chain it continues. Per stroke,
  votes of other ids are shifted by whole periods (the texture is periodic) to meet the largest
  group, which heals strokes that merged. u is then fitted by least squares as a piecewise-linear
  function of arc length (knots every `knot_spacing_px`, inserted as points so that downstream
  linear interpolation of u is exact): close to the votes (no sliding), slope close to 1/P (no
  stretch, `stretch_weight`), even stretch between knots (`bend_weight`); votes farther than
  `outlier_px` from the fit are dropped and the fit redone. Parts without votes (growth) continue
  the fit; strokes without any vote start at u = s / P.
- "seed" (seed 000, section 2.2.2, as a baseline): strokes are re-cut so that they start near a
  previous start (strategy 1) in the preferred direction (strategy 2, weight = d + angle penalty),
  grow at most `max_growth_px` per frame (strategy 3), the rest of the lines is filled by the
  longest pieces left from the existing ends (strategy 4), and only strokes of at least
  `min_carry_px` are carried as bases (strategy 5). u = arc length / P from each start.
- "none" (`--no-coherence`): ids renumbered 0..S-1 every frame, u = arc length / P.

Ids: a previous id goes to the new stroke that holds most of its matched length, and a new stroke
takes the id holding most of its matched length (greedy on matched length, ties broken by stroke
index then id), so the largest persisting part of a stroke that splits or merges keeps the id;
every other stroke gets a fresh id from a counter. Everything is deterministic for a given input.

Self-similar levels (Benard et al. 2010): a stroke whose u is stretched by lambda = 1 / (P du/ds)
is drawn with the 1D texture octaves k = `level` and k + 1, octave k sampling the texture at
u * 2^-k; `level_weight` is the weight of octave `level` and 1 - level_weight that of octave
level + 1. With c = log2(P du/ds) (the fitted slope), level = floor(c) and
level_weight = 1 - frac(c): when a stroke shrinks 8 times under a dolly its marks do not; the
unstretched case is level 0, weight 1. Brush head and tail keep their size in the ribbon writer,
which only needs u and the stroke length.

Split criteria (angle, maximum length) and the removal of doubled contour pieces
(`drop_doubled`, LineOptions.doubled_px) belong to the per-frame line pass. With the default
`join_tol_px` the tracked frame draws the input lines with bridges of at most `join_tol_px` where
strokes are healed (0: exactly the input lines).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .coherence import Samples, match_samples, resample_strokes, surface_between
from .errors import UsageError
from .model import Strokes, bracket, row_norm, uclip
from .options import _FLAGS, _flag
from .strokeops import _cat, _replace, _tree, cut_pieces, drop_hairpins

METHODS = ("kalnins", "seed", "none")


def _field_name(name: str) -> str:
    """How an error names a TrackingOptions field: its command-line option where it has one."""
    return _flag(name) if name in _FLAGS else name


@dataclass(frozen=True)
class TrackingOptions:
    """Options of the tracking pass. Pixel values are image pixels.

    method: "kalnins" | "seed" | "none". period_px: texture period P of u.
    search_radius_px, min_tangent_dot: correspondence of carried samples (BRIEF 3: 6 px, 0.65).
    vote_spacing_px: spacing of the samples carried from frame to frame (kalnins).
    stretch_weight: weight of "slope close to 1/P" against "u close to the votes" (kalnins): a
    stroke of length L stretched by a factor (1 + d) costs stretch_weight L d^2, as much as votes
    all missed by sqrt(stretch_weight) d periods; both scale with L, so short and long strokes
    trade sliding for stretch alike.
    outlier_px: votes farther than this from the fit are dropped (kalnins).
    min_id_px: matched length needed for an id to persist.
    min_segment_px: a chain is cut between runs of votes carrying different ids (Kalnins' segments);
    runs shorter than this are absorbed by their neighbours (kalnins).
    dense_spacing_px: spacing of the new strokes' samples that votes land on (positions along
    the stroke are refined below it by projecting on the sample's tangent).
    reverse_votes: new samples also look back for the nearest old sample (both ways, as BRIEF 3).
    join_tol_px, join_angle_deg: segments with the same carried id whose strokes end within
    join_tol_px of each other, turning by at most join_angle_deg, are healed into one stroke
    (0 disables; above 1e-3 the joint bridges the gap, which adds at most join_tol_px of line).
    snap_boundaries: cuts between two carried ids go where the previous stroke ends project.
    chain_touching: join chains whose ends meet (join_tol_px, join_angle_deg) before cutting by
    votes (see the module doc); healing after the cut is then not needed.
    knot_spacing_px: u is piecewise linear with knots this far apart (0: one line per stroke);
    bend_weight: weight of even stretch between knots (kalnins).
    max_growth_px, min_carry_px, seed_search_px, seed_angle_penalty_px: seed 000 strategies 3, 5,
    the neighbourhood of strategy 1 and the direction penalty (px per radian) of strategy 2."""

    method: str = "kalnins"
    period_px: float = 30.0
    search_radius_px: float = 6.0
    min_tangent_dot: float = 0.65
    vote_spacing_px: float = 4.0
    stretch_weight: float = 3e-3
    outlier_px: float = 3.0
    min_id_px: float = 2.0
    max_growth_px: float = 20.0
    min_carry_px: float = 10.0
    seed_search_px: float = 12.0
    seed_angle_penalty_px: float = 10.0
    min_segment_px: float = 7.0
    knot_spacing_px: float = 24.0
    join_tol_px: float = 2.0
    join_angle_deg: float = 90.0
    dense_spacing_px: float = 5.0
    reverse_votes: bool = True
    bend_weight: float = 0.01
    snap_boundaries: bool = True
    chain_touching: bool = True

    def __post_init__(self):
        if self.method not in METHODS:
            raise UsageError(f"unknown coherence method {self.method!r} (known: {', '.join(METHODS)})")
        for name in ("period_px", "search_radius_px", "vote_spacing_px", "seed_search_px", "dense_spacing_px"):
            if not getattr(self, name) > 0:
                raise UsageError(f"{_field_name(name)} must be > 0, got {getattr(self, name)}")
        for name in ("stretch_weight", "outlier_px", "min_id_px", "max_growth_px", "min_carry_px",
                     "seed_angle_penalty_px", "join_tol_px", "min_segment_px", "knot_spacing_px", "bend_weight"):
            if not getattr(self, name) >= 0:
                raise UsageError(f"{_field_name(name)} must be >= 0, got {getattr(self, name)}")
        if not 0 <= self.min_tangent_dot <= 1:
            raise UsageError(f"min tangent dot must be in [0, 1], got {self.min_tangent_dot}")


def insert_points(strokes: Strokes, stroke: np.ndarray, s: np.ndarray) -> Strokes:
    """Strokes with extra points at arc lengths s (px) of strokes `stroke` (same polylines; the
    new points interpolate position and surface point). Points closer than 1e-6 px to an existing
    point are not added."""
    if len(stroke) == 0:
        return strokes
    offsets = strokes.offsets
    base, G = strokes.global_arc
    g = base[stroke] + np.asarray(s, float)
    first = offsets[:-1][stroke]
    last = offsets[1:][stroke] - 1
    i, j = bracket(G, G.searchsorted(g, side="right"), first, last)
    Gi, Gj = G[i], G[j]
    keep = ((Gj - Gi > 0) & (g - Gi > 1e-6) & (Gj - g > 1e-6)).nonzero()[0]
    i, j, g, stroke, Gi, Gj = i[keep], j[keep], g[keep], stroke[keep], Gi[keep], Gj[keep]
    if len(i) == 0:
        return strokes
    a = ((g - Gi) / (Gj - Gi))[:, None]
    # take(axis=0) for row gathers: numpy's fancy indexing of (N, 2) / (N, 3) rows is ~8x slower
    # on arrays of a frame's size (same values).
    P = np.concatenate([strokes.points, strokes.points.take(i, axis=0) * (1 - a) + strokes.points.take(j, axis=0) * a])
    X = np.concatenate([strokes.surface, surface_between(strokes, i, j, a[:, 0])])
    F = np.concatenate([strokes.face, np.where(a[:, 0] < 0.5, strokes.face[i], strokes.face[j])])
    U = np.concatenate([strokes.u, strokes.u[i] * (1 - a[:, 0]) + strokes.u[j] * a[:, 0]])
    # Sort by (stroke, arc); an old point precedes a new point at the same place. The global arc
    # coordinate alone orders the strokes (a 1 px gap between them), and old points come first in
    # allg: a stable sort of allg is that order (~4x cheaper than the 3-key lexsort it replaces).
    order = np.concatenate((G, g)).argsort(kind="stable")
    # Points per stroke: the old counts plus the new points of each stroke.
    counts = (offsets[1:] - offsets[:-1]) + np.bincount(stroke, minlength=len(strokes))
    return _replace(strokes, points=P.take(order, axis=0), surface=X.take(order, axis=0), face=F[order], u=U[order],
                   offsets=np.concatenate(((0,), counts.cumsum())).astype(np.int64))


def rotate_closed(strokes: Strokes, which: np.ndarray, s_start: np.ndarray) -> Strokes:
    """Closed strokes `which` made to start at arc length `s_start` (px) instead; same loop."""
    S = len(strokes)
    L = strokes.lengths
    rot = np.zeros(S, bool)
    rot[which] = True
    start = np.zeros(S)
    start[which] = s_start
    nr = int(rot.sum())
    pst = _cat(np.arange(S), np.flatnonzero(rot))
    second = _cat(np.zeros(S, bool), np.ones(nr, bool))
    s0 = _cat(start, np.zeros(nr))
    s1 = _cat(L, start[rot])
    order = np.lexsort((second, pst))
    pieces = cut_pieces(strokes, pst[order], s0[order], s1[order])
    keep = np.ones(len(pieces.points), bool)
    keep[pieces.offsets[:-1][second[order]]] = False  # the joint point is already there
    owner = pst[order][pieces.stroke_of_point][keep]
    counts = np.bincount(owner, minlength=S)
    out = _replace(strokes, points=pieces.points[keep], surface=pieces.surface[keep], face=pieces.face[keep],
                  u=np.zeros(int(keep.sum())), offsets=_cat(0, np.cumsum(counts)).astype(np.int64))
    return _replace(out, u=out.arc_length / out.period_px)


def _turn_loops_to_seams(cur: Strokes, dense: Samples, vm: np.ndarray, u: np.ndarray, vid: np.ndarray, P: float):
    """Rotate closed strokes whose votes show the seam of an old loop (consecutive votes of one id
    whose u differs by more than half the loop) so they start there. Returns the strokes, their
    1 px samples (reordered, s measured from the new start) and the vote targets remapped."""
    if len(vm) == 0 or len(cur) == 0:
        return cur, dense, vm
    first, last = cur.offsets[:-1], cur.offsets[1:] - 1
    L = cur.lengths
    closed = (L > 0) & (row_norm(cur.points.take(first, axis=0) - cur.points.take(last, axis=0)) < 1e-6)
    if not closed.any():
        return cur, dense, vm
    vst, vs = dense.stroke[vm], dense.s[vm]
    sel = np.flatnonzero(closed[vst])
    if len(sel) < 2:
        return cur, dense, vm
    o = sel[np.lexsort((vs[sel], vid[sel], vst[sel]))]  # consecutive votes of one id
    stq, sq, uq, idq = vst[o], vs[o], u[o], vid[o]
    jump = np.abs(np.diff(uq))
    ok = (stq[1:] == stq[:-1]) & (idq[1:] == idq[:-1]) & (jump > np.maximum(0.5 * L[stq[:-1]] / P, 1.0))
    if not ok.any():
        return cur, dense, vm
    k = np.flatnonzero(ok)
    # Largest jump per stroke.
    k = k[np.lexsort((-jump[k], stq[k]))]
    k = k[_cat(True, stq[k][1:] != stq[k][:-1])]
    which = stq[k]
    seam = 0.5 * (sq[k] + sq[k + 1])
    cur = rotate_closed(cur, which, seam)
    shift = np.zeros(len(L))
    shift[which] = seam
    s_new = np.mod(dense.s - shift[dense.stroke], np.where(L > 0, L, 1.0)[dense.stroke])
    perm = np.lexsort((s_new, dense.stroke))
    inv = np.empty_like(perm)
    inv[perm] = np.arange(len(perm))
    dense = Samples(p=dense.p[perm], X=dense.X[perm], u=dense.u[perm], t=dense.t[perm], ids=dense.ids[perm],
                    stroke=dense.stroke[perm], s=s_new[perm], w=dense.w[perm])
    return cur, dense, inv[vm]


class PiecewiseU:
    """u along every stroke as a piecewise-linear function of arc length, knots every ~`knot_px`
    px (n_s = ceil(L_s / knot_px) equal intervals per stroke), solved for all strokes at once as
    one sparse least-squares problem (block diagonal)."""

    def __init__(self, lengths: np.ndarray, knot_px: float):
        self.L = np.asarray(lengths, float)
        self.n = np.maximum(1, np.ceil(self.L / knot_px - 1e-9)).astype(np.int64)
        self.h = self.L / self.n
        self.base = _cat(0, np.cumsum(self.n + 1)).astype(np.int64)  # first knot of each stroke

    def inner_knot_stroke(self) -> np.ndarray:
        return np.repeat(np.arange(len(self.L)), self.n - 1)

    def inner_knot_s(self) -> np.ndarray:
        st = self.inner_knot_stroke()
        j = np.arange(len(st)) - np.repeat(_cat(0, np.cumsum(self.n - 1)[:-1]), self.n - 1) + 1
        return j * self.h[st]

    def _interval(self, st, s):
        # Cached for the last (st, s) pair: the fit and the evaluation at the votes share it.
        c = self.__dict__.get("_iv")
        if c is not None and c[0] is st and c[1] is s:
            return c[2], c[3]
        h = self.h[st]
        hp = h > 0
        x = np.where(hp, s / np.where(hp, h, 1.0), 0.0)
        j = uclip(np.floor(x), 0, self.n[st] - 1).astype(np.int64)
        k, a = self.base[st] + j, uclip(x - j, 0.0, 1.0)
        self._iv = (st, s, k, a)
        return k, a

    def eval(self, knots: np.ndarray, st: np.ndarray, s: np.ndarray) -> np.ndarray:
        k, a = self._interval(st, s)
        return knots[k] * (1 - a) + knots[k + 1] * a

    @staticmethod
    def _terms(nk, cols, vals, y, rows):
        """Normal-equation terms of residuals sum_a vals[a] x[cols[a]] - y (weights already in
        vals and y), appended to rows[band row] (rows[3]: the right-hand side) in the order they
        are added; y None: a zero right-hand side (its terms are +0.0 everywhere: adding them
        changes nothing, they are left out)."""
        m = len(cols)
        for a_ in range(m):
            rows[0].append(np.bincount(cols[a_], vals[a_] * vals[a_], minlength=nk))
            if y is not None:
                rows[3].append(np.bincount(cols[a_], vals[a_] * y, minlength=nk))
            for b_ in range(a_ + 1, m):
                rows[b_ - a_].append(np.bincount(cols[a_], vals[a_] * vals[b_], minlength=nk))
        return rows

    #: Terms the votes add to each band row (0, 1, 2) and to the right-hand side (3), first.
    _VOTE_TERMS = (2, 1, 0, 2)

    def _fixed_terms(self, prior_a, prior_b, b0, stretch_weight, bend_weight):
        """The terms that do not depend on the votes (stretch, bend, anchor), cached for the
        same arguments (the tracker fits twice with the same prior, dropping outliers): per band
        row and right-hand side a (vote terms + fixed terms, nk) buffer whose first rows the
        fit fills with its vote terms (see fit)."""
        key = (prior_a, prior_b, b0, stretch_weight, bend_weight)
        c = self.__dict__.get("_fixed")
        if c is not None and all(x is y or (not isinstance(x, np.ndarray) and x == y) for x, y in zip(c[0], key)):
            return c[1]
        nk = int(self.base[-1])
        S = len(self.L)
        # Each term adds at distinct knots (the intervals, inner knots and knots are distinct):
        # its np.bincount is its values set at those knots over zeros (the one difference, a
        # -0.0 product, adds to a sum that never is -0.0, as it starts with a vote term:
        # nothing changes). Written straight into the buffers, in _terms' order:
        # row 0: stretch aa, bb, bend aa, bb, cc, anchor; row 1: stretch ab, bend ab, bc;
        # row 2: bend ac; right-hand side: stretch ay, by, anchor (bend: zero, left out).
        nv0, nv1, nv2, nv3 = self._VOTE_TERMS
        b0_, b1_, b2_, b3_ = (np.zeros((nv0 + 6, nk)), np.zeros((nv1 + 3, nk)), np.zeros((nv2 + 1, nk)),
                              np.zeros((nv3 + 3, nk)))
        # stretch, per interval
        js = np.arange(S).repeat(self.n)
        cn = self.n.cumsum()
        kk = self.base[js] + (np.arange(cn[-1] if S else 0) - (cn - self.n).repeat(self.n))
        hs = self.h[js]
        hh = np.maximum(hs, 1.0)
        ws = np.sqrt(stretch_weight / hh)
        va, vb, y = -ws, ws, ws * hs * b0
        b0_[nv0, kk] = va * va
        b3_[nv3, kk] = va * y
        b1_[nv1, kk] = va * vb
        b0_[nv0 + 1, kk + 1] = vb * vb
        b3_[nv3 + 1, kk + 1] = vb * y
        # bend, per inner knot (strokes with >= 2 intervals)
        inner = np.flatnonzero(self.n[js] >= 2)
        jb = kk[inner]
        last_interval = jb + 1 >= self.base[js[inner]] + self.n[js[inner]]
        jb, sb = jb[~last_interval], js[inner][~last_interval]
        wb = np.sqrt(bend_weight * np.maximum(self.L[sb], 1.0))
        va, vb, vc = wb, -2 * wb, wb
        b0_[nv0 + 2, jb] = va * va
        b1_[nv1 + 1, jb] = va * vb
        b2_[nv2, jb] = va * vc
        b0_[nv0 + 3, jb + 1] = vb * vb
        b1_[nv1 + 2, jb + 1] = vb * vc
        b0_[nv0 + 4, jb + 2] = vc * vc
        # weak anchor to the line fit
        ks = np.arange(S).repeat(self.n + 1)
        sk = (np.arange(nk) - self.base[ks]) * self.h[ks]
        we = np.full(nk, 1e-3)
        b0_[nv0 + 5] = we * we
        b3_[nv3 + 2] = we * (1e-3 * (prior_a[ks] + prior_b[ks] * sk))
        bufs = [b0_, b1_, b2_, b3_]
        self._fixed = (key, bufs)
        return bufs

    def fit(self, st, s, u, w, prior_a, prior_b, b0, stretch_weight, bend_weight) -> np.ndarray:
        """Knot values minimizing sum w (u(s) - u)^2 (votes) + stretch_weight / h (du - h b0)^2
        per interval (slope close to the nominal b0 = 1/P) +
        bend_weight L (second difference)^2 per inner knot (even stretch) + 1e-6 (knot - prior)^2
        (the line fit a + b s; fixes strokes without votes)."""
        nk = int(self.base[-1])
        # Normal equations accumulated straight into the 3 lower bands of a symmetric banded
        # matrix (every residual touches at most 3 consecutive knots of one stroke), in a fixed
        # order: votes, stretch, bend, anchor. Each band row is the sum of its terms in that
        # order: the terms stacked in one buffer and summed along it (np.add.reduce over the
        # first axis adds the rows one after the other, elementwise: the same sums as adding
        # the terms one by one into zeros, whose first addition is exact).
        k, a = self._interval(st, s)
        sw = np.sqrt(w)
        votes = self._terms(nk, [k, k + 1], [sw * (1 - a), sw * a], sw * u, ([], [], [], []))
        bufs = self._fixed_terms(prior_a, prior_b, b0, stretch_weight, bend_weight)
        band = np.empty((3, nk))
        for r in range(3):  # (every buffer holds 1+ terms: each term is added for every stroke)
            np.add.reduce(_fill_rows(bufs[r], votes[r]), axis=0, out=band[r])
        rhs = np.add.reduce(_fill_rows(bufs[3], votes[3]), axis=0)
        band[1, -1:] = 0.0
        band[2, -2:] = 0.0
        if nk == 0:
            from scipy.linalg import solveh_banded

            return solveh_banded(band, rhs, lower=True, check_finite=False)
        # scipy.linalg.solveh_banded without its checks and wrappers: the same LAPACK pbsv.
        from scipy.linalg.lapack import dpbsv

        _, x, info = dpbsv(band, rhs, lower=1, overwrite_ab=1, overwrite_b=1)
        if info > 0:
            from numpy.linalg import LinAlgError

            raise LinAlgError(f"{info}th leading minor not positive definite")
        if info < 0:
            raise ValueError(f"illegal value in {-info}th argument of internal pbsv")
        return x


def _fill_rows(buf: np.ndarray, rows: list) -> np.ndarray:
    """buf with its first len(rows) rows set to `rows`."""
    for i, t in enumerate(rows):
        buf[i] = t
    return buf


def _local_slope(smp: Samples) -> np.ndarray:
    """du/ds (periods per px) at every sample, from its neighbours in the same stroke."""
    n = len(smp)
    if n < 2:
        return np.zeros(n)
    # The next (previous) sample where it is on the same stroke, else the sample itself.
    same = smp.stroke[1:] == smp.stroke[:-1]
    ar = np.arange(n)
    nxt = ar + np.concatenate((same, (False,)))
    prv = ar - np.concatenate(((False,), same))
    ds = smp.s[nxt] - smp.s[prv]
    return np.where(ds > 0, (smp.u[nxt] - smp.u[prv]) / np.where(ds > 0, ds, 1.0), 0.0)


def _join_segments(cur: Strokes, r_stroke, r_s0, r_s1, r_label, r_sign, tol_px: float, angle_deg: float,
                   straightest_first: bool = False):
    """Healing at junctions: segments (runs) of different open strokes of the same kind that carry
    the same id and end at the same point (within tol_px, turning by at most angle_deg) are
    drawn as one stroke. Links are made end to end, each end of a run in one link at most, so a
    short chain between two others joins both (paths of any length; a ring of links is opened at
    its lowest run). Returns group (R,) (a group id per run: the lowest run of the group), rev
    (R,): whether each run is traversed backwards, so that the runs of a group meet end to start
    and u increases along the votes, and pos (R,): the place of each run in its group."""
    R = len(r_stroke)
    group = np.arange(R)
    rev = r_sign < 0
    pos = np.zeros(R, np.int64)
    if R < 2 or tol_px <= 0:
        return group, rev, pos
    L = cur.lengths
    first, last = cur.offsets[:-1], cur.offsets[1:] - 1
    closed = row_norm(cur.points[first] - cur.points[last]) < 1e-6
    at_start = (r_s0 <= 1e-9) & ~closed[r_stroke]
    at_end = (r_s1 >= L[r_stroke] - 1e-9) & ~closed[r_stroke]
    # Ends of strokes that a labelled segment reaches: (run, 0 = stroke start | 1 = stroke end).
    e_run = _cat(np.flatnonzero(at_start), np.flatnonzero(at_end))
    e_end = _cat(np.zeros(int(at_start.sum()), np.int64), np.ones(int(at_end.sum()), np.int64))
    if len(e_run) < 2:
        return group, rev, pos
    sk = r_stroke[e_run]
    pt = np.where(e_end[:, None] == 0, cur.points[first[sk]], cur.points[last[sk]])
    nb = np.where(e_end == 0, np.minimum(first[sk] + 1, last[sk]), np.maximum(last[sk] - 1, first[sk]))
    d = cur.points[nb] - pt  # direction away from the end, into the stroke
    d = d / np.maximum(row_norm(d), 1e-12)[:, None]
    if tol_px < 1e-3:
        # Ends at the same point: equal after rounding to the tolerance (sort, compare neighbours).
        key = np.round(pt / max(tol_px, 1e-9)).astype(np.int64)
        o = np.lexsort((key[:, 1], key[:, 0]))
        eq = np.flatnonzero(np.all(key[o][1:] == key[o][:-1], axis=1))
        pairs = np.stack([o[eq], o[eq + 1]], axis=1)
    else:
        from scipy.spatial import cKDTree

        pairs = cKDTree(pt).query_pairs(tol_px, output_type="ndarray")
    if len(pairs) == 0:
        return group, rev, pos
    a, b = pairs[:, 0], pairs[:, 1]
    ok = (sk[a] != sk[b]) & (cur.kind[sk[a]] == cur.kind[sk[b]])
    straight = -np.einsum("ij,ij->i", d[a], d[b])  # cosine of the turn at the joint
    ok &= straight >= np.cos(np.radians(angle_deg))
    a, b, straight = a[ok], b[ok], straight[ok]
    # A piece of chain without votes (a few px between two chains: no carried sample landed on
    # it) continues the id of a chain it touches, so that the id is carried across it.
    lab = r_label.copy()
    for _ in range(2):
        la, lb = lab[e_run[a]], lab[e_run[b]]
        fa = (la < 0) & (lb >= 0)
        fb = (lb < 0) & (la >= 0)
        if not (fa.any() or fb.any()):
            break
        # Deterministic: the lowest-numbered labelled partner wins (last write wins, so sort down).
        for f_, tgt, src in ((fa, a, b), (fb, b, a)):
            k = np.flatnonzero(f_)
            k = k[np.argsort(-e_run[src[k]], kind="stable")]
            lab[e_run[tgt[k]]] = lab[e_run[src[k]]]
    ok = (lab[e_run[a]] == lab[e_run[b]]) & (lab[e_run[a]] >= 0)
    a, b, straight = a[ok], b[ok], straight[ok]
    if len(a) == 0:
        return group, rev, pos
    # Deterministic links, each run end in one link at most. Run ends are the entries of the
    # e_* arrays (nodes); partner[node] is the node it is linked to (-1: free). Plain Python on
    # int lists: a greedy pass in a fixed order over ~100-200 candidate links a frame.
    # Where three ends meet, the straightest continuation is linked first (straightest_first).
    keys = (e_run[b], e_run[a], -np.round(straight, 9)) if straightest_first else (e_run[b], e_run[a])
    o = np.lexsort(keys)
    run_of, end_of = e_run.tolist(), e_end.tolist()
    partner = [-1] * len(run_of)
    for x, y in zip(a[o].tolist(), b[o].tolist()):
        if partner[x] >= 0 or partner[y] >= 0 or run_of[x] == run_of[y]:
            continue
        partner[x], partner[y] = y, x
    # lk[r, e]: the node linked to end e (0 start, 1 end) of run r, -1 if none.
    partner = np.array(partner, np.int64)
    lk = np.full((R, 2), -1, np.int64)
    lk[e_run, e_end] = partner
    linked = lk >= 0
    runs = np.flatnonzero(linked.any(axis=1))
    # Path starts: runs with one linked end; then rings (every run of them linked at both ends).
    starts = _cat(runs[linked[runs, 0] != linked[runs, 1]], runs).tolist()
    lk = lk.ravel().tolist()
    seen = [False] * R
    sign, g_l, rev_l, pos_l = r_sign.tolist(), group.tolist(), rev.tolist(), pos.tolist()
    for r0 in starts:
        if seen[r0]:
            continue
        # Enter r0 through its free end (a ring: through its start), leave through the other.
        e = 1 if lk[2 * r0] >= 0 and lk[2 * r0 + 1] < 0 else 0
        r = r0
        members, backwards = [], []  # backwards: entered at the stroke end, traversed reversed
        while not seen[r]:
            seen[r] = True
            members.append(r)
            backwards.append(e == 1)
            nxt = lk[2 * r + 1 - e]
            if nxt < 0:
                break
            r, e = run_of[nxt], end_of[nxt]
        # Whole path backwards if the votes say so (plain Python: paths are short and few).
        if sum(-sign[m] if bk else sign[m] for m, bk in zip(members, backwards)) < 0:
            members, backwards = members[::-1], [not bk for bk in backwards[::-1]]
        g = min(members)
        for k, (m, bk) in enumerate(zip(members, backwards)):
            g_l[m], rev_l[m], pos_l[m] = g, bk, k
    group, rev, pos = np.array(g_l, np.int64), np.array(rev_l, bool), np.array(pos_l, np.int64)
    return group, rev, pos


def _close_pairs(pt: np.ndarray, r: float) -> np.ndarray:
    """(K, 2) index pairs i < j of the points pt (N, 2) at most r apart: the pairs of
    cKDTree(pt).query_pairs(r) (same test, dx * dx + dy * dy <= r * r), in another order. For a
    few hundred stroke ends a sweep along x is ~4x cheaper than building a tree: neighbours in x
    order within r (plus a margin, the test decides) are the candidates."""
    lo, hi = _close_pair_arrays(pt, r)
    return np.stack([lo, hi], axis=1)


def _close_pair_arrays(pt: np.ndarray, r: float) -> tuple[np.ndarray, np.ndarray]:
    """_close_pairs as its two columns (lower index, higher index), same pairs in the same order."""
    n = len(pt)
    px, py = pt[:, 0].copy(), pt[:, 1].copy()  # contiguous columns for the gathers below
    o = px.argsort(kind="stable")
    x = px[o]
    ar = np.arange(n)
    cnt = x.searchsorted(x + (r + 1e-6), side="right") - ar - 1
    csum = cnt.cumsum()
    # Candidate t of sorted point i (t counted over all candidates) is sorted point
    # i + 1 + (t - first candidate of i): one repeat of the per-point shift.
    a = o.repeat(cnt)
    b = o[np.arange(int(csum[-1]) if n else 0) + (ar + 1 - (csum - cnt)).repeat(cnt)]
    dx = px[a] - px[b]
    dy = py[a] - py[b]
    keep = (dx * dx + dy * dy <= r * r).nonzero()[0]
    a, b = a[keep], b[keep]
    return np.minimum(a, b), np.maximum(a, b)


def _straightest_order(straight: np.ndarray, ra: np.ndarray, rb: np.ndarray, S: int) -> np.ndarray:
    """np.lexsort((rb, ra, -np.round(straight, 9))) (ra, rb in [0, S)): the same permutation, by one
    stable sort of an integer key where it fits in 63 bits. np.round(x, 9) is rint(x * 1e9) / 1e9,
    whose order (ties included) is that of the integer rint(x * 1e9) (|x| <= ~1: distinct integers
    stay distinct after the division)."""
    r9 = np.rint(straight * 1e9)
    if S >= 40000 or not (np.abs(r9) <= 1.5e9).all():  # (3e9 S^2 < 2^63)
        return np.lexsort((rb, ra, -np.round(straight, 9)))
    t = (1_500_000_000 - r9).astype(np.int64)  # ascending -round(straight, 9), >= 0
    return ((t * S + ra) * S + rb).argsort(kind="stable")


def _touching_paths(strokes: Strokes, tol_px: float, angle_deg: float):
    """_join_segments(strokes, arange(S), zeros(S), lengths, zeros(S), ones(S), tol_px, angle_deg,
    straightest_first=True), the call chain_touching makes, specialized (same group, rev, pos): every
    run is a whole stroke, all labels agree and all signs are +1, so the label healing is moot, the
    ends are the open strokes' first and last points and a path is reversed when most of its
    strokes are entered at their end. The tracker runs it on every frame (~200 strokes): the
    per-member bookkeeping of the walk is done with numpy after a bare Python walk."""
    S = len(strokes)
    group = np.arange(S)
    rev = np.zeros(S, bool)
    pos = np.zeros(S, np.int64)
    P = strokes.points
    first, last = strokes.offsets[:-1], strokes.offsets[1:] - 1
    closed = row_norm(P.take(first, axis=0) - P.take(last, axis=0)) < 1e-6
    op = np.flatnonzero(~closed)
    n = len(op)
    if 2 * n < 2:
        return group, rev, pos
    # Nodes: starts of the open strokes, then their ends (the order _join_segments uses).
    e_run = _cat(op, op)
    fo, lo = first[op], last[op]
    e_pt = _cat(fo, lo)
    nb = _cat(np.minimum(fo + 1, lo), np.maximum(lo - 1, fo))
    pt = P.take(e_pt, axis=0)
    d = P.take(nb, axis=0) - pt  # direction away from the end, into the stroke
    d = d / np.maximum(row_norm(d), 1e-12)[:, None]
    a, b = _close_pair_arrays(pt, tol_px)
    if len(a) == 0:
        return group, rev, pos
    ok = (e_run[a] != e_run[b]) & (strokes.kind[e_run[a]] == strokes.kind[e_run[b]])
    dx, dy = d[:, 0], d[:, 1]
    straight = -(dx[a] * dx[b] + dy[a] * dy[b])  # cosine of the turn at the joint
    ok &= straight >= np.cos(np.radians(angle_deg))
    if not ok.any():
        return group, rev, pos
    a, b, straight = a[ok], b[ok], straight[ok]
    # Greedy links in the order of _join_segments (straightest first; the pairs come in another
    # order than the k-d tree's, the sort decides). A node's code is 2 * stroke + end.
    o = _straightest_order(straight, e_run[a], e_run[b], S)
    a, b = a[o], b[o]
    code = 2 * e_run + (np.arange(2 * n) >= n)
    partner = np.full(2 * n, -1, np.int64)
    # A link whose two ends are in no other candidate link is taken whatever the order (most of
    # them): set at once; only links at junctions of 3+ ends go through the greedy pass.
    deg = np.bincount(_cat(a, b), minlength=2 * n)
    solo = (deg[a] == 1) & (deg[b] == 1)
    partner[a[solo]] = code[b[solo]]
    partner[b[solo]] = code[a[solo]]
    if not solo.all():
        # (The ends of these links are in no solo link: a set of the ends taken so far is all
        # the greedy pass needs.)
        taken, xs, ys = set(), [], []
        for x, y in zip(a[~solo].tolist(), b[~solo].tolist()):
            if x in taken or y in taken:
                continue
            taken.add(x)
            taken.add(y)
            xs.append(x)
            ys.append(y)
        partner[xs] = code[ys]
        partner[ys] = code[xs]
    # nxt[c]: code of the end linked to end c (-1: free); entering at c, one leaves at c ^ 1.
    nxt = np.full(2 * S, -1, np.int64)
    nxt[code] = partner
    linked = (nxt >= 0).reshape(S, 2)
    l0, l1 = linked[:, 0], linked[:, 1]
    runs = np.flatnonzero(l0 | l1)
    one = runs[l0[runs] != l1[runs]]
    nxt = nxt.tolist()
    walk, heads = [], []
    # Path starts: strokes with one linked end, entered through the free end, in stroke order. A
    # path (the links make paths and rings) runs from its start to its other end stroke, which
    # is the one start left to skip.
    done = set()
    for c in (2 * one + l0[one]).tolist():
        if c >> 1 in done:
            continue
        heads.append(len(walk))
        while True:
            walk.append(c)
            nc = nxt[c ^ 1]
            if nc < 0:
                break
            c = nc
        done.add(c >> 1)
    if len(walk) < len(runs):
        # Rings (linked strokes no path reached), entered through their start.
        seen = [False] * S
        for c in walk:
            seen[c >> 1] = True
        for c in (2 * runs).tolist():
            if seen[c >> 1]:
                continue
            heads.append(len(walk))
            while not seen[c >> 1]:
                seen[c >> 1] = True
                walk.append(c)
                c = nxt[c ^ 1]
                if c < 0:
                    break
    walk, heads = np.array(walk, np.int64), np.array(heads, np.int64)
    lens = np.diff(_cat(heads, len(walk)))
    path = np.repeat(np.arange(len(heads)), lens)
    k = np.arange(len(walk)) - heads[path]
    r, back = walk >> 1, (walk & 1).astype(bool)
    # A path goes backwards when more of its strokes are entered at their end (sum of signs < 0).
    flip = (2 * np.add.reduceat(walk & 1, heads) > lens)[path]
    group[r] = np.minimum.reduceat(r, heads)[path]
    rev[r] = back ^ flip
    pos[r] = np.where(flip, lens[path] - 1 - k, k)
    return group, rev, pos


def chain_touching(strokes: Strokes, tol_px: float, angle_deg: float) -> Strokes:
    """Strokes of the same kind whose ends meet (within tol_px, turning by at most angle_deg)
    concatenated into one path (straightest continuation first where three ends meet), so that
    the cuts between carried ids can go where the previous frame had them, wherever the chaining
    happened to stop this frame (hysteresis of id boundaries). Same lines; ids renumbered."""
    S = len(strokes)
    if S < 2 or tol_px <= 0:
        return strokes
    group, rev, pos = _touching_paths(strokes, tol_px, angle_deg)
    if np.array_equal(group, np.arange(S)):
        return strokes
    # Gather the points of each path in order (reversed strokes backwards); a joint point that
    # repeats the previous one is dropped (a bridge, when the ends were apart, is kept).
    # (group, pos) pairs are distinct: one stable sort of group * S + pos is lexsort((pos, group)).
    order = (group * S + pos).argsort(kind="stable")
    offs = strokes.offsets
    start, counts = offs[:-1][order], (offs[1:] - offs[:-1])[order]
    csum = counts.cumsum()
    c0 = csum - counts  # where each stroke's points start in the gathered order
    # Point t of the gathered order: start + (t - c0), or start + count - 1 - (t - c0) reversed.
    t = np.arange(int(csum[-1]))
    ro = rev[order]
    src = np.where(ro.repeat(counts), (start + counts - 1 + c0).repeat(counts) - t, t + (start - c0).repeat(counts))
    g = group[order]
    new_g = np.concatenate(((True,), g[1:] != g[:-1]))
    joint = c0[~new_g]
    P = strokes.points
    drop = joint[row_norm(P.take(src[joint], axis=0) - P.take(src[joint - 1], axis=0)) < 1e-9]
    path = new_g.cumsum() - 1
    first = order[new_g]
    # Points per path: its strokes' points less the dropped joint points.
    n_path = np.bincount(path, weights=counts, minlength=len(first)).astype(np.int64) - np.bincount(
        path[c0.searchsorted(drop, side="right") - 1], minlength=len(first))
    if len(drop):
        keep = np.ones(len(src), bool)
        keep[drop] = False
        src = src[keep]
    out = Strokes(points=P.take(src, axis=0), surface=strokes.surface.take(src, axis=0), face=strokes.face[src],
                  offsets=np.concatenate(((0,), n_path.cumsum())).astype(np.int64),
                  kind=strokes.kind[first], ids=np.arange(len(first), dtype=np.int64), u=None,
                  level=strokes.level[first], level_weight=strokes.level_weight[first], camera=strokes.camera,
                  frame=strokes.frame, period_px=strokes.period_px)
    # Strands that overlapped at their ends (one 0.1 px past where the next begins) turn back at
    # the joint: a hairpin, drawn as a folded ribbon. The joint point goes. (Joints in the
    # output's numbering: the dropped repeats before them shift them down.)
    j = joint - np.searchsorted(drop, joint)
    out = drop_hairpins(out, angle_deg, tol_px, at=np.concatenate([j - 1, j]))
    return _replace(out, u=out.arc_length / out.period_px)


def _concat_groups(pieces: Strokes, g_sorted: np.ndarray) -> Strokes:
    """Join consecutive pieces with the same group id into one stroke (the joint point of the
    second piece is dropped when it repeats the first's last point)."""
    K = len(pieces)
    if K == 0:
        return pieces
    new_g = _cat(True, g_sorted[1:] != g_sorted[:-1])
    if new_g.all():
        return pieces
    keep = np.ones(len(pieces.points), bool)
    cont = np.flatnonzero(~new_g)
    head = pieces.offsets[:-1][cont]
    same = row_norm(pieces.points[head] - pieces.points[head - 1]) < 1e-9
    keep[head[same]] = False
    owner = (np.cumsum(new_g) - 1)[pieces.stroke_of_point][keep]
    counts = np.bincount(owner, minlength=int(new_g.sum()))
    sel = np.flatnonzero(new_g)
    out = _replace(pieces, points=pieces.points[keep], surface=pieces.surface[keep], face=pieces.face[keep],
                  u=np.zeros(int(keep.sum())), offsets=_cat(0, np.cumsum(counts)).astype(np.int64),
                  kind=pieces.kind[sel], ids=np.arange(len(sel), dtype=np.int64), level=pieces.level[sel],
                  level_weight=pieces.level_weight[sel])
    return _replace(out, u=out.arc_length / out.period_px)


def _u_trend(run: np.ndarray, vid: np.ndarray, label: np.ndarray, pos: np.ndarray, u: np.ndarray,
             R: int) -> np.ndarray:
    """(R,) px of every run along which the carried u increases, less the px along which it
    decreases: the votes that carry the run's own id (`label`), in order of their position `pos`
    (px along the new stroke), each step counted by its length with the sign of its du. A step
    across the seam of an old loop (u jumps back by the loop) counts for its length only."""
    keep = np.flatnonzero(vid == label.take(run))
    if len(keep) < 2:
        return np.zeros(R)
    rk, pk = run.take(keep), pos.take(keep)
    pk = pk - pk.min()
    o = np.argsort(rk * (pk.max() + 1.0) + pk, kind="stable")  # by run, then position
    rq = rk.take(o)
    same = rq[1:] == rq[:-1]
    step = np.where(same, np.sign(np.diff(u.take(keep).take(o))) * np.diff(pk.take(o)), 0.0)
    return np.bincount(rq[1:], weights=step, minlength=R)


def _unwrap_loop_votes(prev: Strokes, u: np.ndarray, vid: np.ndarray, s: np.ndarray, group: np.ndarray,
                       w: np.ndarray, P: float, min_loop_spacing_px: float) -> np.ndarray:
    """Votes u (V,) made continuous across the seams of the previous frame's closed strokes.

    A closed stroke's u runs from u0 at its start to u0 + U at its end, the same point (U: its
    length in periods), so its votes jump by U where the old seam lies. A new stroke that runs
    across that point (an open piece of the old loop, or a loop the chaining started elsewhere
    and _turn_loops_to_seams could not turn) would fit u through the jump and fold it backwards.
    Within each vote group (`group`: a new stroke and the carried id `vid`), votes sorted by
    their arc length `s` (px) along the new stroke; a step between two that arc length does not
    explain (du - ds / P, a whole number of U away from 0) is undone, and the group keeps the
    offset of most of its weight `w`, so the votes away from the seam keep their u."""
    if len(u) == 0 or len(prev) == 0:
        return u
    first, last = prev.offsets[:-1], prev.offsets[1:] - 1
    L = prev.lengths
    closed = (L > 0) & (row_norm(prev.points.take(first, axis=0) - prev.points.take(last, axis=0)) < 1e-6)
    if not closed.any():
        return u
    # U per carried id (ids are unique per stroke); only loops of at least 4 vote spacings
    # (`min_loop_spacing_px`), whose jump stands out from the noise of neighbouring votes.
    span = prev.u.take(last) - prev.u.take(first)
    loop = closed & (L >= 4.0 * min_loop_spacing_px)
    ids_sorted = np.argsort(prev.ids, kind="stable")
    k = np.searchsorted(prev.ids, vid, sorter=ids_sorted)
    src = ids_sorted[np.minimum(k, len(ids_sorted) - 1)]
    U = np.where((prev.ids[src] == vid) & loop[src], span[src], 0.0)
    if not (U > 0).any():
        return u
    o = np.lexsort((s, group))
    gq, sq, uq, Uq = group[o], s[o], u[o], U[o]
    same = gq[1:] == gq[:-1]
    step = np.diff(uq) - np.diff(sq) / P
    turns = np.where(same & (Uq[1:] > 0), np.round(step / np.where(Uq[1:] > 0, Uq[1:], 1.0)), 0.0)
    if not turns.any():
        return u
    # Whole loops added so far within the group (a cumulative sum restarted at each group).
    c = _cat(0.0, np.cumsum(turns))
    start = _cat(True, ~same)
    c -= c[np.maximum.accumulate(np.where(start, np.arange(len(c)), 0))]
    # The offset holding most of the group's weight stays (ties: the lower one).
    ci = c.astype(np.int64)
    base = ci.min()
    n_off = int(ci.max() - base) + 1
    ukey, kinv = _unique_inverse(gq.astype(np.int64) * n_off + (ci - base))
    kgroup = ukey // n_off
    keep = _first_max_per_group(kgroup, np.bincount(kinv, weights=w[o]))
    keep_c = np.zeros(int(gq.max()) + 1, np.int64)
    keep_c[kgroup[keep]] = ukey[keep] % n_off + base
    out = u.copy()
    out[o] = uq - (ci - keep_c[gq]) * Uq
    return out


def _segment_sums(idx: np.ndarray, n: int, *weights) -> list[np.ndarray]:
    return [np.bincount(idx, weights=w, minlength=n) for w in weights]


def _unique_inverse(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """np.unique(x, return_inverse=True) of a 1-D integer array (same sort, same results) without
    np.unique's generic wrapping (~10 us a call; the tracker makes three a frame)."""
    perm = x.argsort(kind="stable")  # (any order of equal keys gives the same result; timsort is
    aux = x[perm]                    # cheaper on these partly ordered keys)
    mask = np.empty(len(aux), bool)
    mask[:1] = True
    np.not_equal(aux[1:], aux[:-1], out=mask[1:])
    inv = np.empty(len(aux), np.intp)
    inv[perm] = mask.cumsum() - 1
    return aux[mask], inv


def _first_max_per_group(group: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """For entries sorted by `group` (runs of equal values, non-empty): the index of the first
    entry of each group holding the group's maximum weight (ties: the earliest), in group order.
    The sorted-input form of a (group, -weight, position) lexsort, without the sort."""
    new = _cat(True, group[1:] != group[:-1])
    top = np.maximum.reduceat(weight, np.flatnonzero(new))[np.cumsum(new) - 1]
    cand = np.flatnonzero(weight == top)
    return cand[_cat(True, group[cand][1:] != group[cand][:-1])]


_INT64_MAX = int(np.iinfo(np.int64).max)  # (np.iinfo costs ~5 us a call)


def assign_ids(n_strokes: int, cand_stroke: np.ndarray, cand_id: np.ndarray, cand_w: np.ndarray,
               next_id: int, min_w: float = 0.0) -> tuple[np.ndarray, int]:
    """Greedy one-to-one assignment of previous ids to new strokes by matched length: the
    heaviest (stroke, id) pair first (ties: lower stroke index, then lower id); each id and each
    stroke used once. Strokes left without an id get fresh ids next_id, next_id+1, ... in stroke
    order. Returns (ids (S,), new next_id)."""
    ids = np.full(n_strokes, -1, np.int64)
    keep = cand_w >= max(min_w, 1e-12)
    cs, ci, cw = cand_stroke[keep], cand_id[keep], cand_w[keep]
    # Rank of every pair in the greedy order (heaviest first; ties: lower stroke, lower id).
    order = np.lexsort((ci, cs, -np.round(cw, 9)))
    rank = np.empty(len(order), np.int64)
    rank[order] = np.arange(len(order))
    alive = np.ones(len(cs), bool)
    # Ids as 0..n_ids-1 (so that both sides index flat arrays).
    _, cinv = _unique_inverse(ci)
    n_ids = int(cinv.max()) + 1 if len(cinv) else 0
    used_s = np.zeros(n_strokes, bool)
    used_i = np.zeros(n_ids, bool)
    big = _INT64_MAX
    # Pairs that come first for both their stroke and their id are exactly the ones the greedy
    # pass takes; take them all, drop what they exclude, repeat (a few rounds, all vectorized).
    while alive.any():
        idx = np.flatnonzero(alive)
        ri, si, ii = rank[idx], cs[idx], cinv[idx]
        best_s = np.full(n_strokes, big)
        np.minimum.at(best_s, si, ri)
        best_i = np.full(n_ids, big)
        np.minimum.at(best_i, ii, ri)
        take = idx[(best_s[si] == ri) & (best_i[ii] == ri)]
        ids[cs[take]] = ci[take]
        used_s[cs[take]] = True
        used_i[cinv[take]] = True
        alive &= ~used_s[cs] & ~used_i[cinv]
    fresh = np.flatnonzero(ids < 0)
    ids[fresh] = next_id + np.arange(len(fresh))
    return ids, next_id + len(fresh)


def levels_from_slope(slope_periods_per_px: np.ndarray, period_px: float) -> tuple[np.ndarray, np.ndarray]:
    """Self-similar octave level and blend weight (see module doc) from du/ds per stroke."""
    c = np.log2(np.maximum(np.abs(slope_periods_per_px) * period_px, 1e-6))
    level = np.floor(c)
    return level, 1.0 - (c - level)


def _end_samples(prev: Strokes) -> Samples:
    """Both ends of every stroke of `prev` (starts, then ends) as samples: surface point, tangent
    into the stroke, id (for snap_boundaries)."""
    first, last = prev.offsets[:-1], prev.offsets[1:] - 1
    P, X = prev.points, prev.surface
    e_pt = _cat(first, last)
    e_nb = _cat(np.minimum(first + 1, last), np.maximum(last - 1, first))
    t = P.take(e_nb, axis=0) - P.take(e_pt, axis=0)
    t = t / np.maximum(row_norm(t), 1e-12)[:, None]
    n = len(e_pt)
    return Samples(p=P.take(e_pt, axis=0), X=X.take(e_pt, axis=0), u=np.zeros(n), t=t, ids=_cat(prev.ids, prev.ids),
                   stroke=np.zeros(n, np.int64), s=np.zeros(n), w=np.ones(n))


def snap_boundaries(prev: Strokes, camera, dense: Samples, r_stroke, r_s0, r_s1, r_label, radius_px: float,
                    min_tangent_dot: float, tol_px: float, dense_tree=None, ends_match=None):
    """Move every cut between two runs of one stroke (labels A | B) to where an end of the previous
    frame's stroke A or B projects on the new stroke (both ends found: their mean), when that is
    within `tol_px` of the cut. The end points are matched like the votes (projected with
    `camera`, nearest dense sample within `radius_px` with agreeing tangent, refined along its
    tangent). `ends_match`: (_end_samples(prev), match, projected) when the caller already matched
    them against `dense` (as match_samples(..., k=4, return_projected=True) would).
    Returns new (s0, s1) per run; runs keep at least 1e-3 px."""
    inner = np.flatnonzero((r_stroke[1:] == r_stroke[:-1]) & (r_label[1:] >= 0) & (r_label[:-1] >= 0))
    if len(inner) == 0 or len(prev) == 0 or len(dense) == 0:
        return r_s0, r_s1
    if ends_match is not None:
        ends, m, q = ends_match
    else:
        ends = _end_samples(prev)
        m, q = match_samples(ends, camera, dense, dense_tree, radius_px=radius_px, min_tangent_dot=min_tangent_dot,
                             k=4, return_projected=True)
    hit = np.flatnonzero(m >= 0)
    if len(hit) == 0:
        return r_s0, r_s1
    mh = m[hit]
    es = dense.s[mh] + np.clip(np.einsum("ij,ij->i", q.take(hit, axis=0) - dense.p.take(mh, axis=0), dense.t.take(mh, axis=0)),
                               -0.5 * dense.w[mh], 0.5 * dense.w[mh])
    est, eid = dense.stroke[mh], ends.ids[hit]
    M = int(max(eid.max(), r_label.max())) + 1
    ekey = est.astype(np.int64) * M + eid
    o = np.argsort(ekey, kind="stable")
    ekey, es = ekey[o], es[o]
    cut = r_s1[inner]
    # Both labels of every cut searched at once (keys of the left run, then of the right run).
    n = len(inner)
    sk = r_stroke[inner].astype(np.int64) * M
    key = _cat(sk + r_label[inner], sk + r_label[inner + 1])
    lo = np.searchsorted(ekey, key, "left")
    hi = np.searchsorted(ekey, key, "right")
    cut2 = _cat(cut, cut)
    val, hit2 = [], []
    for k in range(2):  # an old stroke has two ends: at most two candidates per key
        j = lo + k
        ok = j < hi
        jj = np.minimum(j, len(es) - 1)
        ok &= np.abs(es[jj] - cut2) <= tol_px
        val.append(np.where(ok, es[jj], 0.0))
        hit2.append(ok)
    # Summed in the order of one label at a time, candidate 0 then 1 (es >= +0, so the sum from
    # zero starts exactly at the first term).
    acc = ((val[0][:n] + val[1][:n]) + val[0][n:]) + val[1][n:]
    cnt = ((hit2[0][:n].astype(float) + hit2[1][:n]) + hit2[0][n:]) + hit2[1][n:]
    new = np.where(cnt > 0, acc / np.maximum(cnt, 1), cut)
    # Keep both runs non-empty.
    new = np.clip(new, r_s0[inner] + 1e-3, r_s1[inner + 1] - 1e-3)
    new = np.where(r_s0[inner] + 1e-3 < r_s1[inner + 1] - 1e-3, new, cut)
    s0, s1 = r_s0.copy(), r_s1.copy()
    s1[inner] = new
    s0[inner + 1] = new
    return s0, s1


def segment_by_votes(dense: Samples, lengths: np.ndarray, vm: np.ndarray, vid: np.ndarray, w: np.ndarray,
                     min_segment_px: float):
    """Cut the strokes sampled by `dense` (1 px samples, in stroke order; lengths (S,) px) into runs of the same
    carried id. vm (V,) dense sample hit by each vote, vid (V,) its carried id, w (V,) its weight.
    A sample is labelled with the id of most vote weight on it; samples without a vote take the
    label of the nearest voted sample of their stroke; runs shorter than `min_segment_px` (except
    the longest of a stroke) are absorbed by neighbours.
    Returns run (D,) run of each dense sample, and per run: stroke, s0, s1 (px), label (carried
    id, -1 where the stroke had no vote)."""
    D = len(dense)
    label = np.full(D, -1, np.int64)
    if len(vm):
        # The id with the most vote weight on a sample wins it (ties: the lower id). Summed, not
        # the single heaviest vote: where parallel contour pieces run 1-3 px apart, a sample gets
        # votes of its own line and a stray one of the neighbour line.
        M = int(vid.max()) + 1
        key, inv = _unique_inverse(vm.astype(np.int64) * M + vid)
        # Rounded: a sum's last bits depend on the order of the votes, a tie must not.
        kw = np.round(np.bincount(inv.ravel(), weights=w), 9)
        ks, ki = key // M, key % M
        # Per sample the most weight, ties to the lower id: keys come sorted by (sample, id), so
        # that is the first key of its sample holding the sample's maximum (no sort needed; a
        # 3-key lexsort of ~1000 keys cost ~50 us).
        win = _first_max_per_group(ks, kw)
        label[ks[win]] = ki[win]
    idx = np.arange(D)
    stroke, s = dense.stroke, dense.s

    def fill(lab):
        known = lab >= 0
        f = np.maximum.accumulate(np.where(known, idx, -1))
        b = np.minimum.accumulate(np.where(known, idx, D)[::-1])[::-1]
        f0, b0 = np.maximum(f, 0), np.minimum(b, D - 1)  # clamped once, used thrice
        fok = (f >= 0) & (stroke[f0] == stroke)
        bok = (b < D) & (stroke[b0] == stroke)
        df = np.where(fok, s - s[f0], np.inf)
        db = np.where(bok, s[b0] - s, np.inf)
        out = np.where(df <= db, lab[f0], lab[b0])
        return np.where(fok | bok, out, -1)

    def runs(lab):
        start = _cat(True, (lab[1:] != lab[:-1]) | (stroke[1:] != stroke[:-1])) if D else np.zeros(0, bool)
        r = np.cumsum(start) - 1
        return r, np.bincount(r, weights=dense.w) if D else np.zeros(0)

    lab = fill(label)
    done = None  # (r, rl) of the final labels when the loop already has them
    for _ in range(4):
        r, rl = runs(lab)
        if len(rl) == 0:
            break
        rfirst = np.flatnonzero(_cat(True, r[1:] != r[:-1]))
        rs = stroke[rfirst]
        longest = np.zeros(len(rl), bool)
        o = np.lexsort((-rl, rs))
        longest[o[_cat(True, rs[o][1:] != rs[o][:-1])]] = True
        short = (rl < min_segment_px) & ~longest & (lab[rfirst] >= 0)
        if not short.any():
            done = r, rl
            break
        lab = fill(np.where(short[r], -1, lab))
    r, rl = done if done is not None else runs(lab)
    first = np.flatnonzero(_cat(True, r[1:] != r[:-1])) if D else np.zeros(0, np.int64)
    last = _cat(first[1:] - 1, D - 1) if D else np.zeros(0, np.int64)
    rs = stroke[first]
    head = _cat(True, rs[1:] != rs[:-1]) if D else np.zeros(0, bool)
    tail = _cat(rs[1:] != rs[:-1], True) if D else np.zeros(0, bool)
    # Runs meet halfway between their samples; strokes are covered from 0 to their length.
    s0 = np.where(head, 0.0, 0.5 * (s[first] + s[np.maximum(first - 1, 0)]))
    s1 = np.where(tail, lengths[rs], 0.5 * (s[last] + s[np.minimum(last + 1, D - 1)]))
    return r, rs, s0, s1, lab[first]


# --- the tracker -----------------------------------------------------------------------------

class Tracker:
    """Carries the drawing from frame to frame. Call `step` on the frames in order."""

    def __init__(self, options: TrackingOptions | None = None):
        self.options = options or TrackingOptions()
        self.prev: Strokes | None = None
        self.next_id = 0

    def reset(self) -> None:
        self.prev, self.next_id = None, 0

    def step(self, strokes: Strokes) -> Strokes:
        """The tracked version of one frame's strokes (same lines, see the module doc; ids, u,
        level set; strokes may be re-cut, healed and reversed). The camera of `strokes` is required for
        carrying samples from the previous frame."""
        o = self.options
        strokes = _replace(strokes, period_px=o.period_px)
        if o.method == "none":
            out = self._fresh(strokes, renumber=True)
        elif self.prev is None or len(self.prev) == 0 or strokes.camera is None or self.prev.camera is None \
                or len(strokes) == 0:
            out = self._fresh(strokes)
        elif o.method == "kalnins":
            out = self._kalnins(strokes)
        else:
            out = self._seed(strokes)
        self.prev = out
        return out

    # -- no history: fresh ids, u = arc length / P
    def _fresh(self, strokes: Strokes, renumber: bool = False) -> Strokes:
        S = len(strokes)
        if renumber:
            ids = np.arange(S, dtype=np.int64)
        else:
            ids = self.next_id + np.arange(S, dtype=np.int64)
            self.next_id += S
        return _replace(strokes, ids=ids, u=strokes.arc_length / self.options.period_px,
                       level=np.zeros(S), level_weight=np.ones(S))

    # -- Kalnins 2003
    def _kalnins(self, cur: Strokes) -> Strokes:
        o = self.options
        P = o.period_px
        prev = self.prev
        if o.chain_touching:
            cur = chain_touching(cur, o.join_tol_px, o.join_angle_deg)
        votes = resample_strokes(prev, o.vote_spacing_px)
        dense = resample_strokes(cur, o.dense_spacing_px)
        dense_tree = _tree(dense.p) if len(dense) else None  # shared by the vote and end matches
        # The previous strokes' ends (snap_boundaries) are matched in the same query as the votes
        # (each point's match is independent of the others; 2+ rows each, so that the projection
        # takes the same matrix-vector path).
        ends = _end_samples(prev) if o.snap_boundaries and len(prev) and len(dense) else None
        V = len(votes)
        if ends is not None and V >= 2:
            # (only X, t and the length of the samples are used by the match)
            src = Samples(p=np.concatenate([votes.p, ends.p]), X=np.concatenate([votes.X, ends.X]), u=None,
                          t=np.concatenate([votes.t, ends.t]), ids=None, stroke=None, s=None, w=None)
            m, q = match_samples(src, cur.camera, dense, dense_tree, radius_px=o.search_radius_px,
                                 min_tangent_dot=o.min_tangent_dot, k=4, return_projected=True,
                                 piece_distance=True)
            ends_match = (ends, m[V:], q[V:])
            m, q = m[:V], q[:V]
        else:
            m, q = match_samples(votes, cur.camera, dense, dense_tree, radius_px=o.search_radius_px,
                                 min_tangent_dot=o.min_tangent_dot, k=4, return_projected=True,
                                 piece_distance=True)
            ends_match = None
        hit = m >= 0
        vm = m[hit]
        # Where along the new stroke each vote falls, finer than the sample spacing: the
        # projection of the voter on the matched sample's tangent (within its piece).
        # (take(axis=0) for row gathers: fancy indexing of rows is several times slower)
        dtv = dense.t.take(vm, axis=0)
        hi = np.flatnonzero(hit)  # rows by index: a boolean row mask is ~5x slower than take
        ds = np.einsum("ij,ij->i", q.take(hi, axis=0) - dense.p.take(vm, axis=0), dtv)
        ds = np.clip(ds, -0.5 * dense.w[vm], 0.5 * dense.w[vm])
        u = votes.u[hit]
        vid = votes.ids[hit]
        w = votes.w[hit]
        sign = np.sign(np.einsum("ij,ij->i", votes.t.take(hi, axis=0), dtv))
        if o.reverse_votes and len(votes) and len(dense):
            # The other way too (as the metrics do): every new sample looks back for the nearest
            # old sample of the previous frame and takes its u (refined along the old tangent).
            rm, rq = match_samples(dense, prev.camera, votes, _tree(votes.p), radius_px=o.search_radius_px,
                                   min_tangent_dot=o.min_tangent_dot, k=4, return_projected=True,
                                   piece_distance=True)
            rh = np.flatnonzero(rm >= 0)
            src = rm[rh]
            slope = _local_slope(votes)
            vts = votes.t.take(src, axis=0)
            off = np.clip(np.einsum("ij,ij->i", rq.take(rh, axis=0) - votes.p.take(src, axis=0), vts),
                          -0.5 * votes.w[src], 0.5 * votes.w[src])
            vm = _cat(vm, rh)
            ds = _cat(ds, np.zeros(len(rh)))
            u = _cat(u, votes.u[src] + off * slope[src])
            vid = _cat(vid, votes.ids[src])
            w = _cat(w, dense.w[rh])
            sign = _cat(sign, np.sign(np.einsum("ij,ij->i", vts, dense.t.take(rh, axis=0))))
        # Closed strokes (contour loops) start anywhere the chaining happened to start: turn them
        # so that they start at the old seam, where the carried u jumps by a whole loop.
        dense0 = dense
        cur, dense, vm = _turn_loops_to_seams(cur, dense, vm, u, vid, P)
        if dense is not dense0:  # samples reordered: the tree's indices no longer apply
            dense_tree = ends_match = None
        # Segments (Kalnins' brush path segments): each new chain is cut where the id its votes
        # carry changes, so a chain that now runs through two old strokes keeps both ids.
        run, r_stroke, r_s0, r_s1, r_label = segment_by_votes(dense, cur.lengths, vm, vid, w, o.min_segment_px)
        R = len(r_stroke)
        if o.snap_boundaries and R > 1:
            # Hysteresis of id boundaries: a cut between two carried ids goes where the previous
            # frame's end of either stroke projects, not halfway between dense samples.
            r_s0, r_s1 = snap_boundaries(prev, cur.camera, dense, r_stroke, r_s0, r_s1, r_label,
                                         o.search_radius_px, o.min_tangent_dot, 1.5 * o.dense_spacing_px,
                                         dense_tree, ends_match)
        rv = run[vm]
        r_len = r_s1 - r_s0
        s_rel = np.clip(dense.s[vm] + ds - r_s0[rv], 0.0, r_len[rv])
        # Direction: previous strokes have u increasing along them; a segment whose samples run
        # against the voters' tangents is reversed (seed 000 strategy 2, in vote form).
        r_sign = np.bincount(rv, weights=w * sign, minlength=R)
        # ... unless the carried u itself says which way it increases: an edge turning through
        # edge-on flips its image direction, so the tangents disagree while u, on the surface,
        # keeps its order (followed by tangents alone, u ran backwards along the stroke).
        trend = _u_trend(rv, vid, r_label, dense.s[vm] + ds, u, R)
        r_sign = np.where(np.abs(trend) >= o.dense_spacing_px, trend, r_sign)
        # Healing (chain_touching off): segments carrying the same id that now end at the same
        # point (the chaining stopped at a junction it went through in the previous frame) are
        # drawn as one stroke.
        if o.chain_touching:
            # Chains that meet were joined before the cut: nothing is left to heal (measured).
            group, rev, pos = np.arange(R), r_sign < 0, np.zeros(R, np.int64)
        else:
            group, rev, pos = _join_segments(cur, r_stroke, r_s0, r_s1, r_label, r_sign, o.join_tol_px,
                                            o.join_angle_deg)
        order = np.lexsort((pos, group))
        pieces = cut_pieces(cur, r_stroke[order], r_s0[order], r_s1[order], rev[order])
        g_sorted = group[order]
        cur = _concat_groups(pieces, g_sorted)
        S = len(cur)
        # Offset of every run inside its output stroke.
        off_sorted = np.cumsum(r_len[order]) - r_len[order]
        g_start = _cat(True, g_sorted[1:] != g_sorted[:-1]) if R else np.zeros(0, bool)
        base = np.maximum.accumulate(np.where(g_start, off_sorted, 0.0)) if R else np.zeros(0)
        offset = np.zeros(R)
        offset[order] = off_sorted - base
        if o.chain_touching:  # group = arange(R): one output stroke per run, in order
            st = rv
        else:
            st = np.searchsorted(np.unique(group), group)[rv] if R else np.zeros(0, np.int64)
        L = cur.lengths
        s = offset[rv] + np.where(rev[rv], r_len[rv] - s_rel, s_rel)
        s = np.clip(s, 0, L[st])
        # Vote groups: (stroke, carried id).
        if len(st):
            M = int(vid.max()) + 1
            key = st.astype(np.int64) * M + vid  # (stroke, id) as one integer
            ukey, ginv = _unique_inverse(key)
            gkeys = np.empty((len(ukey), 2), np.int64)
            np.floor_divide(ukey, M, out=gkeys[:, 0])
            np.remainder(ukey, M, out=gkeys[:, 1])
            gw = np.bincount(ginv, weights=w)
        else:
            gkeys, ginv, gw = np.zeros((0, 2), np.int64), np.zeros(0, np.int64), np.zeros(0)
        if len(st):
            u = _unwrap_loop_votes(prev, u, vid, s, ginv, w, P, o.vote_spacing_px)
        # Primary group per stroke: most matched length, ties to the lower id. gkeys come sorted
        # by (stroke, id): the first group of a stroke holding the stroke's maximum (no sort).
        primary = np.zeros(len(gw), bool)
        if len(gw):
            primary[_first_max_per_group(gkeys[:, 0], gw)] = True
        b0 = 1.0 / P
        lam = o.stretch_weight * P * P * L  # see TrackingOptions.stretch_weight

        def fit(mask):
            w_ = w * mask
            S0, S1, S2, T0, T1 = _segment_sums(st, S, w_, w_ * s, w_ * s * s, w_ * u, w_ * s * u)
            A11, A12, A22 = S0, S1, S2 + lam
            R1, R2 = T0, T1 + lam * b0
            det = A11 * A22 - A12 * A12
            ok = (S0 > 0) & (det > 1e-12 * np.maximum(A11 * A22, 1e-300))
            a = np.where(ok, (R1 * A22 - A12 * R2) / np.where(ok, det, 1), 0.0)
            b = np.where(ok, (A11 * R2 - A12 * R1) / np.where(ok, det, 1), b0)
            return a, b, ok

        if len(st):
            a, b, ok = fit(primary[ginv].astype(float))
            # Other groups join the primary one shifted by whole periods (periodic texture).
            res = u - (a[st] + b[st] * s)
            shift = np.round(np.bincount(ginv, weights=w * res, minlength=len(gw)) / np.maximum(gw, 1e-12))
            shift[primary] = 0
            u = u - shift[ginv]
            a, b, ok = fit(np.ones(len(st)))
            inlier = np.ones(len(st))
            if o.knot_spacing_px > 0:
                # Piecewise-linear u (knots every ~knot_spacing_px): follows uneven stretch
                # (perspective, edges of a loop growing at different rates) without sliding.
                pw = PiecewiseU(L, o.knot_spacing_px)
                for _ in range(2):
                    knots = pw.fit(st, s, u, w * inlier, a, b, b0, o.stretch_weight * P * P, o.bend_weight)
                    inlier = (np.abs(u - pw.eval(knots, st, s)) * P <= o.outlier_px).astype(float)
            else:
                inlier = (np.abs(u - (a[st] + b[st] * s)) * P <= o.outlier_px).astype(float)
                a2, b2, ok2 = fit(inlier)
                a, b, ok = np.where(ok2, a2, a), np.where(ok2, b2, b), ok | ok2
            gw_in = np.bincount(ginv, weights=w * inlier, minlength=len(gw))
            cand_s, cand_i, cand_w = gkeys[:, 0], gkeys[:, 1], gw_in
        else:
            a, b, ok = np.zeros(S), np.full(S, b0), np.zeros(S, bool)
            cand_s = cand_i = np.zeros(0, np.int64)
            cand_w = np.zeros(0)
        b = np.where(ok, np.maximum(b, 1e-3 * b0), b0)  # never fold the texture back
        sop = cur.stroke_of_point
        if len(st) and o.knot_spacing_px > 0:
            # u is interpolated linearly between points downstream: give it the knots as points.
            cur = insert_points(cur, pw.inner_knot_stroke(), pw.inner_knot_s())
            sop = cur.stroke_of_point
            u_new = pw.eval(knots, sop, cur.arc_length)
            b = np.where((L > 0) & ok, (knots[pw.base[1:] - 1] - knots[pw.base[:-1]]) / np.maximum(L, 1e-9), b)
        else:
            u_new = a[sop] + b[sop] * cur.arc_length
        ids, self.next_id = assign_ids(S, cand_s, cand_i, cand_w, self.next_id, o.min_id_px)
        level, weight = levels_from_slope(b, P)
        out = _replace(cur, ids=ids, u=u_new, level=level, level_weight=weight)
        if not o.chain_touching:  # (chain_touching drops them where it joins)
            # Healed strands that overlapped at their ends turn back there by a fraction of a pixel.
            out = drop_hairpins(out, o.join_angle_deg, o.join_tol_px)
        return out

    # -- seed 000 strategies 1-5
    def _seed(self, cur: Strokes) -> Strokes:
        o = self.options
        P = o.period_px
        prev = self.prev
        S = len(cur)
        L = cur.lengths
        carried = np.flatnonzero(prev.lengths >= o.min_carry_px)  # strategy 5
        dense = resample_strokes(cur, 1.0)
        claims: list[list[tuple[float, float]]] = [[] for _ in range(S)]
        pieces = []  # (stroke, s0, s1, reverse, id)
        if len(carried) and len(dense):
            from scipy.spatial import cKDTree

            st0 = prev.offsets[:-1][carried]
            X0 = prev.surface[st0]
            d0 = prev.points[np.minimum(st0 + 1, prev.offsets[1:][carried] - 1)] - prev.points[st0]
            d0 = d0 / np.maximum(row_norm(d0), 1e-12)[:, None]
            q, z = cur.camera.project(X0)
            # A start now behind the camera projects mirrored to a finite pixel: it claims nothing.
            behind = ~((z > 0) | cur.camera.is_ortho)
            q = np.where(behind[:, None], np.nan, q)
            tree = cKDTree(dense.p)
            kk = min(16, len(dense))
            dist, idx = tree.query(np.nan_to_num(q, nan=-1e9, posinf=-1e9, neginf=-1e9), k=kk,
                                   distance_upper_bound=o.seed_search_px)
            dist, idx = dist.reshape(-1, kk), idx.reshape(-1, kk)
            valid = np.isfinite(dist)
            safe = np.where(valid, idx, 0)
            cosf = np.einsum("ikj,ij->ik", dense.t[safe], d0)
            # Strategy 2: weight = d + penalty * angle, for both directions along the stroke.
            wf = dist + o.seed_angle_penalty_px * np.arccos(np.clip(cosf, -1, 1))
            wb = dist + o.seed_angle_penalty_px * np.arccos(np.clip(-cosf, -1, 1))
            backward = wb < wf
            wgt = np.where(valid, np.minimum(wf, wb), np.inf)
            best = np.argmin(wgt, axis=1)
            r = np.arange(len(carried))
            found = np.isfinite(wgt[r, best])
            # Longest previous strokes choose first (fewer, longer strokes).
            order = np.lexsort((carried, -prev.lengths[carried]))
            for k in order.tolist():  # one iteration per carried stroke
                if not found[k]:
                    continue
                j = safe[k, best[k]]
                sk, s_start, back = int(dense.stroke[j]), float(dense.s[j]), bool(backward[k, best[k]])
                grow = prev.lengths[carried[k]] + o.max_growth_px  # strategy 3
                lo, hi = (max(0.0, s_start - grow), s_start) if back else (s_start, min(L[sk], s_start + grow))
                # Clip against pieces already claimed on this stroke.
                blocked = False
                for c0, c1 in claims[sk]:
                    if c0 <= s_start <= c1:
                        blocked = True
                        break
                    if back and c1 <= s_start:
                        lo = max(lo, c1)
                    if not back and c0 >= s_start:
                        hi = min(hi, c0)
                if blocked or hi - lo < 1e-6:
                    continue
                claims[sk].append((lo, hi))
                pieces.append((sk, lo, hi, back, int(prev.ids[carried[k]])))
        # Strategy 4: what is left of each stroke, between claimed pieces and the stroke ends.
        for sk in range(S):
            t, n_before = 0.0, len(pieces)
            for c0, c1 in sorted(claims[sk]):
                if c0 - t > 1e-6:
                    pieces.append((sk, t, c0, False, -1))
                t = max(t, c1)
            if L[sk] - t > 1e-6 or (not claims[sk] and len(pieces) == n_before):
                pieces.append((sk, t, float(L[sk]), False, -1))
        pieces.sort(key=lambda p: (p[0], p[1]))
        arr = np.array([(p[0], p[1], p[2], p[3], p[4]) for p in pieces], float).reshape(-1, 5)
        out = cut_pieces(cur, arr[:, 0].astype(np.int64), arr[:, 1], arr[:, 2], arr[:, 3] > 0)
        ids = arr[:, 4].astype(np.int64)
        fresh = np.flatnonzero(ids < 0)
        ids[fresh] = self.next_id + np.arange(len(fresh))
        self.next_id += len(fresh)
        K = len(out)
        return _replace(out, ids=ids, u=out.arc_length / P, level=np.zeros(K), level_weight=np.ones(K))


def track_frames(frames: list[Strokes], options: TrackingOptions | None = None) -> list[Strokes]:
    """Track a list of frames in order (convenience for tests and benchmarks)."""
    tr = Tracker(options)
    return [tr.step(f) for f in frames]
