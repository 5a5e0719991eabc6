"""Joins between strokes: where a stroke's end meets the end of another stroke of its kind (or
its own other end: a loop) within `join_px`, the line running on through it (tangents within
`join_angle_deg`), the two are one line drawn as two strokes (a brush path cut where its id
changes, a loop's seam). There a line has no head or tail (the along modifier's taper,
strokekit.style.widths) and the ribbons (strokekit.ribbons) run their body to the joint: both
ends move to the middle of the two and share one end edge across the line's bisecting direction.
The ends left are free ends."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from strokekit.model import row_norm


def stroke_bounds(sid: np.ndarray, n_strokes: int) -> tuple[np.ndarray, np.ndarray]:
    """(starts, ends) (S,): the first and one-past-last point of each stroke, for points grouped by
    stroke index sid (N,), sorted."""
    starts = np.searchsorted(sid, np.arange(n_strokes), side="left")
    ends = np.searchsorted(sid, np.arange(n_strokes), side="right")
    return starts, ends


def arc_lengths(p: np.ndarray, sid: np.ndarray) -> np.ndarray:
    """Cumulative arc length (px) from each stroke's start, for points grouped by stroke."""
    d = np.zeros(len(p))
    if len(p) > 1:
        d[1:] = np.linalg.norm(np.diff(p, axis=0), axis=1)
        d[1:][sid[1:] != sid[:-1]] = 0.0
    c = np.cumsum(d)
    first = np.r_[True, sid[1:] != sid[:-1]] if len(p) else np.zeros(0, bool)
    base = np.maximum.accumulate(np.where(first, c, 0.0)) if len(p) else c
    return c - base


#: A stroke's direction at an end: from its point this many px along it (at most half its length)
#: to the end (a last segment a fraction of a pixel long says little of where the line goes).
_END_REACH_PX = 2.0


@dataclass(frozen=True, eq=False)
class StrokeJoins:
    """The joined stroke ends of one frame (strokekit.style.joins). joined (S, 2): the start (0) and the end
    (1) of each stroke; point (S, 2, 2) px: where a joined end goes, the middle of the two ends;
    normal (S, 2, 2): the end edge both ribbons share, across the bisector of the two strokes'
    directions, oriented as the stroke's own normal at that end and scaled by the miter factor
    (each ribbon keeps its width square to itself); partner (S, 2): the end joined to, as
    2 x stroke + (0: start, 1: end), -1 where none."""

    joined: np.ndarray
    point: np.ndarray
    normal: np.ndarray
    partner: np.ndarray


def stroke_joins(points: np.ndarray, sid: np.ndarray, n_strokes: int, kind: np.ndarray, join_px: float,
                 join_angle_deg: float, arc: np.ndarray | None = None) -> StrokeJoins:
    """Which ends of the strokes (points (N, 2) px grouped by stroke index sid (N,), kind (S,)) are
    joins: the end of another stroke of the same kind, or the stroke's other end (a loop at least
    4 join_px long), within join_px, the line running on through both (their directions turning by
    at most join_angle_deg; a stair-step, where a scanned mesh's contour moves from one shingle to
    the next, is one too), and moving both to their middle keeps each ahead of its stroke's next
    point. Each end joins one other, the nearest first (then the straightest). `arc`: the points'
    arc_lengths where the caller has them (Strokes.arc_length, the same values)."""
    S = n_strokes
    joined = np.zeros((S, 2), bool)
    point = np.zeros((S, 2, 2))
    normal = np.zeros((S, 2, 2))
    partner = np.full((S, 2), -1, np.int64)
    out = StrokeJoins(joined, point, normal, partner)
    starts, ends = stroke_bounds(sid, S)
    arc = arc_lengths(points, sid) if arc is None else arc
    L = np.where(ends - starts >= 2, arc[np.maximum(ends - 1, 0)] if len(arc) else 0.0, 0.0)
    ok = np.flatnonzero(L > 0)
    if len(ok) < 1 or join_px <= 0:
        return out
    # Each end's position and outward direction (away from its stroke), from the point
    # _END_REACH_PX along it; rows 2k, 2k + 1: stroke ok[k]'s start and end.
    span = float(L.max()) + 1.0
    g = arc + sid * span
    s0, e1 = starts[ok], ends[ok] - 1
    reach = np.minimum(_END_REACH_PX, 0.5 * L[ok])
    j0 = np.clip(np.searchsorted(g, ok * span + reach, side="left"), s0 + 1, e1)
    j1 = np.clip(np.searchsorted(g, ok * span + L[ok] - reach, side="right") - 1, s0, e1 - 1)
    K = len(ok)
    at, back, nx = np.empty(2 * K, np.int64), np.empty(2 * K, np.int64), np.empty(2 * K, np.int64)
    at[0::2], at[1::2] = s0, e1
    back[0::2], back[1::2] = j0, j1
    nx[0::2], nx[1::2] = s0 + 1, e1 - 1  # the neighbour of each end
    E, NX = points[at], points[nx]
    D = E - points[back]
    D /= np.maximum(row_norm(D), 1e-300)[:, None]
    owner = np.repeat(ok, 2)
    a, b = close_pairs(E, join_px)
    if len(a) == 0:
        return out
    sa, sb = owner[a], owner[b]
    dot = D[a, 0] * D[b, 0] + D[a, 1] * D[b, 1]
    thru = D[a] - D[b]  # the line's direction through the joint, from a's stroke into b's
    thru /= np.maximum(row_norm(thru), 1e-300)[:, None]
    mid = 0.5 * (E[a] + E[b])
    ma, mb = mid - NX[a], mid - NX[b]
    ahead = (ma[:, 0] * D[a, 0] + ma[:, 1] * D[a, 1] > 0) & (mb[:, 0] * D[b, 0] + mb[:, 1] * D[b, 1] > 0)
    kind = np.asarray(kind)
    keep = ((kind[sa] == kind[sb]) & (dot <= -np.cos(np.radians(join_angle_deg)))
            & ahead & ((sa != sb) | (L[sa] >= 4.0 * join_px)))
    a, b, dot, thru, mid = a[keep], b[keep], dot[keep], thru[keep], mid[keep]
    dist = row_norm(E[b] - E[a])
    used = [False] * len(E)
    take = []
    al, bl = a.tolist(), b.tolist()  # (Python ints: the greedy loop indexes them one at a time)
    for k in np.lexsort((b, a, np.round(dot, 9), np.round(dist, 9))).tolist():
        if not (used[al[k]] or used[bl[k]]):
            used[al[k]] = used[bl[k]] = True
            take.append(k)
    take = np.asarray(take, np.int64)
    tt, ta = thru[take], D[a[take]]
    miter = 1.0 / np.maximum(tt[:, 0] * ta[:, 0] + tt[:, 1] * ta[:, 1], 1e-3)
    # both ends of every join at once: end e joined to end f
    e, f = np.concatenate([a[take], b[take]]), np.concatenate([b[take], a[take]])
    tt, miter, mid = np.concatenate([tt, tt]), np.concatenate([miter, miter]), np.concatenate([mid[take], mid[take]])
    s_e, w_e = owner[e], e % 2
    # the shared edge across the line, turned to the stroke's own normal: its direction of
    # travel at the end is D (an end) or -D (a start), the line's is +-thru
    De = D[e]
    along = (tt[:, 0] * De[:, 0] + tt[:, 1] * De[:, 1]) * np.where(w_e == 1, 1.0, -1.0)
    t = np.where((along >= 0)[:, None], tt, -tt)
    joined[s_e, w_e] = True
    point[s_e, w_e] = mid
    normal[s_e, w_e] = np.stack([-t[:, 1], t[:, 0]], 1) * miter[:, None]
    partner[s_e, w_e] = 2 * owner[f] + f % 2
    return out


def close_pairs(E: np.ndarray, r: float) -> tuple[np.ndarray, np.ndarray]:
    """(a, b): every pair a < b of the points E (M, 2) at most r apart (squared distance <= r^2,
    as scipy's cKDTree.query_pairs), in no particular order: after a sort on x, each point
    against those after it within r in x."""
    order = np.argsort(E[:, 0], kind="stable")
    x = E[order, 0]
    n = np.searchsorted(x, x + r, side="right") - np.arange(len(x)) - 1  # the points after each within r in x
    i = np.repeat(np.arange(len(x)), n)
    j = i + 1 + (np.arange(len(i)) - np.repeat(np.cumsum(n) - n, n))
    p, q = order[i], order[j]
    d = E[p] - E[q]
    near = d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] <= r * r
    p, q = p[near], q[near]
    return np.minimum(p, q), np.maximum(p, q)
