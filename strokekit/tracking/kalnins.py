"""Kalnins et al. 2003 tracking: samples of the previous frame's strokes vote for ids and u on
the new strokes; u is fitted per stroke as a piecewise-linear function of arc length (see the
tracking package's tracker module for the whole design)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from strokekit.lines.strokeops import join_arrays, query_tree
from strokekit.model import Strokes, carry_points
from strokekit.sampling import Samples
from strokekit.tracking.grid import match_pieces
from strokekit.tracking.joins import chain_touching, concat_groups, join_segments, turn_loops_to_seams
from strokekit.tracking.options import TrackingOptions
from strokekit.tracking.strokeops import cut_pieces, drop_hairpins, resample
from strokekit.tracking.ufit import fit_u, levels_from_slope, local_slope
from strokekit.tracking.votes import assign_ids, end_samples, segment_by_votes, snap_boundaries, u_trend


class Kalnins:
    """The default method (`--coherence kalnins`)."""

    name = "kalnins"

    def track(self, prev: Strokes, cur: Strokes, o: TrackingOptions, next_id: int) -> tuple[Strokes, int]:
        """The tracked `cur` (ids, u, level) given the previous frame's tracked strokes, and the
        next unused id."""
        return kalnins_step(prev, cur, o, next_id)


def kalnins_step(prev: Strokes, cur: Strokes, o: TrackingOptions, next_id: int) -> tuple[Strokes, int]:
    P = cur.period_px
    pose = cur.pose
    if o.chain_touching:
        cur = chain_touching(cur, o.join_tol_px, o.join_angle_deg)
    # In a moving scene the previous frame's surface points move with their objects to where they
    # are now before they are projected with the new camera (and the new ones back, for the
    # reverse votes): the correspondence the metrics use.
    moving = prev.pose is not None or pose is not None
    carried = carry_points(prev.surface, prev.face, prev.pose, pose) if moving else None
    votes = resample(prev, o.vote_spacing_px, surface=carried)
    if moving:
        prev = prev.replace(surface=carried)  # (its ends, where snap_boundaries projects them)
    dense = resample(cur, o.dense_spacing_px)
    # The previous strokes' ends (snap_boundaries) are matched in the same query as the votes
    # (each point's match is independent of the others; 2+ rows each, so that the projection
    # takes the same matrix-vector path).
    ends = end_samples(prev) if o.snap_boundaries and len(prev) and len(dense) else None
    V = len(votes)
    if ends is not None and V >= 2:
        # (only X, t and the length of the samples are used by the match)
        src = Samples(p=np.concatenate([votes.p, ends.p]), X=np.concatenate([votes.X, ends.X]), u=None,
                      t=np.concatenate([votes.t, ends.t]), ids=None, stroke=None, s=None, w=None)
        m, q = match_pieces(src, cur.camera, dense, o.search_radius_px, o.min_tangent_dot, k=4)
        ends_match = (ends, m[V:], q[V:])
        m, q = m[:V], q[:V]
    else:
        m, q = match_pieces(votes, cur.camera, dense, o.search_radius_px, o.min_tangent_dot, k=4)
        ends_match = None
    hit = m >= 0
    vm = m[hit]
    # Where along the new stroke each vote falls, finer than the sample spacing: the
    # projection of the voter on the matched sample's tangent (within its piece).
    # (take(axis=0) for row gathers: fancy indexing of rows is slower)
    dtv = dense.t.take(vm, axis=0)
    hi = np.flatnonzero(hit)  # rows by index: a boolean row mask is slower than take
    ds = np.einsum("ij,ij->i", q.take(hi, axis=0) - dense.p.take(vm, axis=0), dtv)
    ds = np.clip(ds, -0.5 * dense.w[vm], 0.5 * dense.w[vm])
    u = votes.u[hit]
    vid = votes.ids[hit]
    w = votes.w[hit]
    sign = np.sign(np.einsum("ij,ij->i", votes.t.take(hi, axis=0), dtv))
    if o.reverse_votes and len(votes) and len(dense):
        # The other way too (as the metrics do): every new sample looks back for the nearest
        # old sample of the previous frame and takes its u (refined along the old tangent).
        back = dense
        if moving:
            back = replace(dense, X=resample(cur, o.dense_spacing_px,
                                             surface=carry_points(cur.surface, cur.face, pose, prev.pose)).X)
        rm, rq = match_pieces(back, prev.camera, votes, o.search_radius_px, o.min_tangent_dot, k=4)
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
    if dense is not dense0:  # samples reordered: the ends' matches no longer apply
        ends_match = None
    # Segments (Kalnins' brush path segments): each new chain is cut where the id its votes
    # carry changes, so a chain that now runs through two old strokes keeps both ids.
    run, r_stroke, r_s0, r_s1, r_label = segment_by_votes(dense, cur.lengths, vm, vid, w, o.min_segment_px)
    R = len(r_stroke)
    if o.snap_boundaries and R > 1:
        # Hysteresis of id boundaries: a cut between two carried ids goes where the previous
        # frame's end of either stroke projects, not halfway between dense samples.
        # (the ends matched again where the samples were reordered: against the tree of the new
        # samples where they were not, as the votes' match would have been)
        dense_tree = query_tree(dense.p) if ends_match is None and dense is dense0 and len(dense) else None
        r_s0, r_s1 = snap_boundaries(prev, cur.camera, dense, r_stroke, r_s0, r_s1, r_label,
                                     o.search_radius_px, o.min_tangent_dot, 1.5 * o.dense_spacing_px,
                                     dense_tree, ends_match)
    rv = run[vm]
    r_len = r_s1 - r_s0
    s_rel = np.clip(dense.s[vm] + ds - r_s0[rv], 0.0, r_len[rv])
    # Direction: previous strokes have u increasing along them; a segment whose samples run
    # against the voters' tangents is reversed (the seed method's preferred direction, in vote form).
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
        # Chains that meet were joined before the cut: nothing is left to heal.
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
