"""Temporal coherence metrics of BRIEF section 3, between the strokes of consecutive frames.

Every stroke is resampled at 1 px of arc length. A sample carries its stroke id, position p (px),
parameter u (texture periods), surface point X (world) and screen tangent t. Correspondence
between frames f-1 and f: X of frame f-1 is projected with frame f's camera and matched to the
nearest frame-f sample within `radius_px` (6) whose tangent agrees (|t.t'| >= `min_tangent_dot`,
0.65); the same is run from f to f-1. Silhouettes slide over the surface, so matching is done on
the screen position of the projected point, never on identical surface points.

- M1 id persistence: matched length whose id is the same in both frames / matched length.
- M2 popping: length without a match in the other frame (both directions) / both frames' length.
- M4 sliding: |u' - u| wrapped into (-1/2, 1/2], times the period P, in px (median, p95, max).
- M5 flatness: lambda = 1 / (P du/ds); length-weighted mean |log2 lambda| over a frame; a
  stretch counts for at most MAX_STRETCH_OCTAVES (10), which a frozen texture (constant u) gets.
  `flatness_raw` is that number on u as written. `flatness` is the same measure on the texture
  as drawn with the self-similar levels of Benard 2010 (Strokes.level, level_weight, convention
  of strokekit.tracking): octave k samples u * 2^-k, so its lambda is 2^k / (P du/ds); the
  blend of octaves level and level+1 is read at its continuous level
  c = level + 1 - level_weight. `flatness_blend` counts the two octaves apart with their
  weights instead (an upper bound: 1/3 octave on average even for a perfect level choice).
- M7 end growth: per id present in both frames, |L' - L| in px.
"""

from __future__ import annotations

import re

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from .errors import InputError
from .model import Strokes, bracket, row_norm, uclip

#: BRIEF 3 constants.
MATCH_RADIUS_PX = 6.0
MIN_TANGENT_DOT = 0.65


@dataclass(frozen=True, eq=False)
class Samples:
    """Strokes resampled at ~`step` px of arc length (midpoints of equal pieces of each stroke).

    p (M, 2) px; X (M, 3) world; u (M,) periods; t (M, 2) unit screen tangents; ids (M,) stroke ids;
    stroke (M,) stroke index; s (M,) arc length from the stroke start, px; w (M,) length each
    sample stands for, px (sums to the stroke length)."""

    p: np.ndarray
    X: np.ndarray
    u: np.ndarray
    t: np.ndarray
    ids: np.ndarray
    stroke: np.ndarray
    s: np.ndarray
    w: np.ndarray

    def __len__(self) -> int:
        return len(self.p)


_FRAMES: dict = {}  # id(camera) -> (camera, frame): the last cameras seen, by identity


def _frame_of(camera) -> tuple:
    """(right, up', fwd, eye, f) of a camera, computed once per camera object (up to 64 cameras
    kept; looked up by identity: hashing a Camera, a dataclass of tuples, and comparing it
    cost more than the lookup saved)."""
    hit = _FRAMES.get(id(camera))
    if hit is not None and hit[0] is camera:
        return hit[1]
    right, up, fwd = camera.basis
    frame = (right, up, fwd, np.asarray(camera.eye, float), camera.focal_px)
    if len(_FRAMES) >= 64:
        _FRAMES.clear()  # (atomic: safe if trackers run in threads; refilled in a frame or two)
    _FRAMES[id(camera)] = (camera, frame)
    return frame


def project(camera, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Camera.project (BRIEF 1.1) with the camera frame cached: (N, 2) px and (N,) depths."""
    right, up, fwd, eye, f = _frame_of(camera)
    q = np.asarray(X, float) - eye
    z = q @ fwd
    xr, yu = q @ right, q @ up
    if camera.is_ortho:
        return np.stack([camera.width / 2.0 + f * xr, camera.height / 2.0 - f * yu], axis=-1), z
    out = np.empty((len(z), 2))  # filled by column: np.stack costs more than the arithmetic here
    with np.errstate(divide="ignore", invalid="ignore"):
        out[:, 0] = camera.width / 2.0 + f * xr / z
        out[:, 1] = camera.height / 2.0 - f * yu / z
    return out, z


def surface_between(strokes: Strokes, i: np.ndarray, j: np.ndarray, a: np.ndarray) -> np.ndarray:
    """World points under the screen points p_i + a (p_j - p_i) (a (K,) in [0, 1]): the surface
    points are interpolated perspective-correctly (1/z is linear on screen), so that a point in
    the middle of a long receding segment is the world point actually drawn there."""
    X = strokes.surface
    cam = strokes.camera
    a = np.asarray(a, float)
    # Gathered once for the depths and the interpolation; take(axis=0): numpy's fancy indexing of
    # (N, 3) rows is ~8x slower on frame-sized arrays (same values).
    Xi, Xj = X.take(i, axis=0), X.take(j, axis=0)
    if cam is not None and not cam.is_ortho and len(i):
        _, _, fwd, eye, _ = _frame_of(cam)
        zi, zj = (Xi - eye) @ fwd, (Xj - eye) @ fwd
        ok = (zi > 0) & (zj > 0)
        if ok.all():  # the usual case: the np.where below pass zi, zj through
            den = (1 - a) * zj + a * zi
            dp = den > 0
            a = a * zi / den if dp.all() else np.where(dp, a * zi / np.where(dp, den, 1.0), a)
        else:
            zi = np.where(ok, zi, 1.0)
            den = (1 - a) * np.where(ok, zj, 1.0) + a * zi
            a = np.where(ok & (den > 0), a * zi / np.where(den > 0, den, 1.0), a)
    return Xi * (1 - a)[:, None] + Xj * a[:, None]


def resample_strokes(strokes: Strokes, step_px: float = 1.0, with_surface: bool = True) -> Samples:
    """Resample every stroke into pieces of at most `step_px` px; one sample at the middle of each
    piece, with u, X and position interpolated linearly along the polyline (vectorized).
    with_surface=False leaves X at zero (screen-only uses, cheaper)."""
    if len(strokes) == 0 or len(strokes.points) == 0:
        z = np.zeros(0)
        zi = np.zeros(0, np.int64)
        return Samples(np.zeros((0, 2)), np.zeros((0, 3)), z, np.zeros((0, 2)), zi, zi, z, z)
    L = strokes.lengths
    S = len(strokes)
    n = np.maximum(1, np.ceil(L / step_px - 1e-9)).astype(np.int64)
    stroke = np.arange(S).repeat(n)
    cn = n.cumsum()
    k = np.arange(cn[-1]) - (cn - n).repeat(n)
    w = (L / n)[stroke]
    s = (k + 0.5) * w
    base, G = strokes.global_arc
    offsets = strokes.offsets
    g = s + base[stroke]
    first = offsets[:-1][stroke]
    last = offsets[1:][stroke] - 1
    i, j = bracket(G, G.searchsorted(g, side="right"), first, last)
    single = last == first  # one-point stroke
    if single.any():
        j = np.where(single, first, j)
        i = np.where(single, first, i)
    Gi = G[i]
    d = G[j] - Gi
    dp = d > 0
    a = (g - Gi) / d if dp.all() else np.where(dp, (g - Gi) / np.where(dp, d, 1.0), 0.0)
    a = uclip(a, 0.0, 1.0)
    P, U = strokes.points, strokes.u
    Xs = surface_between(strokes, i, j, a) if with_surface else np.zeros((len(i), 3))
    u = U[i] * (1 - a) + U[j] * a
    Pi, Pj = P.take(i, axis=0), P.take(j, axis=0)  # once for the position and the tangent (take: see above)
    t = Pj - Pi
    tn = row_norm(t)  # np.linalg.norm(t, axis=1) without its overhead
    pos = tn > 0
    t = t / tn[:, None] if pos.all() else np.where(pos[:, None], t / np.where(pos, tn, 1.0)[:, None], 0.0)
    p = Pi * (1 - a)[:, None] + Pj * a[:, None]
    return Samples(p=p, X=Xs, u=u, t=t, ids=strokes.ids[stroke], stroke=stroke, s=s, w=w)


def match_samples(src: Samples, camera, dst: Samples, dst_tree: cKDTree | None = None, *,
                  radius_px: float = MATCH_RADIUS_PX, min_tangent_dot: float = MIN_TANGENT_DOT,
                  k: int = 8, return_projected: bool = False, piece_distance: bool = False,
                  exact: bool = False):
    """For every sample of `src`: the index of its match in `dst` (or -1). src.X is projected
    with `camera` (dst's camera); the match is the nearest dst sample within `radius_px` px
    whose tangent agrees with the src tangent (|t.t'| >= min_tangent_dot). With
    return_projected, also the (M, 2) projected pixel positions.
    piece_distance (for sparse dst samples, as the tracker's): among the k nearest agreeing
    samples, the one whose piece of line (length w along t, centred on p) passes nearest wins,
    instead of the one whose centre is nearest: where lines run 1-3 px apart (shingled mesh
    contours) the nearest centre of samples 3-4 px apart is often on the wrong line, the line
    the 1 px samples of the metrics pick is not. The metrics use the plain rule.
    exact (the metrics, BRIEF 3): where all k nearest samples are within reach and none agrees,
    every sample within reach is examined, so the nearest agreeing one is never missed in
    crowded places (the tracker's votes are content with the k nearest)."""
    out = np.full(len(src), -1, np.int64)
    if len(src) == 0 or len(dst) == 0:
        return (out, np.full((len(src), 2), np.nan)) if return_projected else out
    q, z = project(camera, src.X)
    # (Columns combined by hand: numpy's reductions along a short trailing axis cost ~10 us.)
    fin = np.isfinite(q)
    ok = fin[:, 0] & fin[:, 1] & ((z > 0) | camera.is_ortho)
    if not ok.any():
        return (out, q) if return_projected else out
    tree = dst_tree if dst_tree is not None else cKDTree(dst.p)
    kk = min(k, len(dst))
    every = ok.all()  # the usual case: no copies, no scatter
    qq = q if every else q[ok]
    st = src.t if every else src.t[ok]
    dist, idx = tree.query(qq, k=kk, distance_upper_bound=radius_px)
    n = len(qq)
    if piece_distance:
        # Neighbour by neighbour: (kk, n) planes, so that every operation below runs along rows
        # of n (the (n, kk) layout makes numpy loop n times over rows of kk: several times
        # slower). Same operations on the same values, elementwise.
        dist = dist.reshape(n, kk).T.copy()
        valid = dist < np.inf  # (the tree marks "not found" with inf)
        every_valid = valid.all()
        idx = idx.reshape(n, kk).T
        safe = idx.copy() if every_valid else np.where(valid, idx, 0)
        # One gather of the planes t_x, t_y, p_x, p_y, w/2 instead of three gathers: (5, kk, n),
        # each plane contiguous for the arithmetic below.
        planes = np.empty((5, len(dst)))
        planes[0:2] = dst.t.T
        planes[2:4] = dst.p.T
        np.multiply(dst.w, 0.5, out=planes[4])
        D = planes.take(safe, axis=1)
        T0, T1 = D[0], D[1]
        # (In place where a temporary can take the result: the same operations, fewer arrays.)
        dots = T0 * st[:, 0]
        dots += T1 * st[:, 1]
        good = np.abs(dots, out=dots) >= min_tangent_dot
        if not every_valid:
            good &= valid
        # Squared distance to the piece: across the line, plus beyond the piece's ends along it.
        # (Where no neighbour was found dist is inf and so is the cost; `good` masks it anyway.)
        along = qq[:, 0] - D[2]
        along *= T0
        a1 = qq[:, 1] - D[3]
        a1 *= T1
        along += a1
        beyond = np.abs(along)
        beyond -= D[4]
        np.maximum(beyond, 0.0, out=beyond)
        cost = dist * dist
        cost -= np.multiply(along, along, out=a1)
        np.maximum(cost, 0.0, out=cost)
        cost += np.multiply(beyond, beyond, out=beyond)
        # Per query the first neighbour of least cost among the good ones (np.argmin's rule),
        # by rows: a strict < keeps the earlier neighbour on ties.
        has = good[0].copy()
        best = np.where(has, cost[0], np.inf)
        first = np.zeros(n, np.int64)
        for c in range(1, kk):
            better = good[c] & (cost[c] < best)
            first[better] = c
            best = np.where(better, cost[c], best)
            has |= good[c]
        m = np.where(has, safe.ravel()[first * n + np.arange(n)], -1)  # safe[first, col], flat
    else:
        dist = dist.reshape(n, kk)
        idx = idx.reshape(n, kk)
        valid = np.isfinite(dist)
        safe = np.where(valid, idx, 0)
        T = dst.t[safe]
        dots = np.abs(T[..., 0] * st[:, None, 0] + T[..., 1] * st[:, None, 1])
        good = valid & (dots >= min_tangent_dot)
        has = good[:, 0].copy()  # good.any(axis=1), by columns (numpy's reductions along a short axis cost ~10 us)
        for c in range(1, kk):
            has |= good[:, c]
        # Neighbours come sorted by distance: the first good one is the nearest agreeing sample.
        first = np.argmax(good, axis=1)
        m = np.where(has, safe.ravel()[np.arange(n) * kk + first], -1)  # safe[row, first], flat (cheaper)
    if exact and not piece_distance:
        redo = np.flatnonzero(~has & valid[:, -1])
        if len(redo):
            m[redo] = _nearest_agreeing(tree, qq[redo], st[redo], dst.t, radius_px,
                                        min_tangent_dot)
    if every:
        out = m
    else:
        out[np.flatnonzero(ok)] = m
    return (out, q) if return_projected else out


def _nearest_agreeing(tree: cKDTree, q: np.ndarray, t: np.ndarray, dst_t: np.ndarray, radius_px: float,
                      min_tangent_dot: float) -> np.ndarray:
    """(N,) for points q (N, 2) with tangents t: the nearest sample of `tree` within radius_px whose
    tangent (dst_t) agrees, among all of them, or -1."""
    near = tree.query_ball_point(q, radius_px)
    counts = np.fromiter((len(x) for x in near), np.int64, len(near))
    out = np.full(len(q), -1, np.int64)
    if counts.sum() == 0:
        return out
    cand = np.fromiter((j for x in near for j in x), np.int64, int(counts.sum()))
    row = np.repeat(np.arange(len(q)), counts)
    d = tree.data[cand] - q[row]
    dist2 = np.einsum("ij,ij->i", d, d)
    good = np.abs(np.einsum("ij,ij->i", dst_t[cand], t[row])) >= min_tangent_dot
    row, cand, dist2 = row[good], cand[good], dist2[good]
    o = np.lexsort((cand, dist2, row))  # per row the nearest first (ties: lower index)
    first = o[np.r_[True, row[o][1:] != row[o][:-1]]] if len(o) else o
    out[row[first]] = cand[first]
    return out


def _wrap(du: np.ndarray) -> np.ndarray:
    """Wrap a parameter difference into (-1/2, 1/2] (periodic texture)."""
    return -((-du + 0.5) % 1.0 - 0.5)


#: M5: the stretch counted for a texture stretched further, or frozen (constant u), in octaves.
MAX_STRETCH_OCTAVES = 10.0


def _flatness(strokes: Strokes, smp: Samples, mode: str) -> float:
    """Length-weighted mean |log2 lambda| of one frame (see module doc). mode "raw": u as
    written; "level": the self-similar texture at its continuous level c = level + 1 -
    level_weight (octave blend read as one texture of scale 2^c, as Benard 2010 designs it);
    "blend": the two blended octaves counted separately with their weights (an upper bound)."""
    if len(smp) < 2:
        return 0.0
    same = smp.stroke[1:] == smp.stroke[:-1]
    ds = 0.5 * (smp.w[1:] + smp.w[:-1])
    ok = same & (ds > 0)
    if not ok.any():
        return 0.0
    P = strokes.period_px
    ds = ds[ok]
    # A texture stretched beyond MAX_STRETCH_OCTAVES (constant u: frozen, lambda infinite)
    # counts as stretched by that much: left out, a stroke with constant u would score 0.
    du = np.maximum(np.abs(smp.u[1:] - smp.u[:-1])[ok], ds / (P * 2.0 ** MAX_STRETCH_OCTAVES))
    log_lam = -np.log2(P * du / ds)  # lambda = 1 / (P du/ds)
    w = ds
    if mode == "raw":
        return float(np.sum(w * np.abs(log_lam)) / np.sum(w))
    st = smp.stroke[1:][ok]
    lev = strokes.level[st]
    wt = np.clip(strokes.level_weight[st], 0.0, 1.0)
    # Octave k samples u 2^-k: lambda_k = 2^k lambda. Octave `level` has weight `level_weight`,
    # octave level + 1 the rest.
    if mode == "level":
        e = np.abs(log_lam + lev + 1 - wt)
    else:
        e = wt * np.abs(log_lam + lev) + (1 - wt) * np.abs(log_lam + lev + 1)
    return float(np.sum(w * e) / np.sum(w))


@dataclass
class PairMetrics:
    """Metrics of one frame pair (f-1, f). Lengths in px."""

    frame: int
    matched_px: float
    same_id_px: float
    unmatched_px: float
    total_px: float
    sliding_px: np.ndarray = field(repr=False)  # |wrapped du| * P of every matched sample
    growth_px: np.ndarray = field(repr=False)  # |L' - L| per persisting id
    flatness: float = 0.0  # of frame f, with self-similar levels
    flatness_raw: float = 0.0  # of frame f, u as written
    flatness_blend: float = 0.0  # of frame f, blended octaves counted apart
    prev_frame: int = -1  # the frame compared with (frame - 1 unless frames are missing)

    @property
    def m1(self) -> float:
        return self.same_id_px / self.matched_px if self.matched_px > 0 else 1.0

    @property
    def m2(self) -> float:
        return self.unmatched_px / self.total_px if self.total_px > 0 else 0.0

    def summary(self) -> dict:
        return {"frame": self.frame, "M1": self.m1, "M2": self.m2, **_stats("M4", self.sliding_px),
                "M5": self.flatness, "M5_raw": self.flatness_raw,
                "M5_blend": self.flatness_blend, **_stats("M7", self.growth_px),
                "matched_px": self.matched_px, "total_px": self.total_px}


def _stats(name: str, v: np.ndarray) -> dict:
    if len(v) == 0:
        return {f"{name}_median": 0.0, f"{name}_p95": 0.0, f"{name}_max": 0.0}
    return {f"{name}_median": float(np.median(v)), f"{name}_p95": float(np.percentile(v, 95)),
            f"{name}_max": float(np.max(v))}


def pair_metrics(prev: Strokes, cur: Strokes, *, radius_px: float = MATCH_RADIUS_PX,
                 min_tangent_dot: float = MIN_TANGENT_DOT, prev_samples: Samples | None = None,
                 cur_samples: Samples | None = None) -> PairMetrics:
    """BRIEF 3 metrics between the strokes of frame f-1 (`prev`) and frame f (`cur`). Both need
    their camera. The sliding uses cur.period_px."""
    if prev.camera is None or cur.camera is None:
        raise InputError("coherence metrics need the camera of both frames")
    a = prev_samples if prev_samples is not None else resample_strokes(prev, 1.0)
    b = cur_samples if cur_samples is not None else resample_strokes(cur, 1.0)
    P = cur.period_px
    ta = cKDTree(a.p) if len(a) else None
    tb = cKDTree(b.p) if len(b) else None
    ab = match_samples(a, cur.camera, b, tb, radius_px=radius_px, min_tangent_dot=min_tangent_dot, exact=True)
    ba = match_samples(b, prev.camera, a, ta, radius_px=radius_px, min_tangent_dot=min_tangent_dot, exact=True)
    ma, mb = ab >= 0, ba >= 0
    matched = a.w[ma].sum() + b.w[mb].sum()
    same = a.w[ma][a.ids[ma] == b.ids[ab[ma]]].sum() + b.w[mb][b.ids[mb] == a.ids[ba[mb]]].sum()
    unmatched = a.w[~ma].sum() + b.w[~mb].sum()
    total = a.w.sum() + b.w.sum()
    slide = np.concatenate([np.abs(_wrap(b.u[ab[ma]] - a.u[ma])), np.abs(_wrap(b.u[mb] - a.u[ba[mb]]))]) * P
    common, ia, ib = np.intersect1d(prev.ids, cur.ids, return_indices=True)
    # Ids are unique per frame when tracked; with repeated ids compare the first occurrences.
    growth = np.abs(cur.lengths[ib] - prev.lengths[ia])
    return PairMetrics(frame=int(cur.frame), prev_frame=int(prev.frame), matched_px=float(matched), same_id_px=float(same),
                       unmatched_px=float(unmatched), total_px=float(total), sliding_px=slide, growth_px=growth,
                       flatness=_flatness(cur, b, "level"), flatness_raw=_flatness(cur, b, "raw"),
                       flatness_blend=_flatness(cur, b, "blend"))


def sequence_metrics(frames: list[Strokes], **kw) -> tuple[list[PairMetrics], dict]:
    """Metrics of every consecutive pair of `frames` (in order) and the overall summary:
    M1 over all matched length; M2 median and mean of the per-pair values; M4 and M7 median, p95
    and max over all pairs' samples; M5 mean and max over frames 2..n (with levels and raw)."""
    pairs = []
    prev_s = None
    for k in range(1, len(frames)):
        a = prev_s if prev_s is not None else resample_strokes(frames[k - 1], 1.0)
        b = resample_strokes(frames[k], 1.0)
        pairs.append(pair_metrics(frames[k - 1], frames[k], prev_samples=a, cur_samples=b, **kw))
        prev_s = b
    return pairs, overall(pairs)


def overall(pairs: list[PairMetrics]) -> dict:
    """Summary of a list of pair metrics (see sequence_metrics)."""
    if not pairs:
        return {"pairs": 0}
    matched = sum(p.matched_px for p in pairs)
    same = sum(p.same_id_px for p in pairs)
    m2 = np.array([p.m2 for p in pairs])
    fl = np.array([p.flatness for p in pairs])
    flr = np.array([p.flatness_raw for p in pairs])
    return {"pairs": len(pairs), "M1": same / matched if matched > 0 else 1.0,
            "M2_median": float(np.median(m2)), "M2_mean": float(np.mean(m2)), "M2_max": float(np.max(m2)),
            **_stats("M4", np.concatenate([p.sliding_px for p in pairs])),
            "M5": float(np.mean(fl)), "M5_max": float(np.max(fl)),
            "M5_raw": float(np.mean(flr)), "M5_raw_max": float(np.max(flr)),
            "M5_blend": float(np.mean([p.flatness_blend for p in pairs])),
            **_stats("M7", np.concatenate([p.growth_px for p in pairs]))}


def frame_files(out_dir, pattern: str = "frame_{frame:04d}") -> list[Path]:
    """The frame JSON files of a folder named by `pattern` (render --pattern), sorted by name."""
    from .fileio import check_pattern

    check_pattern(pattern)
    d = Path(out_dir)
    if not d.exists():
        raise InputError("folder not found", d)
    if not d.is_dir():
        raise InputError("not a folder", d)
    glob = re.sub(r"\{frame[^}]*\}", "*", pattern) + ".json"
    # Exactly the names the pattern gives: {frame} is a number that formats back to the name
    # (shot_{frame:04d} must not take shot_0001_draft.json, nor a report frame_report.json).
    literal = re.split(r"\{frame[^}]*\}", pattern)
    exact = re.compile("(.+?)".join(re.escape(s) for s in literal) + r"\.json")

    def named_by_pattern(name: str) -> bool:
        m = exact.fullmatch(name)
        if m is None or len(set(m.groups())) != 1:
            return False
        # Some whole number must format back to the name, in any integer format ({frame:x},
        # {frame:<4}, {frame:,}); a longer name of another render (_draft) has none.
        text = m.group(1)
        digits = re.sub(r"[^0-9a-fA-F]", "", text)
        tries = set()
        for base in (10, 16, 8, 2):
            for s in (text.strip().replace(",", "").replace("_", ""), digits):
                try:
                    tries.add(int(s, base))
                except ValueError:
                    pass
        tries |= {-x for x in tries}  # ("{frame:=+5}" and fill characters: the sign stands apart)
        if len(text) == 1:
            tries.add(ord(text))  # {frame:c}
        for n in tries:
            try:
                if pattern.format(frame=n) + ".json" == name:
                    return True
            except (ValueError, OverflowError):
                continue
        return False

    files = sorted(p for p in d.glob(glob) if named_by_pattern(p.name))  # (not render's .strokekit-run.json)
    if len(files) < 2:
        hint = " (its frames have no JSON: render without --no-json)" if not files and any(d.glob(glob[:-5] + ".svg")) else ""
        raise InputError(f"needs at least 2 {glob} files to compare, found {len(files)}{hint}", d)
    return files


def folder_metrics(out_dir, pattern: str = "frame_{frame:04d}", **kw) -> tuple[list[PairMetrics], dict]:
    """Read every frame JSON of `out_dir` named by `pattern` (strokekit.writers.strokes_json
    format), in frame order, and return (per pair metrics, overall summary)."""
    from .writers.strokes_json import read_strokes_json

    frames = []
    for f in frame_files(out_dir, pattern):
        try:
            st = read_strokes_json(f)
        except (KeyError, ValueError, TypeError) as e:
            raise InputError(f"not a strokekit frame JSON ({type(e).__name__}: {e})", f) from None
        if st.camera is None:
            raise InputError("frame JSON has no camera: cannot project surface points", f)
        frames.append(st)
    frames.sort(key=lambda s: s.frame)
    return sequence_metrics(frames, **kw)
