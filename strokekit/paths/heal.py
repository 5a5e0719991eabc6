"""Healing: a short brush path that meets another end to end on one line becomes part of it.

A path shorter than PathOptions.heal_px whose end meets the start of a longer path (within
HEAL_TOL_PX, same kind, turning by at most HEAL_ANGLE_DEG) heals into it where the cut is new
(one of the two was born this frame) or lasts (the two met the frame before too: a flicker does
not cut and heal every frame). A short path heals into one long path at most, so two long paths
never join through it. The healed path keeps the long path's id and u; the short one keeps its
own u shifted by the whole periods that bring it nearest the long one's (its texture does not
slide), or takes the long one's continuation by arc length where its u runs the other way.
Held-back paths (cover.held_back) stay apart.
"""

from __future__ import annotations

import numpy as np

from strokekit.model import Strokes, row_norm
from strokekit.tracking.joins import gather_paths, touching_paths
from strokekit.tracking.strokeops import select
from strokekit.tracking.votes import is_in

#: Ends this close (px) meet; the most the healed path turns where they do (degrees).
HEAL_TOL_PX = 1.5
HEAL_ANGLE_DEG = 45.0


def _pair_keys(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """One int64 key per unordered pair of ids (ids below 2**31)."""
    lo, hi = np.minimum(a, b).astype(np.int64), np.maximum(a, b).astype(np.int64)
    return (lo << 31) | hi


def touching_pairs(paths: Strokes) -> np.ndarray:
    """Sorted keys (_pair_keys) of the pairs of ids whose paths meet end to end."""
    seen = []

    def record(ra, rb, a_end, b_end):
        seen.append(_pair_keys(paths.ids[ra], paths.ids[rb]))
        return np.zeros(len(ra), bool)

    if len(paths) >= 2:
        touching_paths(paths, HEAL_TOL_PX, HEAL_ANGLE_DEG, allow=record)
    return np.unique(np.concatenate(seen)) if seen else np.zeros(0, np.int64)


def heal_paths(paths: Strokes, known: np.ndarray, touched: np.ndarray, short_px: float,
               apart: np.ndarray) -> tuple[Strokes, np.ndarray]:
    """The paths with their healed cuts joined (module doc): `known` the ids carried from the
    previous frame, `touched` the pairs of ids that met there (touching_pairs), `apart` (S,) the
    paths that join none. Returns the paths and the new index of each old path."""
    S = len(paths)
    if S < 2 or short_px <= 0:
        return paths, np.arange(S)
    ids, L = paths.ids, paths.lengths
    carried = is_in(ids, known)

    def allow(ra, rb, a_end, b_end):
        k = _pair_keys(ids[ra], ids[rb])
        i = np.minimum(np.searchsorted(touched, k), len(touched) - 1)
        again = touched[i] == k if len(touched) else np.zeros(len(k), bool)
        ok = ((carried[ra] != carried[rb]) | again) & ~apart[ra] & ~apart[rb]
        ok &= a_end != b_end  # (one's end meets the other's start: their u run the same way)
        # A short path heals into one long path at most (the longest it meets), never two long
        # paths into one through it.
        long_a, long_b = L[ra] >= short_px, L[rb] >= short_px
        ok &= long_a != long_b
        short, partner = np.where(long_a, rb, ra), np.where(long_a, ra, rb)
        k = np.flatnonzero(ok)
        k = k[np.lexsort((-L[partner[k]], short[k]))]
        ok[k[1:][short[k][1:] == short[k][:-1]]] = False
        return ok

    group, rev, pos = touching_paths(paths, HEAL_TOL_PX, HEAL_ANGLE_DEG, allow=allow)
    return _joined(paths, group, rev, pos, carried)


def bridge_splits(paths: Strokes, known: np.ndarray, parent: np.ndarray, gap_px: float,
                  apart: np.ndarray, on_line) -> tuple[Strokes, np.ndarray]:
    """The paths with their fresh splits held joined: a path with a fresh id whose votes came
    mostly from the id `parent` (S,) of a carried path it meets end to end within `gap_px`
    (same kind, the bridge running on along both ends, turning by at most HEAL_ANGLE_DEG, and
    beyond HEAL_TOL_PX lying on the drawing: `on_line(pa, pb)` (K,) whether segments pa -> pb do)
    is drawn as part of it, bridged: a split of one line costs no id. `apart` as heal_paths.
    Returns the paths and the new index of each old path."""
    S = len(paths)
    if S < 2 or gap_px <= 0:
        return paths, np.arange(S)
    carried_all = is_in(paths.ids, known)
    # (Only the fresh paths with a parent drawn this frame, and their parents, can join.)
    child = ~carried_all & is_in(parent, paths.ids)
    sub = np.flatnonzero(child | (carried_all & is_in(paths.ids, parent[child])))
    if len(sub) < 2:
        return paths, np.arange(S)
    keep = np.zeros(S, bool)
    keep[sub] = True
    part = select(paths, keep)
    ids, P, parent, apart, carried = part.ids, part.points, parent[sub], apart[sub], carried_all[sub]
    first, last = part.offsets[:-1], part.offsets[1:] - 1
    cos_max = np.cos(np.radians(HEAL_ANGLE_DEG))

    def end_of(r, at_end):
        """The end point of paths r and the unit direction out of it (over up to 3 px)."""
        e = np.where(at_end, last[r], first[r])
        inner = np.where(at_end, np.maximum(last[r] - 3, first[r]), np.minimum(first[r] + 3, last[r]))
        d = P[e] - P[inner]
        return P[e], d / np.maximum(row_norm(d), 1e-12)[:, None]

    def allow(ra, rb, a_end, b_end):
        ok = (a_end != b_end) & ~apart[ra] & ~apart[rb]
        ok &= ((carried[ra] & ~carried[rb] & (parent[rb] == ids[ra]))
               | (carried[rb] & ~carried[ra] & (parent[ra] == ids[rb])))
        pa, da = end_of(ra, a_end)
        pb, db = end_of(rb, b_end)
        v = pb - pa
        gap = row_norm(v)
        v = v / np.maximum(gap, 1e-12)[:, None]
        on = ((v * da).sum(1) >= cos_max) & (-(v * db).sum(1) >= cos_max)
        if ok.any():
            k = np.flatnonzero(ok & on & (gap > HEAL_TOL_PX))
            on[k] = on_line(pa[k], pb[k])
        return ok & ((gap <= HEAL_TOL_PX) | on)

    g_sub, r_sub, p_sub = touching_paths(part, gap_px, HEAL_ANGLE_DEG, allow=allow)
    group, rev, pos = np.arange(S), np.zeros(S, bool), np.zeros(S, np.int64)
    group[sub], rev[sub], pos[sub] = sub[g_sub], r_sub, p_sub
    return _joined(paths, group, rev, pos, carried_all)


def _joined(paths: Strokes, group: np.ndarray, rev: np.ndarray, pos: np.ndarray,
            carried: np.ndarray) -> tuple[Strokes, np.ndarray]:
    """The paths laid end to end as touching_paths links them (group, rev, pos), each drawn the
    way its keeper's u increases (the keeper: carried first, then the longest) with the keeper's
    id and u, the others' u continued (module doc); and the new index of each old path."""
    S = len(paths)
    ids, L = paths.ids, paths.lengths
    if np.array_equal(group, np.arange(S)):
        return paths, np.arange(S)
    g = gather_paths(paths, group, rev, pos)
    K = len(g.first)
    new_of = np.empty(S, np.int64)
    new_of[g.order] = g.path_sorted
    # The keeper of each healed path: carried first, then the longest.
    rank = np.lexsort((-L, ~carried, new_of))
    keeper = rank[np.r_[True, new_of[rank][1:] != new_of[rank][:-1]]]
    off = np.concatenate(((0,), g.n_path.cumsum())).astype(np.int64)
    path = np.repeat(np.arange(K), g.n_path)
    src = g.src
    own = paths.stroke_of_point[src] == keeper[path]
    # Drawn the way the keeper's u increases.
    at = np.flatnonzero(own)
    k0 = np.full(K, len(src))
    k1 = np.full(K, -1)
    np.minimum.at(k0, path[at], at)
    np.maximum.at(k1, path[at], at)
    u = paths.u[src]
    down = u[k1] < u[k0]
    if down.any():
        i = np.arange(len(src))
        idx = np.where(down[path], off[path] + off[path + 1] - 1 - i, i)
        src, own, u = src[idx], own[idx], u[idx]
    out = Strokes(points=paths.points.take(src, axis=0), surface=paths.surface.take(src, axis=0),
                  face=paths.face[src], offsets=off, kind=paths.kind[keeper], ids=ids[keeper], u=u,
                  level=paths.level[keeper], level_weight=paths.level_weight[keeper], camera=paths.camera,
                  frame=paths.frame, period_px=paths.period_px)
    # u: the keeper's own; before it and after it, continued by arc length.
    G, P = out.arc_length, out.period_px
    at = np.flatnonzero(own)
    k0 = np.full(K, len(src))
    k1 = np.full(K, -1)
    np.minimum.at(k0, path[at], at)
    np.maximum.at(k1, path[at], at)
    before = ~own & (np.arange(len(src)) < k0[path])
    after = ~own & (np.arange(len(src)) > k1[path])
    cont = u.copy()
    b, a = path[before], path[after]
    cont[before] = u[k0[b]] - (G[k0[b]] - G[before]) / P
    cont[after] = u[k1[a]] + (G[after] - G[k1[a]]) / P
    # A joined path whose own u runs the same way keeps it, shifted by the whole periods nearest
    # the continuation (its texture does not slide); one running against it takes the continuation.
    m = paths.stroke_of_point[src]
    i = np.arange(len(src))
    lo = np.full(S, len(src))
    hi = np.full(S, -1)
    np.minimum.at(lo, m, i)
    np.maximum.at(hi, m, i)
    same_way = u[np.maximum(hi, 0)] >= u[np.minimum(lo, len(src) - 1)]
    n = np.bincount(m, minlength=S)
    shift = np.round(np.bincount(m, weights=cont - u, minlength=S) / np.maximum(n, 1))
    return out.replace(u=np.where(own | ~same_way[m], cont, u + shift[m])), new_of
