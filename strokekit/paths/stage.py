"""One frame's brush paths from its exact lines and the previous frame's paths (`brush_step`).

The steps, all vectorized over the frame's samples:

1. The lines are sampled every `sample_px` (position, tangent, surface point).
2. Votes (with history): the previous paths, sampled every `vote_spacing_px`, are advected with
   the surface: every line sample (projected with the previous camera) looks for the nearest
   previous path sample within `search_radius_px` whose tangent agrees and whose kind is
   compatible (the correspondence the metrics use). A vote carries the path's id and its u (paths.votes).
3. Labels: each line sample takes the id of most vote weight; samples no vote reached take the
   label of the nearest labelled sample of their line (a path grows along its line); runs of one
   label shorter than `min_run_px` go to their neighbours (tracking.votes.segment_by_votes).
4. Cover: a piece of contour line running beside a line of higher rank within `cover_px` is
   covered by it, not drawn (the shingles of a mesh contour share one path; paths.cover).
5. Pieces (the uncovered runs, cut where their line turns past `join_angle_deg`) are joined end
   to end into paths (paths.pieces): pieces of one label within `join_px`, a piece no path claims
   to a path or to another such piece within `new_join_px`, turning at most `join_angle_deg`;
   links within one label first, of those the links that continue the previous path first, the
   cheapest first (gap + 10 px per radian of turn), then of the longest piece; two paths never
   join. A bridge longer than 2 px is only made where every point of it lies within 1 px of a
   line (the paths invent nothing). A path whose ends meet is closed into a loop. Pieces of a
   path shorter than `merge_px` (this frame and the last) join like unclaimed pieces, and so do
   those of an orphan: a path of one label that is not its longest (that one gets the id), at
   most `orphan_px` long (its votes came from a path that runs elsewhere). A path whose two
   ends meet ends of longer paths of one other label lies within that label's line (a strand
   of shingles the contour moved onto, the part a gap cut off a loop): it takes that label and
   joins them (paths.pieces.interior_paths).
6. Ids: each previous id goes to one path, the heaviest claims first: the votes of that id a
   path holds, those of the other kind classes too, and a quarter of the length of its pieces of
   that label; the other paths get fresh ids. Each path is turned so that its carried u
   increases along it, a closed path to start at its old seam, and u is fitted to the votes as
   the Kalnins tracker does (tracking.ufit.fit_u), with its self-similar level. A new path
   shorter than `hold_px` lying beside the drawn ones is held back one frame (`held_back`): a
   piece that shows for a frame costs no id.
"""

from __future__ import annotations

import numpy as np

from strokekit.model import N_KINDS, BrushPaths, Strokes, row_norm
from strokekit.numba_cache import keyboard_interrupts
from strokekit.paths.cover import HOLD_RADIUS_PX, covered_runs, held_back, on_drawing, run_cover
from strokekit.paths.heal import bridge_splits, heal_paths, touching_pairs
from strokekit.paths.options import PathOptions
from strokekit.paths.pieces import (
    HAIRPIN_PX,
    LinkPairs,
    close_loops,
    concat,
    interior_paths,
    line_pieces,
    link_labels,
    link_pieces,
    one_label_per_path,
    reverse,
    seams,
)
from strokekit.paths.votes import EndVotes, Votes, carried_votes, heal_jumps, hidden_as_one, landing, path_ids
from strokekit.sampling import Samples
from strokekit.tracking.grid import SampleGrid
from strokekit.tracking.joins import rotate_closed
from strokekit.tracking.strokeops import cut_pieces, resample, select
from strokekit.tracking.ufit import fit_u, levels_from_slope
from strokekit.tracking.votes import is_in, segment_by_votes, u_trend, unique_inverse


def brush_step(prev: Strokes | None, lines: Strokes, o: PathOptions, next_id: int,
               touched: np.ndarray | None = None) -> tuple[BrushPaths, int]:
    """The brush paths of a frame's `lines` given the previous frame's paths (None: no history),
    and the next unused id (see module doc); `touched`: the pairs of ids whose paths met end to
    end in the previous frame (paths.heal.touching_pairs)."""
    if len(lines) == 0 or len(lines.points) == 0:
        return _empty(lines), next_id
    first_fresh = next_id
    D = resample(lines, o.sample_px)
    history = prev is not None and len(prev) > 0 and lines.camera is not None and prev.camera is not None
    votes = carried_votes(prev, lines, D, o) if history else Votes.none()
    # 3. Labels: runs of one carried id along the lines.
    run, r_line, r_s0, r_s1, r_label = segment_by_votes(D, lines.lengths, votes.m, votes.vid, votes.w, o.min_run_px)
    # 4. Cover. (One grid of the line samples: for the cover, the bridges and held_back.)
    line_grid = SampleGrid(D.p, HOLD_RADIUS_PX)
    drawn_kind = hidden_as_one(lines.kind)
    cover = run_cover(D, drawn_kind, run, r_line, r_label, r_s1 - r_s0, o.cover_px, line_grid)
    # 5. Pieces, joined into paths.
    p_run, p_s0, p_s1, smp_piece = line_pieces(lines, D, cover, run, r_line, r_s0, r_s1, o.join_angle_deg)
    if len(p_run) == 0:
        return _empty(lines), next_id
    p_line, p_label = r_line[p_run], r_label[p_run]
    link_label = link_labels(p_label, p_s0, p_s1, prev if history else None, o.merge_px)
    pieces = cut_pieces(lines.replace(kind=drawn_kind), p_line, p_s0, p_s1)
    plen = p_s1 - p_s0
    ok, vk, s_in = landing(votes.m, cover, smp_piece, D, p_s0, p_s1)
    vu, vid, vw = votes.u[ok], votes.vid[ok], votes.w[ok]
    pairs = LinkPairs.of(pieces, max(o.join_px, o.new_join_px), o.join_angle_deg)

    def link(link_label):  # (the ends' votes follow the labels)
        ends = EndVotes.of(vk, s_in, vu, vid, link_label, plen, lines.period_px) if len(votes) else None
        group, rev, pos = link_pieces(pieces, o.join_px, o.join_angle_deg, link_label, o.new_join_px,
                                      lambda pa, pb: on_drawing(line_grid, pa, pb, D=D), free_px=2.0, ends=ends,
                                      pairs=pairs)
        return one_label_per_path(group, pos, link_label), rev, pos

    group, rev, pos = link(link_label)
    orphan = orphans(group, link_label, plen, o.orphan_px)
    if orphan.any():  # (linked again as unclaimed pieces: an orphan joins the path it touches)
        link_label = np.where(orphan, -1, link_label)
        group, rev, pos = link(link_label)
    inner = interior_paths(group, rev, pos, link_label, plen, pairs)
    if (inner >= 0).any():  # (linked again: a path within another's line takes its label)
        link_label = np.where(inner >= 0, inner, link_label)
        group, rev, pos = link(link_label)
    paths, path_of, offset = concat(pieces, group, rev, pos, o.join_angle_deg, HAIRPIN_PX)
    paths = close_loops(paths, o.join_px, o.join_angle_deg, line_grid, D)
    # A hidden path's level: the fewest surfaces that hide any piece of it.
    occ_level = np.full(len(paths), np.iinfo(np.int64).max)
    np.minimum.at(occ_level, path_of, lines.kind[p_line] // N_KINDS)
    paths = paths.replace(kind=paths.kind % N_KINDS + N_KINDS * occ_level)
    # 6. Ids, then u.
    known = np.unique(prev.ids) if history else np.zeros(0, np.int64)
    ids, next_id = path_ids(len(paths), path_of, p_label, plen, votes, vk, vid, vw, cover, smp_piece, D, p_s0, p_s1,
                            known, next_id)
    paths = paths.replace(ids=ids)
    covers = (lines, pieces, p_line, p_s0, p_s1, path_of, D, cover, smp_piece)
    if len(votes) == 0:
        return _finish(paths.replace(u=paths.arc_length / lines.period_px), *covers), next_id
    # Where every vote lands along its path.
    vst = path_of[vk]
    vs = np.clip(offset[vk] + np.where(rev[vk], plen[vk] - s_in, s_in), 0.0, paths.lengths[vst])
    vsign = votes.sign[ok] * np.where(rev[vk], -1.0, 1.0)
    paths = _carried_u(prev, paths, vst, vs, vu, vid, vw, vsign, o)
    owner = np.where(smp_piece >= 0, path_of[np.maximum(smp_piece, 0)], -1)
    hold = held_back(paths, first_fresh, o, D.p, owner, line_grid)
    fresh = ~is_in(paths.ids, known)
    parent = _voted_id(vst, vid, vw, fresh) if o.bridge_px > 0 and fresh.any() else None
    if parent is not None and (parent >= 0).any():  # (only a fresh path with a parent bridges)
        paths, new_of = bridge_splits(paths, known, parent, o.bridge_px, hold,
                                      lambda pa, pb: on_drawing(line_grid, pa, pb, D=D))
        hold = np.bincount(new_of[hold], minlength=len(paths)) > 0
        path_of = new_of[path_of]
        covers = (lines, pieces, p_line, p_s0, p_s1, path_of, D, cover, smp_piece)
    if o.heal_px > 0:
        paths, new_of = heal_paths(paths, known, np.zeros(0, np.int64) if touched is None else touched, o.heal_px,
                                   hold)
        hold = np.bincount(new_of[hold], minlength=len(paths)) > 0
        path_of = new_of[path_of]
        covers = (lines, pieces, p_line, p_s0, p_s1, path_of, D, cover, smp_piece)
    return _finish(paths, *covers, hold), next_id


def _heaviest_pairs(a: np.ndarray, b: np.ndarray, w: np.ndarray):
    """The distinct pairs (a, b) of non-negative ints below 2**31, their summed weights `w`, and
    for each a the pair of most weight (ties: the lowest b): (pa, pb, weight, heaviest, inv), inv
    the pair of each input."""
    key, inv = unique_inverse((np.asarray(a, np.int64) << 32) | np.asarray(b, np.int64))
    wt = np.bincount(inv, weights=w)
    pa, pb = key >> 32, key & 0xFFFFFFFF
    o = np.lexsort((-wt, pa))
    heaviest = np.zeros(len(key), bool)
    heaviest[o[np.r_[True, pa[o][1:] != pa[o][:-1]]]] = True
    return pa, pb, wt, heaviest, inv


def orphans(group: np.ndarray, label: np.ndarray, plen: np.ndarray, max_px: float) -> np.ndarray:
    """(K,) the pieces of the orphan paths (PathOptions.orphan_px): of the paths (`group` (K,) of
    pieces, one label each, `plen` their lengths) holding one label, every one but the longest
    (it is the one that gets the label's id), where it is at most `max_px` long."""
    k = np.flatnonzero(label >= 0)
    out = np.zeros(len(group), bool)
    if len(k) == 0 or max_px <= 0:
        return out
    *_, longest, inv = _heaviest_pairs(label[k], group[k], plen[k])
    path_px = np.bincount(group, weights=plen, minlength=len(group))
    out[k] = ~longest[inv] & (path_px[group[k]] <= max_px)
    return out


def _voted_id(vst: np.ndarray, vid: np.ndarray, vw: np.ndarray, which: np.ndarray) -> np.ndarray:
    """(S,) the id of most vote weight on each path where `which` (S,), -1 elsewhere and where
    no vote landed (vote k on path vst[k], id vid[k], weight vw[k])."""
    out = np.full(len(which), -1, np.int64)
    on = which[vst]
    vst, vid, vw = vst[on], vid[on], vw[on]
    if len(vst) == 0:
        return out
    path, pid, _, heaviest, _ = _heaviest_pairs(vst, vid, vw)
    out[path[heaviest]] = pid[heaviest]
    return out


def _carried_u(prev: Strokes, paths: Strokes, vst: np.ndarray, vs: np.ndarray, vu: np.ndarray, vid: np.ndarray,
               vw: np.ndarray, vsign: np.ndarray, o: PathOptions) -> Strokes:
    """The paths with the u their votes carry (vote k on path vst[k] at arc length vs[k], u vu[k],
    id vid[k], weight vw[k], tangents agreeing with sign vsign[k]): each path turned so that its
    own carried u increases along it (or, where u does not tell, the way the old tangents ran), a
    closed path to start at its old seam, u fitted, its self-similar level set."""
    P, S, L, ids = paths.period_px, len(paths), paths.lengths, paths.ids
    vu = heal_jumps(vst, vs, vu, vid, vw, P)
    trend = u_trend(vst, vid, ids, vs, vu, S)
    r_sign = np.bincount(vst, weights=vw * vsign, minlength=S)
    flip = np.where(np.abs(trend) >= 2.0 * o.sample_px, trend, r_sign) < 0
    if flip.any():
        paths = reverse(paths, flip)
        vs = np.where(flip[vst], L[vst] - vs, vs)
    fst, lst = paths.offsets[:-1], paths.offsets[1:] - 1
    closed = (L > 0) & (row_norm(paths.points.take(fst, axis=0) - paths.points.take(lst, axis=0)) < 1e-6)
    if closed.any():
        which, seam = seams(S, closed, L, vst, vs, vu, vid == ids[vst], P)
        if len(which):
            paths = rotate_closed(paths, which, seam)
            shift = np.zeros(S)
            shift[which] = seam
            vs = np.mod(vs - shift[vst], np.where(L > 0, L, 1.0)[vst])
    if o.other_id_weight != 1.0:  # (a path with none of its own id's votes fits all alike)
        own = vid == paths.ids[vst]
        has_own = np.bincount(vst[own], minlength=S) > 0
        vw = vw * np.where(own | ~has_own[vst], 1.0, o.other_id_weight)
    paths, u_new, b, _ = fit_u(prev, paths, vst, vs, vu, vid, vw, o.tracking)
    level, weight = levels_from_slope(b, P)
    return paths.replace(u=u_new, level=level, level_weight=weight)


def _empty(lines: Strokes) -> BrushPaths:
    zi = np.zeros(0, np.int64)
    z = np.zeros(0)
    return BrushPaths(Strokes.empty(lines.camera, lines.frame, lines.period_px), lines, np.zeros(1, np.int64), zi, z,
                      z, np.zeros(0, bool))


def _finish(paths: Strokes, lines: Strokes, pieces: Strokes, p_line, p_s0, p_s1, path_of, D: Samples, cover,
            smp_piece, hold: np.ndarray | None = None) -> BrushPaths:
    """BrushPaths with the covers: the pieces each path draws, and the covered runs of samples
    beside it. Paths where `hold` is true are left out (BrushPaths.held)."""
    held = None
    if hold is not None and hold.any():
        held = select(paths, hold)
        paths = select(paths, ~hold)
        new = np.cumsum(~hold) - 1
        keep = ~hold[path_of]
        # (Samples covered by a piece of a held path are left to no path: their piece goes.)
        pmap = np.full(len(path_of) + 1, -1, np.int64)
        pmap[np.flatnonzero(keep)] = np.arange(int(keep.sum()))
        smp_piece = pmap[smp_piece]
        p_line, p_s0, p_s1, path_of = p_line[keep], p_s0[keep], p_s1[keep], new[path_of[keep]]
    off, line, s0, s1, drawn = covered_runs(cover, smp_piece, path_of, D, p_line, p_s0, p_s1, len(paths))
    return BrushPaths(strokes=paths, lines=lines, cover_offsets=off, cover_line=line, cover_s0=s0, cover_s1=s1,
                      cover_drawn=drawn, held=held)


def concat_two(a: Strokes, b: Strokes) -> Strokes:
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
        self.touched = np.zeros(0, np.int64)

    def reset(self) -> None:
        self.prev, self.next_id, self.touched = None, 0, np.zeros(0, np.int64)

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
        out, self.next_id = brush_step(self.prev, lines, o, self.next_id, self.touched)
        if o.heal_px > 0:
            self.touched = touching_pairs(out.strokes)
        # The held paths vote with the drawn ones: one still there next frame takes its id back.
        self.prev = out.strokes if out.held is None else concat_two(out.strokes, out.held)
        if lines.pose is not None:  # (a moving scene: where this frame's objects were, for the next one)
            self.prev = self.prev.replace(pose=lines.pose)
        return out


def brush_frames(frames: list[Strokes], options: PathOptions | None = None) -> list[BrushPaths]:
    """Brush paths of a list of frames in order (convenience for tests and benchmarks)."""
    tr = PathTracker(options)
    return [tr.step(f) for f in frames]
