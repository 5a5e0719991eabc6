"""Chaining visible runs into strokes (seed 000 section 2.2.1).

Runs of the same kind are linked through shared mesh vertices where exactly two runs meet and
the turn between them is at most `split_angle_deg`; junctions, ends, sharp turns and clipped or
partly hidden ends stop a chain. The walk is vectorized: every run exists in both directions, the
successor of a directed run is the run continuing from its exit end, and pointer jumping ranks
each directed run within its chain (O(log n) numpy passes, no per-run Python loop).
"""

from __future__ import annotations

import numpy as np

from strokekit.model import KINDS, Strokes, VisibleRuns, row_norm
from strokekit.options import LineOptions


def _partners(node: np.ndarray, direction: np.ndarray, cos_split: float, zero: np.ndarray) -> np.ndarray:
    """For 2R run ends with node ids and unit directions pointing away from the node into the run:
    the other end at the same node when exactly two ends meet and the turn is gentle enough, else -1.
    `zero` (R,) is True where run r's direction (ends 2r, 2r + 1) is all zeros: such a run (no
    length on screen) links whatever the turn."""
    m = len(node)
    partner = np.full(m, -1, np.int64)
    if m == 0:
        return partner
    order = np.argsort(node)  # the pairs found do not depend on the order within a node
    ns = node[order]
    new = np.empty(m, bool)
    new[0] = True
    np.not_equal(ns[1:], ns[:-1], out=new[1:])
    starts = np.flatnonzero(new)
    counts = np.empty(len(starts), np.int64)
    np.subtract(starts[1:], starts[:-1], out=counts[:-1])
    counts[-1] = m - starts[-1]
    pairs = starts[counts == 2]
    e0, e1 = order[pairs], order[pairs + 1]
    # Directions away from the node: the chain goes in along -d0 and out along d1; the turn is the
    # angle between -d0 and d1. Split when turn > split angle, i.e. -d0.d1 < cos(split).
    d0, d1 = np.take(direction, e0, axis=0), np.take(direction, e1, axis=0)
    turn_cos = -np.einsum("ij,ij->i", d0, d1)
    degenerate = zero[e0 >> 1] | zero[e1 >> 1]
    ok = (turn_cos >= cos_split) | degenerate
    partner[e0[ok]] = e1[ok]
    partner[e1[ok]] = e0[ok]
    return partner


def _heads(partner: np.ndarray, items: np.ndarray, rounds: int):
    """Pointer jumping toward the head of each directed chain: (head, rank along the chain) of
    every directed item, or (None, None) when a chain is closed (a cycle has no head). Paths
    reach their heads within `rounds` = ceil(log2(2R)) doublings."""
    pred = np.where(partner >= 0, partner ^ 1, -1)
    ptr = np.where(pred >= 0, pred, items)
    rank = (pred >= 0).astype(np.int64)
    for _ in range(rounds + 1):
        nxt = ptr[ptr]
        if np.array_equal(nxt, ptr):
            break
        rank = rank + rank[ptr]  # a head has rank 0 and points to itself
        ptr = nxt
    if (pred[ptr] >= 0).any():  # an item that never reached a head lies on a cycle
        return None, None
    return ptr, rank


def chain_runs(runs: VisibleRuns, options: LineOptions, camera=None, frame: int = 0) -> Strokes:
    """Link visible runs into polylines. Returns Strokes ordered deterministically (by their
    first run), with u = arc length / period."""
    R = len(runs)
    if R == 0:
        return Strokes.empty(camera, frame, options.period_px)
    nk = len(KINDS) if not len(runs.kind) or runs.kind.max() < len(KINDS) else 128  # (hidden: kind codes)
    # Node ids: a mesh vertex seen by one kind; unique (negative) keys never match anything.
    k0 = np.where(runs.key0 >= 0, runs.key0 * nk + runs.kind, runs.key0)
    k1 = np.where(runs.key1 >= 0, runs.key1 * nk + runs.kind, runs.key1)
    node = np.empty(2 * R, np.int64)
    node[0::2], node[1::2] = k0, k1
    d = runs.p1 - runs.p0
    ln = row_norm(d)
    has_dir = ln > 1e-9
    d = np.where(has_dir[:, None], d / np.where(has_dir, ln, 1)[:, None], 0.0)
    direction = np.empty((2 * R, 2))
    direction[0::2], direction[1::2] = d, -d
    partner = _partners(node, direction, float(np.cos(np.radians(options.split_angle_deg))), ~has_dir)

    # Directed items: d = 2r + dir; item d enters at end d and leaves at end d ^ 1.
    items = np.arange(2 * R)

    rounds = max(1, int(2 * R - 1).bit_length())
    head, rank = _heads(partner, items, rounds)
    if head is None:
        # Closed chains (components of the run graph with no free end) are cut at their smallest
        # run's start end. Every run has at most two links, so a component is a path or a cycle:
        # pointer jumping backward along the directed chains for ceil(log2(2R)) rounds brings every
        # item of a path to its head (an item without predecessor) and gives every item of a cycle
        # the smallest run of the whole cycle.
        pred = np.where(partner >= 0, partner ^ 1, -1)
        ptr = np.where(pred >= 0, pred, items)
        low = items // 2
        for _ in range(rounds):
            low = np.minimum(low, low[ptr])
            ptr = ptr[ptr]
        on_cycle = pred[ptr] >= 0
        is_cut = np.zeros(R, bool)
        is_cut[low[on_cycle]] = True
        cut = 2 * np.flatnonzero(is_cut)
        partner[partner[cut]] = -1
        partner[cut] = -1
        head, rank = _heads(partner, items, rounds)
    succ = partner[items ^ 1]
    # Keep one direction per chain: the one whose head run is the smaller (forward on ties).
    # The opposite direction's head is the reverse of this direction's last item.
    is_last = succ < 0
    last_of_head = np.full(2 * R, -1, np.int64)
    last_of_head[head[is_last]] = items[is_last]
    rev_head = last_of_head[head] ^ 1
    head_run, rev_run = head >> 1, rev_head >> 1
    keep = (head_run < rev_run) | ((head_run == rev_run) & (head & 1 == 0))
    kept = items[keep]
    # By head, then rank along the chain (unique within a chain: one key sorts both).
    order = np.argsort(head[kept] * (2 * R) + rank[kept])
    # Chains ordered by their head's run index (which follows the scene's edge order).
    kept = kept[order]
    h = head[kept]
    chain_start = np.empty(len(h), bool)
    chain_start[:1] = True
    np.not_equal(h[1:], h[:-1], out=chain_start[1:])
    n_chain = int(chain_start.sum())
    run = kept // 2
    fwd = kept % 2 == 0
    # Ends of run r: index r (start) and R + r (end) into the stacked ends.
    entry = np.where(fwd, run, run + R)
    exit_ = np.where(fwd, run + R, run)
    # Points: entry of each chain's first run, then the exit of every run.
    first_idx = np.flatnonzero(chain_start)
    n_pts = len(kept) + n_chain
    pos_exit = np.arange(len(kept)) + np.cumsum(chain_start)
    pos_entry = pos_exit[first_idx] - 1
    # Every point is a run's exit (at pos_exit) or a chain's entry (at pos_entry): its row of the
    # stacked ends, gathered once (row scatters cost several times a take).
    src = np.empty(n_pts, np.int64)
    src[pos_exit] = exit_
    src[pos_entry] = entry.take(first_idx)
    points = np.concatenate([runs.p0, runs.p1]).take(src, axis=0)
    surface = np.concatenate([runs.X0, runs.X1]).take(src, axis=0)
    face = runs.face.take(np.where(src >= R, src - R, src))
    offsets = np.empty(n_chain + 1, np.int64)
    offsets[0] = 0
    offsets[1:-1] = first_idx[1:] + np.arange(1, n_chain)  # each chain: its runs + 1 points
    offsets[-1] = n_pts
    kind = runs.kind[run[first_idx]]
    return Strokes.build(points, surface, face, offsets, kind, camera=camera, frame=frame, period_px=options.period_px)
