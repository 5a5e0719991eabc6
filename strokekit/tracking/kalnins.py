"""Kalnins et al. 2003 tracking: samples of the previous frame's strokes vote for ids and u on
the new strokes; u is fitted per stroke as a piecewise-linear function of arc length (see the
tracking package's tracker module for the whole design)."""

from __future__ import annotations

import numpy as np

from strokekit.lines.strokeops import cut_pieces, drop_hairpins, join_arrays, query_tree
from strokekit.model import Strokes
from strokekit.sampling import Samples, match_samples, resample_strokes
from strokekit.tracking.joins import chain_touching, concat_groups, insert_points, join_segments, turn_loops_to_seams
from strokekit.tracking.options import TrackingOptions
from strokekit.tracking.ufit import PiecewiseU, levels_from_slope, local_slope
from strokekit.tracking.votes import (
    assign_ids,
    end_samples,
    first_max_per_group,
    segment_by_votes,
    segment_sums,
    snap_boundaries,
    u_trend,
    unique_inverse,
    unwrap_loop_votes,
)


class Kalnins:
    """The default method (`--coherence kalnins`)."""

    name = "kalnins"

    def track(self, prev: Strokes, cur: Strokes, o: TrackingOptions, next_id: int) -> tuple[Strokes, int]:
        """The tracked `cur` (ids, u, level) given the previous frame's tracked strokes, and the
        next unused id."""
        return kalnins_step(prev, cur, o, next_id)


def kalnins_step(prev: Strokes, cur: Strokes, o: TrackingOptions, next_id: int) -> tuple[Strokes, int]:
    P = cur.period_px
    if o.chain_touching:
        cur = chain_touching(cur, o.join_tol_px, o.join_angle_deg)
    votes = resample_strokes(prev, o.vote_spacing_px)
    dense = resample_strokes(cur, o.dense_spacing_px)
    dense_tree = query_tree(dense.p) if len(dense) else None  # shared by the vote and end matches
    # The previous strokes' ends (snap_boundaries) are matched in the same query as the votes
    # (each point's match is independent of the others; 2+ rows each, so that the projection
    # takes the same matrix-vector path).
    ends = end_samples(prev) if o.snap_boundaries and len(prev) and len(dense) else None
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
        rm, rq = match_samples(dense, prev.camera, votes, query_tree(votes.p), radius_px=o.search_radius_px,
                               min_tangent_dot=o.min_tangent_dot, k=4, return_projected=True,
                               piece_distance=True)
        rh = np.flatnonzero(rm >= 0)
        src = rm[rh]
        slope = local_slope(votes)
        vts = votes.t.take(src, axis=0)
        off = np.clip(np.einsum("ij,ij->i", rq.take(rh, axis=0) - votes.p.take(src, axis=0), vts),
                      -0.5 * votes.w[src], 0.5 * votes.w[src])
        vm = join_arrays(vm, rh)
        ds = join_arrays(ds, np.zeros(len(rh)))
        u = join_arrays(u, votes.u[src] + off * slope[src])
        vid = join_arrays(vid, votes.ids[src])
        w = join_arrays(w, dense.w[rh])
        sign = join_arrays(sign, np.sign(np.einsum("ij,ij->i", vts, dense.t.take(rh, axis=0))))
    # Closed strokes (contour loops) start anywhere the chaining happened to start: turn them
    # so that they start at the old seam, where the carried u jumps by a whole loop.
    dense0 = dense
    cur, dense, vm = turn_loops_to_seams(cur, dense, vm, u, vid, P)
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
    trend = u_trend(rv, vid, r_label, dense.s[vm] + ds, u, R)
    r_sign = np.where(np.abs(trend) >= o.dense_spacing_px, trend, r_sign)
    # Healing (chain_touching off): segments carrying the same id that now end at the same
    # point (the chaining stopped at a junction it went through in the previous frame) are
    # drawn as one stroke.
    if o.chain_touching:
        # Chains that meet were joined before the cut: nothing is left to heal (measured).
        group, rev, pos = np.arange(R), r_sign < 0, np.zeros(R, np.int64)
    else:
        group, rev, pos = join_segments(cur, r_stroke, r_s0, r_s1, r_label, r_sign, o.join_tol_px,
                                        o.join_angle_deg)
    order = np.lexsort((pos, group))
    pieces = cut_pieces(cur, r_stroke[order], r_s0[order], r_s1[order], rev[order])
    g_sorted = group[order]
    cur = concat_groups(pieces, g_sorted)
    S = len(cur)
    # Offset of every run inside its output stroke.
    off_sorted = np.cumsum(r_len[order]) - r_len[order]
    g_start = join_arrays(True, g_sorted[1:] != g_sorted[:-1]) if R else np.zeros(0, bool)
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
    cur, u_new, b, (cand_s, cand_i, cand_w) = fit_u(prev, cur, st, s, u, vid, w, o)
    ids, next_id = assign_ids(S, cand_s, cand_i, cand_w, next_id, o.min_id_px)
    level, weight = levels_from_slope(b, P)
    out = cur.replace(ids=ids, u=u_new, level=level, level_weight=weight)
    if not o.chain_touching:  # (chain_touching drops them where it joins)
        # Healed strands that overlapped at their ends turn back there by a fraction of a pixel.
        out = drop_hairpins(out, o.join_angle_deg, o.join_tol_px)
    return out, next_id


def fit_u(prev: Strokes, cur: Strokes, st: np.ndarray, s: np.ndarray, u: np.ndarray, vid: np.ndarray,
          w: np.ndarray, o: TrackingOptions, compiled=None):
    """u along the strokes `cur` fitted to the votes carried from `prev`: vote k lands on stroke
    st[k] at arc length s[k] (px) with u[k] (periods), carried id vid[k] and weight w[k]. Per
    stroke the votes of its primary id (most weight) set the fit, those of other ids join it
    shifted by whole periods; u is piecewise linear (knots every o.knot_spacing_px, inserted as
    points) or linear, outliers (o.outlier_px) dropped and the fit redone. Returns (cur with the
    knots inserted, u at its points, the slope du/ds per stroke, and the vote groups (stroke,
    id, inlier weight) that assign_ids takes). `compiled`: other implementations of the linear fit
    (`line_fit`), of the piecewise fit's sums (`band_terms`, see PiecewiseU.fit) and of
    insert_points (`insert_points`): the brush path stage's compiled ones."""
    P = cur.period_px
    S = len(cur)
    L = cur.lengths
    # Vote groups: (stroke, carried id).
    if len(st):
        M = int(vid.max()) + 1
        key = st.astype(np.int64) * M + vid  # (stroke, id) as one integer
        ukey, ginv = unique_inverse(key)
        gkeys = np.empty((len(ukey), 2), np.int64)
        np.floor_divide(ukey, M, out=gkeys[:, 0])
        np.remainder(ukey, M, out=gkeys[:, 1])
        gw = np.bincount(ginv, weights=w)
    else:
        gkeys, ginv, gw = np.zeros((0, 2), np.int64), np.zeros(0, np.int64), np.zeros(0)
    if len(st):
        u = unwrap_loop_votes(prev, u, vid, s, ginv, w, P, o.vote_spacing_px)
    # Primary group per stroke: most matched length, ties to the lower id. gkeys come sorted
    # by (stroke, id): the first group of a stroke holding the stroke's maximum (no sort).
    primary = np.zeros(len(gw), bool)
    if len(gw):
        primary[first_max_per_group(gkeys[:, 0], gw)] = True
    b0 = 1.0 / P
    lam = o.stretch_weight * P * P * L  # see TrackingOptions.stretch_weight

    def fit(mask):
        if compiled is not None:
            return compiled.line_fit(st, s, u, w, mask, lam, b0)
        w_ = w * mask
        S0, S1, S2, T0, T1 = segment_sums(st, S, w_, w_ * s, w_ * s * s, w_ * u, w_ * s * u)
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
                knots = pw.fit(st, s, u, w * inlier, a, b, b0, o.stretch_weight * P * P, o.bend_weight,
                               None if compiled is None else compiled.band_terms)
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
        cur = (insert_points if compiled is None else compiled.insert_points)(cur, pw.inner_knot_stroke(),
                                                                              pw.inner_knot_s())
        sop = cur.stroke_of_point
        u_new = pw.eval(knots, sop, cur.arc_length)
        b = np.where((L > 0) & ok, (knots[pw.base[1:] - 1] - knots[pw.base[:-1]]) / np.maximum(L, 1e-9), b)
    else:
        u_new = a[sop] + b[sop] * cur.arc_length
    return cur, u_new, b, (cand_s, cand_i, cand_w)
