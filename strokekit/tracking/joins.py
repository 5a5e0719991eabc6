"""Strokes joined for tracking: pieces that touch end to end chained into paths
(`chain_touching`, the links walked by a compiled pass, `joins_kernels`), segments of one chain
joined in order, closed strokes rotated to their seams."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from strokekit.lines.strokeops import join_arrays
from strokekit.model import Strokes, row_norm
from strokekit.numba_cache import LazyKernels
from strokekit.sampling import Samples
from strokekit.tracking.strokeops import cut_pieces, drop_hairpins

kernels = LazyKernels("strokekit.tracking.joins_kernels").kernels


def rotate_closed(strokes: Strokes, which: np.ndarray, s_start: np.ndarray) -> Strokes:
    """Closed strokes `which` made to start at arc length `s_start` (px) instead; same loop."""
    S = len(strokes)
    L = strokes.lengths
    rot = np.zeros(S, bool)
    rot[which] = True
    start = np.zeros(S)
    start[which] = s_start
    nr = int(rot.sum())
    pst = join_arrays(np.arange(S), np.flatnonzero(rot))
    second = join_arrays(np.zeros(S, bool), np.ones(nr, bool))
    s0 = join_arrays(start, np.zeros(nr))
    s1 = join_arrays(L, start[rot])
    order = np.lexsort((second, pst))
    pieces = cut_pieces(strokes, pst[order], s0[order], s1[order])
    keep = np.ones(len(pieces.points), bool)
    keep[pieces.offsets[:-1][second[order]]] = False  # the joint point is already there
    owner = pst[order][pieces.stroke_of_point][keep]
    counts = np.bincount(owner, minlength=S)
    out = strokes.replace(points=pieces.points[keep], surface=pieces.surface[keep], face=pieces.face[keep],
                  u=np.zeros(int(keep.sum())), offsets=join_arrays(0, np.cumsum(counts)).astype(np.int64))
    return out.replace(u=out.arc_length / out.period_px)


def turn_loops_to_seams(cur: Strokes, dense: Samples, vm: np.ndarray, u: np.ndarray, vid: np.ndarray, P: float):
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
    k = k[join_arrays(True, stq[k][1:] != stq[k][:-1])]
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


def join_segments(cur: Strokes, r_stroke, r_s0, r_s1, r_label, r_sign, tol_px: float, angle_deg: float,
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
    e_run = join_arrays(np.flatnonzero(at_start), np.flatnonzero(at_end))
    e_end = join_arrays(np.zeros(int(at_start.sum()), np.int64), np.ones(int(at_end.sum()), np.int64))
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
    # int lists: a greedy pass in a fixed order over the few candidate links of a frame.
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
    starts = join_arrays(runs[linked[runs, 0] != linked[runs, 1]], runs).tolist()
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
    few hundred stroke ends a sweep along x is cheaper than building a tree: neighbours in x
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


def touching_paths(strokes: Strokes, tol_px: float, angle_deg: float, allow=None):
    """The paths chain_touching makes: join_segments(strokes, arange(S), zeros(S), lengths,
    zeros(S), ones(S), tol_px, angle_deg, straightest_first=True) specialized (same group, rev,
    pos): every run is a whole stroke, all labels agree and all signs are +1, so the ends are the
    open strokes' first and last points, the straightest continuation is linked first where three
    ends meet, and a path is reversed when most of its strokes are entered at their end.
    `allow(ra, rb, a_end, b_end)`, when given, is shown every candidate joint (the strokes of its
    two ends, and whether each is the stroke's last point) and returns which may be linked. Returns group (S,) (the lowest stroke of each path), rev (S,)
    and pos (S,)."""
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
    # Nodes: starts of the open strokes, then their ends (the order join_segments uses).
    e_run = join_arrays(op, op)
    fo, lo = first[op], last[op]
    e_pt = join_arrays(fo, lo)
    nb = join_arrays(np.minimum(fo + 1, lo), np.maximum(lo - 1, fo))
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
    if allow is not None and ok.any():
        k = np.flatnonzero(ok)
        ok[k] = allow(e_run[a[k]], e_run[b[k]], a[k] >= n, b[k] >= n)
    if not ok.any():
        return group, rev, pos
    a, b, straight = a[ok], b[ok], straight[ok]
    # Greedy links in the order of join_segments (straightest first; the pairs come in another
    # order than the k-d tree's, the sort decides), each end in one link at most.
    o = _straightest_order(straight, e_run[a], e_run[b], S)
    return walk_links(a[o], b[o], e_run, n, S)


def walk_links(a: np.ndarray, b: np.ndarray, e_run: np.ndarray, n: int, S: int):
    """Candidate links a, b (L,) between stroke ends (node i < n: the start of stroke e_run[i],
    else its end), in the order they are taken (each end in one link at most), walked into
    paths: group (S,) (the lowest stroke of each path), rev (S,) (traversed backwards), pos (S,)
    (its place in the path). A path starts at a stroke with one linked end, entered through the
    free end, in stroke order (then rings, entered through their lowest stroke's start), and
    goes backwards when more of its strokes are entered at their end."""
    return kernels().link_paths(a, b, e_run, n, S)


@dataclass(frozen=True)
class GatheredPaths:
    """How the strokes of paths are laid end to end (see gather_paths). order (S,) strokes in
    path order; c0 (S,) where each starts in the gathered points; src (N',) the source point of
    each gathered point, repeated joint points left out; new_g (S,) a stroke starts a path;
    joint, drop: gathered indices of the joints and of the joints dropped as repeats;
    path_sorted (S,) the path of each stroke in `order`; first (K,) each path's first stroke;
    n_path (K,) points per path."""

    order: np.ndarray
    c0: np.ndarray
    src: np.ndarray
    new_g: np.ndarray
    joint: np.ndarray
    drop: np.ndarray
    path_sorted: np.ndarray
    first: np.ndarray
    n_path: np.ndarray


def gather_paths(strokes: Strokes, group: np.ndarray, rev: np.ndarray, pos: np.ndarray) -> GatheredPaths:
    """The points of each path (group, rev, pos of touching_paths) in order, reversed strokes
    backwards; a joint point that repeats the previous one is dropped (a bridge, when the ends
    were apart, is kept)."""
    S = len(strokes)
    # (group, pos) pairs are distinct: one stable sort of group * S + pos is lexsort((pos, group)).
    order = (group * S + pos).argsort(kind="stable")
    c0, src, new_g, joint, drop, path, first, n_path = kernels().gather(
        strokes.offsets, order, np.asarray(rev, bool), np.asarray(group, np.int64), strokes.points)
    return GatheredPaths(order, c0, src, new_g, joint, drop, path, first, n_path)


def chain_touching(strokes: Strokes, tol_px: float, angle_deg: float) -> Strokes:
    """Strokes of the same kind whose ends meet (within tol_px, turning by at most angle_deg)
    concatenated into one path (straightest continuation first where three ends meet), so that
    the cuts between carried ids can go where the previous frame had them, wherever the chaining
    happened to stop this frame (hysteresis of id boundaries). Same lines; ids renumbered."""
    S = len(strokes)
    if S < 2 or tol_px <= 0:
        return strokes
    group, rev, pos = touching_paths(strokes, tol_px, angle_deg)
    if np.array_equal(group, np.arange(S)):
        return strokes
    g = gather_paths(strokes, group, rev, pos)
    src, first, n_path, joint, drop = g.src, g.first, g.n_path, g.joint, g.drop
    P = strokes.points
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
    return out.replace(u=out.arc_length / out.period_px)


def concat_groups(pieces: Strokes, g_sorted: np.ndarray) -> Strokes:
    """Join consecutive pieces with the same group id into one stroke (the joint point of the
    second piece is dropped when it repeats the first's last point)."""
    K = len(pieces)
    if K == 0:
        return pieces
    new_g = join_arrays(True, g_sorted[1:] != g_sorted[:-1])
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
    out = pieces.replace(points=pieces.points[keep], surface=pieces.surface[keep], face=pieces.face[keep],
                  u=np.zeros(int(keep.sum())), offsets=join_arrays(0, np.cumsum(counts)).astype(np.int64),
                  kind=pieces.kind[sel], ids=np.arange(len(sel), dtype=np.int64), level=pieces.level[sel],
                  level_weight=pieces.level_weight[sel])
    return out.replace(u=out.arc_length / out.period_px)
