"""Filled outlines of strokes whose width varies along them (the SVG draws them filled: SVG's
stroke-width is one number per path).

A stroke of points P_i and radii r_i (half its widths) is one closed path: along its left side
(P_i + n r, n the segment's normal) forward, a round cap, along its right side back, a round cap.
Where two segments meet, the outer side turns on an arc of radius r_i about the point (a round
join) and the inner side goes through the point itself. Filled by the nonzero rule, that path is
exactly the union of its pieces: every segment's trapezoid (the normals' offsets at both ends),
the outer join's circular sector and the caps' half discs all wind the same way, and the inner
detours through the point add nothing, so overlaps fill once and there is no notch at a join
nor a hole at a sharp turn. Arcs are SVG arc commands (A) of at most 90 degrees (a join turning
further is split in two), so the sweep flag is read off the turn's direction.
"""

from __future__ import annotations

import numpy as np

from strokekit.model import row_norm
from strokekit.numba_cache import LazyKernels
from strokekit.writers.text import fixed_point_text

#: A join turning by less than this (radians) is drawn straight.
_STRAIGHT = 1e-9


def outline_path_data(points: np.ndarray, offsets: np.ndarray, radii: np.ndarray, decimals: int = 2,
                      members: np.ndarray | None = None) -> list[str]:
    """The path data ('M ... Z') of each stroke's filled outline (module doc): points (N, 2) px,
    stroke s = points[offsets[s]:offsets[s+1]], radii (N,) px (half the widths, > 0); of the
    strokes `members` only (sorted or not; None: every stroke). A stroke whose points all
    coincide is a disc. Written by a compiled loop (writers.outline_compiled); numbers it does
    not take go through numpy's writer (`outline_path_data_numpy`, the same text)."""
    P = np.ascontiguousarray(points, float)
    R = np.ascontiguousarray(radii, float)
    off = np.ascontiguousarray(offsets, np.int64)
    S = len(off) - 1
    mem = np.arange(S, dtype=np.int64) if members is None else np.ascontiguousarray(members, np.int64)
    if S == 0 or not len(mem):
        return [""] * len(mem)
    scale = 10.0 ** decimals
    with np.errstate(invalid="ignore"):
        top = (np.abs(P).max() if len(P) else 0.0) + 2.0 * (R.max() if len(R) else 0.0) + 1.0
    if not (0 <= decimals <= 9 and np.isfinite(top) and top * scale < 1e15):
        return _numpy_members(P, R, off, mem, decimals)
    n_pt = off[mem + 1] - off[mem]
    tokens = int((5 + 6 * np.maximum(n_pt - 1, 0)).sum())
    digits = len(str(int(top * scale))) + 1
    cap = tokens * (16 + 4 * (digits + 2)) + 2 * len(mem) + 16
    buf, ends = outline_kernels().outline_text(P, off, R, mem, int(decimals), _STRAIGHT, cap)
    text = buf.tobytes().decode("ascii")
    starts = np.r_[0, ends[:-1]].tolist()
    return [text[a:b] for a, b in zip(starts, ends.tolist())]


OUTLINE_KERNELS = LazyKernels("strokekit.writers.outline_compiled")
outline_kernels = OUTLINE_KERNELS.kernels


def _numpy_members(P, R, off, mem, decimals) -> list[str]:
    sel = np.repeat(mem, off[mem + 1] - off[mem])
    pts = np.concatenate([np.arange(off[s], off[s + 1]) for s in mem.tolist()]) if len(sel) else np.zeros(0, int)
    sub_off = np.r_[0, np.cumsum(off[mem + 1] - off[mem])]
    return outline_path_data_numpy(P[pts], sub_off, R[pts], decimals)


def outline_path_data_numpy(points: np.ndarray, offsets: np.ndarray, radii: np.ndarray, decimals: int = 2
                            ) -> list[str]:
    """outline_path_data of every stroke, by numpy passes over all tokens at once (the reference
    of the compiled writer; it also takes numbers the compiled one does not)."""
    P = np.asarray(points, float)
    R = np.asarray(radii, float)
    off = np.asarray(offsets, np.int64)
    S = len(off) - 1
    if S == 0:
        return []
    # Consecutive points that coincide are one point (a segment needs a direction).
    sid = np.repeat(np.arange(S), np.diff(off))
    keep = np.ones(len(P), bool)
    if len(P) > 1:
        step = row_norm(P[1:] - P[:-1])
        keep[1:] = ~((sid[1:] == sid[:-1]) & (step <= 1e-9))
    P, R, sid = P[keep], R[keep], sid[keep]
    n_pt = np.bincount(sid, minlength=S)
    off = np.r_[0, np.cumsum(n_pt)]
    m = n_pt - 1  # segments per stroke
    toks = _tokens(P, R, off, m)
    return _text(toks, S, decimals)


def _tokens(P, R, off, m):
    """Every stroke's path as tokens: (owner stroke, command 0 M / 1 L / 2 A, x, y, r, cx, cy) in
    path order (arcs: radius r about (cx, cy))."""
    S = len(m)
    seg_stroke = np.repeat(np.arange(S), np.maximum(m, 0))
    first_pt = off[:-1]
    # global segment g of stroke s, k-th: from point first_pt[s] + k
    seg_first = np.r_[0, np.cumsum(np.maximum(m, 0))][:-1]
    k_of = np.arange(len(seg_stroke)) - seg_first[seg_stroke]
    a = first_pt[seg_stroke] + k_of  # start point of each segment
    d = P[a + 1] - P[a]
    t = d / row_norm(d)[:, None]
    n = np.stack([-t[:, 1], t[:, 0]], 1)

    lines = m >= 1
    slots = np.where(lines, 5 + 6 * m, np.where(m == 0, 5, 0))  # a disc: M and four quarter arcs
    base = np.r_[0, np.cumsum(slots)]
    T = int(base[-1])
    cmd = np.full(T, -1, np.int8)
    xy = np.zeros((T, 2))
    rr = np.zeros(T)
    cc = np.zeros((T, 2))
    owner = np.repeat(np.arange(S), slots)

    def put(pos, c, p, r=None, centre=None):
        cmd[pos] = c
        xy[pos] = p
        if r is not None:
            rr[pos] = r
            cc[pos] = centre

    # discs
    disc = np.flatnonzero(m == 0)
    if len(disc):
        c0 = P[first_pt[disc]]
        r0 = R[first_pt[disc]][:, None]
        b = base[disc]
        put(b, 0, c0 + r0 * [1.0, 0.0])
        for q, v in enumerate(([0.0, 1.0], [-1.0, 0.0], [0.0, -1.0], [1.0, 0.0])):
            put(b + 1 + q, 2, c0 + r0 * v, r0[:, 0], c0)
    if not len(seg_stroke):
        return owner, cmd, xy, rr, cc
    b = base[seg_stroke]
    ms = m[seg_stroke]
    r_a, r_b = R[a][:, None], R[a + 1][:, None]
    # the left side forward: M at the start, L to each segment's end
    first_seg = k_of == 0
    put(b[first_seg], 0, (P[a] + n * r_a)[first_seg])
    put(b + 1 + 3 * k_of, 1, P[a + 1] + n * r_b)
    # the right side back: L to each segment's start
    q = ms - 1 - k_of
    put(b + 3 + 3 * ms + 3 * q, 1, P[a] - n * r_a)
    # caps: at the end (the stroke's last segment), at the start (its first)
    last_seg = k_of == ms - 1
    pe, re_, te, ne = P[a + 1][last_seg], r_b[last_seg], t[last_seg], n[last_seg]
    be, me = b[last_seg], ms[last_seg][:, None][:, 0]
    put(be + 1 + 3 * me, 2, pe + te * re_, re_[:, 0], pe)
    put(be + 2 + 3 * me, 2, pe - ne * re_, re_[:, 0], pe)
    ps, rs, ts, ns = P[a][first_seg], r_a[first_seg], t[first_seg], n[first_seg]
    bs, mss = b[first_seg], ms[first_seg]
    put(bs + 3 + 6 * mss, 2, ps - ts * rs, rs[:, 0], ps)
    put(bs + 4 + 6 * mss, 2, ps + ns * rs, rs[:, 0], ps)
    # joins at the points between segment g and g + 1 of one stroke
    jg = np.flatnonzero(k_of < ms - 1)
    if len(jg):
        ta, tb, na, nb = t[jg], t[jg + 1], n[jg], n[jg + 1]
        v = a[jg] + 1
        pv, rv = P[v], R[v][:, None]
        cross = ta[:, 0] * tb[:, 1] - ta[:, 1] * tb[:, 0]
        dot = np.einsum("ij,ij->i", ta, tb)
        straight = (np.abs(cross) <= _STRAIGHT) & (dot > 0)
        left_outer = cross <= 0  # turning toward -n: the +n (left) side is outer
        wide = dot < 0  # turning by more than 90 degrees: the arc in two
        mid = na + nb
        ml = row_norm(mid)
        hairpin = (ml <= 1e-9)[:, None]  # there the outer side is ahead, on either side
        mid = mid / np.maximum(ml, 1e-300)[:, None]
        bj, kj, mj = b[jg], k_of[jg], ms[jg]
        left_pos = bj + 2 + 3 * kj  # after the L to the end of segment k (the join at its end)
        right_pos = bj + 4 + 3 * mj + 3 * (mj - 1 - (kj + 1))  # after the L to the start of segment k + 1
        for side, pos, end_n, outer in ((1.0, left_pos, nb, left_outer), (-1.0, right_pos, na, ~left_outer)):
            end = pv + side * end_n * rv
            o = outer & ~straight
            inner = ~outer & ~straight
            one = o & ~wide
            two = o & wide
            put(pos[one], 2, end[one], rv[one, 0], pv[one])
            mid_pt = pv + np.where(hairpin, ta, side * mid) * rv
            put(pos[two], 2, mid_pt[two], rv[two, 0], pv[two])
            put(pos[two] + 1, 2, end[two], rv[two, 0], pv[two])
            put(pos[inner], 1, pv[inner])
            put(pos[inner] + 1, 1, end[inner])
    return owner, cmd, xy, rr, cc


def _text(toks, S: int, decimals: int) -> list[str]:
    """The path data text of the tokens, one string per stroke."""
    owner, cmd, xy, rr, cc = toks
    use = cmd >= 0
    owner, cmd, xy, rr, cc = owner[use], cmd[use], xy[use], rr[use], cc[use]
    if not len(cmd):
        return [""] * S
    prev = np.r_[xy[:1], xy[:-1]]
    cr = (prev[:, 0] - cc[:, 0]) * (xy[:, 1] - cc[:, 1]) - (prev[:, 1] - cc[:, 1]) * (xy[:, 0] - cc[:, 0])
    arc = cmd == 2
    # numbers: M/L: x y; A: r r x y (the flags go in the separator after the second r)
    count = np.where(arc, 4, 2)
    start = np.r_[0, np.cumsum(count)][:-1]
    nums = np.empty(int(count.sum()))
    sep = np.full(len(nums), 32, np.uint8)
    nums[start + count - 2] = xy[:, 0]
    nums[start + count - 1] = xy[:, 1]
    ai = start[arc]
    nums[ai] = rr[arc]
    nums[ai + 1] = rr[arc]
    sep[ai + 1] = np.where(cr[arc] > 0, _SWEEP1, _SWEEP0)
    # after each token's y: what starts the next one
    last = start + count - 1
    nxt = np.r_[cmd[1:], -1]
    new_stroke = np.r_[owner[1:] != owner[:-1], True]
    after = np.full(len(cmd), 32, np.uint8)
    after[nxt == 2] = _ARC
    after[(nxt == 1) & (cmd == 2)] = _LINE
    after[new_stroke] = _CLOSE
    sep[last] = after
    text = fixed_point_text(nums, decimals, sep)
    if text is None:  # numbers the digit arithmetic does not take: Python's formatting
        r = (np.round(nums, decimals) + 0.0).tolist()
        parts = [(f"%.{decimals}f" % x).encode() + _SEP_TEXT[int(c)] for x, c in zip(r, sep.tolist())]
        text = b"".join(parts)
    else:
        for code, rep in _SEP_TEXT.items():
            if code != 32:
                text = text.replace(bytes([code]), rep)
    pieces = text[:-1].decode("ascii").split("\0")
    out = [""] * S
    for s, p in zip(np.unique(owner).tolist(), pieces):
        out[s] = "M" + p + "Z"
    return out


_SWEEP0, _SWEEP1, _ARC, _LINE, _CLOSE = 1, 2, 3, 4, 5
_SEP_TEXT = {32: b" ", _SWEEP0: b" 0 0 0 ", _SWEEP1: b" 0 0 1 ", _ARC: b" A", _LINE: b" L", _CLOSE: b"\0"}
