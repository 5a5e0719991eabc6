"""Strokes that persist along the camera path: ids, a parametrization that does not slide, and
self-similar texture levels. The tracking pass is the only stage that walks the frames in order;
everything before it (features, visibility, chaining) is per frame and independent.

`Tracker(options).step(strokes) -> strokes` takes one frame's strokes (as LineRenderer gives them)
and returns them with persistent `ids`, a coherent `u` (texture periods of `period_px` px) and the
self-similar `level` / `level_weight`. Three methods:

- "kalnins" (default; Kalnins et al. 2003, "Coherent Stylized Silhouettes"): the previous frame's
  strokes are sampled every `vote_spacing_px`; each sample carries its surface point X, its u and
  its stroke id. X is projected with the new camera and votes on the nearest new sample within
  `search_radius_px` whose tangent agrees (the same correspondence the metrics of BRIEF 3 use).
  Per new stroke the votes are grouped by the id they carry; the largest group fixes the stroke's
  direction (the stroke is reversed if needed so that u increases along it) and its id; the other
  groups are shifted by whole periods (the texture is periodic) to meet it, which heals strokes
  that merged. u = a + b s is then fitted per stroke by least squares: close to the votes (no
  sliding), and slope b close to the nominal 1/P (no stretch), weighted by `stretch_weight`;
  votes that disagree by more than `outlier_px` are dropped and the fit redone. Parts of a stroke
  without votes (growth) continue the fitted line; strokes without any vote start at u = s / P.
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

Split criteria (angle, maximum length) are LineOptions of the chaining stage.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .coherence import Samples, match_samples, resample_strokes
from .errors import UsageError
from .model import Strokes

METHODS = ("kalnins", "seed", "none")


@dataclass(frozen=True)
class TrackingOptions:
    """Options of the tracking pass. Pixel values are image pixels.

    method: "kalnins" | "seed" | "none". period_px: texture period P of u.
    search_radius_px, min_tangent_dot: correspondence of carried samples (BRIEF 3: 6 px, 0.65).
    vote_spacing_px: spacing of the samples carried from frame to frame (kalnins).
    stretch_weight: weight of "slope close to 1/P" against "u close to the votes" (kalnins); the
    drift of one period over a stroke costs like a uniform error of sqrt(stretch_weight) period.
    outlier_px: votes farther than this from the fit are dropped (kalnins).
    min_id_px: matched length needed for an id to persist.
    min_segment_px: a chain is cut between runs of votes carrying different ids (Kalnins' segments);
    runs shorter than this are absorbed by their neighbours (kalnins).
    max_growth_px, min_carry_px, seed_search_px, seed_angle_penalty_px: seed 000 strategies 3, 5,
    the neighbourhood of strategy 1 and the direction penalty (px per radian) of strategy 2."""

    method: str = "kalnins"
    period_px: float = 30.0
    search_radius_px: float = 6.0
    min_tangent_dot: float = 0.65
    vote_spacing_px: float = 4.0
    stretch_weight: float = 1e-3
    outlier_px: float = 3.0
    min_id_px: float = 2.0
    max_growth_px: float = 20.0
    min_carry_px: float = 10.0
    seed_search_px: float = 12.0
    seed_angle_penalty_px: float = 10.0
    min_segment_px: float = 10.0

    def __post_init__(self):
        if self.method not in METHODS:
            raise UsageError(f"unknown coherence method {self.method!r} (known: {', '.join(METHODS)})")
        for name in ("period_px", "search_radius_px", "vote_spacing_px", "seed_search_px"):
            if not getattr(self, name) > 0:
                raise UsageError(f"{name.replace('_', '-')} must be > 0, got {getattr(self, name)}")
        for name in ("stretch_weight", "outlier_px", "min_id_px", "max_growth_px", "min_carry_px",
                     "seed_angle_penalty_px"):
            if not getattr(self, name) >= 0:
                raise UsageError(f"{name.replace('_', '-')} must be >= 0, got {getattr(self, name)}")
        if not 0 <= self.min_tangent_dot <= 1:
            raise UsageError(f"min tangent dot must be in [0, 1], got {self.min_tangent_dot}")


# --- stroke surgery --------------------------------------------------------------------------

def cut_pieces(strokes: Strokes, stroke: np.ndarray, s0: np.ndarray, s1: np.ndarray,
               reverse: np.ndarray | None = None) -> Strokes:
    """Pieces of strokes: piece k is stroke[k] between arc lengths s0[k] < s1[k] (px), new end
    points interpolated (position, surface point; face of the nearer point), reversed where
    `reverse` is true. u is arc length / P, ids 0..K-1, kind, level and weight of the source.
    Vectorized over all pieces."""
    stroke = np.asarray(stroke, np.int64)
    K = len(stroke)
    if K == 0:
        return Strokes.empty(strokes.camera, strokes.frame, strokes.period_px)
    rev = np.zeros(K, bool) if reverse is None else np.asarray(reverse, bool)
    L = strokes.lengths
    base = np.r_[0.0, np.cumsum(L[:-1] + 1.0)]
    G = strokes.arc_length + np.repeat(base, np.diff(strokes.offsets))
    g0 = base[stroke] + np.asarray(s0, float)
    g1 = base[stroke] + np.asarray(s1, float)
    first = strokes.offsets[:-1][stroke]
    last = strokes.offsets[1:][stroke] - 1
    # Interior original points: G strictly inside (g0, g1).
    lo = np.maximum(np.searchsorted(G, g0, side="right"), first)
    hi = np.minimum(np.searchsorted(G, g1, side="left"), last + 1)
    n_in = np.maximum(hi - lo, 0)

    def at(g):
        j = np.clip(np.searchsorted(G, g, side="right"), first + 1, np.maximum(last, first + 1))
        j = np.minimum(j, len(G) - 1)
        i = np.maximum(j - 1, first)
        d = G[j] - G[i]
        a = np.clip(np.where(d > 0, (g - G[i]) / np.where(d > 0, d, 1.0), 0.0), 0, 1)
        p = strokes.points[i] * (1 - a)[:, None] + strokes.points[j] * a[:, None]
        X = strokes.surface[i] * (1 - a)[:, None] + strokes.surface[j] * a[:, None]
        f = np.where(a < 0.5, strokes.face[i], strokes.face[j])
        return p, X, f

    pa, Xa, fa = at(g0)
    pb, Xb, fb = at(g1)
    counts = n_in + 2
    offsets = np.r_[0, np.cumsum(counts)].astype(np.int64)
    N = int(offsets[-1])
    piece = np.repeat(np.arange(K), counts)
    pos = np.arange(N) - offsets[:-1][piece]  # position within the piece, 0..count-1
    src = lo[piece] + pos - 1  # original point index for interior positions
    interior = (pos > 0) & (pos < counts[piece] - 1)
    src = np.where(interior, src, 0)
    points = strokes.points[src].copy()
    surface = strokes.surface[src].copy()
    face = strokes.face[src].copy()
    head, tail = offsets[:-1], offsets[1:] - 1
    points[head], surface[head], face[head] = pa, Xa, fa
    points[tail], surface[tail], face[tail] = pb, Xb, fb
    if rev.any():
        # Reverse the point order inside reversed pieces.
        order = np.where(rev[piece], offsets[:-1][piece] + counts[piece] - 1 - pos, np.arange(N))
        points, surface, face = points[order], surface[order], face[order]
    src_s = stroke
    out = Strokes(points=points, surface=surface, face=face, offsets=offsets, kind=strokes.kind[src_s],
                  ids=np.arange(K, dtype=np.int64), u=np.zeros(N), level=strokes.level[src_s],
                  level_weight=strokes.level_weight[src_s], camera=strokes.camera, frame=strokes.frame,
                  period_px=strokes.period_px)
    return replace(out, u=out.arc_length / out.period_px)


def _segment_sums(idx: np.ndarray, n: int, *weights) -> list[np.ndarray]:
    return [np.bincount(idx, weights=w, minlength=n) for w in weights]


def assign_ids(n_strokes: int, cand_stroke: np.ndarray, cand_id: np.ndarray, cand_w: np.ndarray,
               next_id: int, min_w: float = 0.0) -> tuple[np.ndarray, int]:
    """Greedy one-to-one assignment of previous ids to new strokes by matched length: the
    heaviest (stroke, id) pair first (ties: lower stroke index, then lower id); each id and each
    stroke used once. Strokes left without an id get fresh ids next_id, next_id+1, ... in stroke
    order. Returns (ids (S,), new next_id)."""
    ids = np.full(n_strokes, -1, np.int64)
    keep = cand_w >= max(min_w, 1e-12)
    cs, ci, cw = cand_stroke[keep], cand_id[keep], cand_w[keep]
    order = np.lexsort((ci, cs, -np.round(cw, 9)))
    used = set()
    for k in order.tolist():  # one pass over candidate pairs (a few per stroke), not points
        s, i = int(cs[k]), int(ci[k])
        if ids[s] >= 0 or i in used:
            continue
        ids[s] = i
        used.add(i)
    fresh = np.flatnonzero(ids < 0)
    ids[fresh] = next_id + np.arange(len(fresh))
    return ids, next_id + len(fresh)


def levels_from_slope(slope_periods_per_px: np.ndarray, period_px: float) -> tuple[np.ndarray, np.ndarray]:
    """Self-similar octave level and blend weight (see module doc) from du/ds per stroke."""
    c = np.log2(np.maximum(np.abs(slope_periods_per_px) * period_px, 1e-6))
    level = np.floor(c)
    return level, 1.0 - (c - level)


def segment_by_votes(dense: Samples, vm: np.ndarray, vid: np.ndarray, w: np.ndarray, min_segment_px: float):
    """Cut the strokes sampled by `dense` (1 px samples, in stroke order) into runs of the same
    carried id. vm (V,) dense sample hit by each vote, vid (V,) its carried id, w (V,) its weight.
    Samples without a vote take the label of the nearest voted sample of their stroke; runs
    shorter than `min_segment_px` (except the longest of a stroke) are absorbed by neighbours.
    Returns run (D,) run of each dense sample, and per run: stroke, s0, s1 (px)."""
    D = len(dense)
    label = np.full(D, -1, np.int64)
    if len(vm):
        # Heaviest vote wins a sample (sorted ascending, the last write wins).
        o = np.lexsort((vid, w))
        label[vm[o]] = vid[o]
    idx = np.arange(D)
    stroke, s = dense.stroke, dense.s

    def fill(lab):
        known = lab >= 0
        f = np.maximum.accumulate(np.where(known, idx, -1))
        b = np.minimum.accumulate(np.where(known, idx, D)[::-1])[::-1]
        fok = (f >= 0) & (stroke[np.maximum(f, 0)] == stroke)
        bok = (b < D) & (stroke[np.minimum(b, D - 1)] == stroke)
        df = np.where(fok, s - s[np.maximum(f, 0)], np.inf)
        db = np.where(bok, s[np.minimum(b, D - 1)] - s, np.inf)
        out = np.where(df <= db, lab[np.maximum(f, 0)], lab[np.minimum(b, D - 1)])
        return np.where(fok | bok, out, -1)

    def runs(lab):
        start = np.r_[True, (lab[1:] != lab[:-1]) | (stroke[1:] != stroke[:-1])] if D else np.zeros(0, bool)
        r = np.cumsum(start) - 1
        return r, np.bincount(r, weights=dense.w) if D else np.zeros(0)

    lab = fill(label)
    for _ in range(4):
        r, rl = runs(lab)
        if len(rl) == 0:
            break
        rs = stroke[np.flatnonzero(np.r_[True, r[1:] != r[:-1]])]
        longest = np.zeros(len(rl), bool)
        o = np.lexsort((-rl, rs))
        longest[o[np.r_[True, rs[o][1:] != rs[o][:-1]]]] = True
        short = (rl < min_segment_px) & ~longest & (lab[np.flatnonzero(np.r_[True, r[1:] != r[:-1]])] >= 0)
        if not short.any():
            break
        lab = fill(np.where(short[r], -1, lab))
    r, rl = runs(lab)
    first = np.flatnonzero(np.r_[True, r[1:] != r[:-1]]) if D else np.zeros(0, np.int64)
    last = np.r_[first[1:] - 1, D - 1] if D else np.zeros(0, np.int64)
    return r, stroke[first], s[first] - 0.5 * dense.w[first], s[last] + 0.5 * dense.w[last]


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
        """The tracked version of one frame's strokes (same lines; ids, u, level set; strokes may
        be reversed, and re-cut by the "seed" method). The camera of `strokes` is required for
        carrying samples from the previous frame."""
        o = self.options
        strokes = replace(strokes, period_px=o.period_px)
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
        return replace(strokes, ids=ids, u=strokes.arc_length / self.options.period_px,
                       level=np.zeros(S), level_weight=np.ones(S))

    # -- Kalnins 2003
    def _kalnins(self, cur: Strokes) -> Strokes:
        o = self.options
        P = o.period_px
        prev = self.prev
        votes = resample_strokes(prev, o.vote_spacing_px)
        dense = resample_strokes(cur, 1.0)
        m = match_samples(votes, cur.camera, dense, radius_px=o.search_radius_px, min_tangent_dot=o.min_tangent_dot)
        hit = m >= 0
        vm = m[hit]
        u = votes.u[hit]
        vid = votes.ids[hit]
        w = votes.w[hit]
        sign = np.sign(np.einsum("ij,ij->i", votes.t[hit], dense.t[vm]))
        # Segments (Kalnins' brush path segments): each new chain is cut where the id its votes
        # carry changes, so a chain that now runs through two old strokes keeps both ids.
        run, r_stroke, r_s0, r_s1 = segment_by_votes(dense, vm, vid, w, o.min_segment_px)
        st = run[vm]
        s = dense.s[vm] - r_s0[st]
        S = len(r_stroke)
        L = r_s1 - r_s0
        # Direction: previous strokes have u increasing along them; a segment whose samples run
        # against the voters' tangents is reversed (seed 000 strategy 2, in vote form).
        flip = np.bincount(st, weights=w * sign, minlength=S) < 0
        cur = cut_pieces(cur, r_stroke, r_s0, r_s1, flip)
        L = cur.lengths  # same lengths up to rounding
        s = np.clip(np.where(flip[st], L[st] - s, s), 0, L[st])
        # Vote groups: (stroke, carried id).
        if len(st):
            key = np.stack([st, vid], axis=1)
            gkeys, ginv = np.unique(key, axis=0, return_inverse=True)
            ginv = ginv.ravel()
            gw = np.bincount(ginv, weights=w)
        else:
            gkeys, ginv, gw = np.zeros((0, 2), np.int64), np.zeros(0, np.int64), np.zeros(0)
        # Primary group per stroke: most matched length, ties to the lower id (gkeys sorted).
        order = np.lexsort((gkeys[:, 1], -gw, gkeys[:, 0])) if len(gw) else np.zeros(0, np.int64)
        primary = np.zeros(len(gw), bool)
        if len(order):
            gs = gkeys[order, 0]
            primary[order[np.r_[True, gs[1:] != gs[:-1]]]] = True
        b0 = 1.0 / P
        lam = o.stretch_weight * L ** 3  # see TrackingOptions.stretch_weight

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
            res = np.abs(u - (a[st] + b[st] * s)) * P
            inlier = (res <= o.outlier_px).astype(float)
            a2, b2, ok2 = fit(inlier)
            a, b, ok = np.where(ok2, a2, a), np.where(ok2, b2, b), ok | ok2
            if len(gw):
                gw_in = np.bincount(ginv, weights=w * inlier, minlength=len(gw))
            cand_s, cand_i, cand_w = gkeys[:, 0], gkeys[:, 1], gw_in
        else:
            a, b, ok = np.zeros(S), np.full(S, b0), np.zeros(S, bool)
            cand_s = cand_i = np.zeros(0, np.int64)
            cand_w = np.zeros(0)
        b = np.where(ok, np.maximum(b, 1e-3 * b0), b0)  # never fold the texture back
        sop = cur.stroke_of_point
        u_new = a[sop] + b[sop] * cur.arc_length
        ids, self.next_id = assign_ids(S, cand_s, cand_i, cand_w, self.next_id, o.min_id_px)
        level, weight = levels_from_slope(b, P)
        return replace(cur, ids=ids, u=u_new, level=level, level_weight=weight)

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
            d0 = prev.points[st0 + 1] - prev.points[st0]
            d0 = d0 / np.maximum(np.linalg.norm(d0, axis=1), 1e-12)[:, None]
            q, z = cur.camera.project(X0)
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
        return replace(out, ids=ids, u=out.arc_length / P, level=np.zeros(K), level_weight=np.ones(K))


def track_frames(frames: list[Strokes], options: TrackingOptions | None = None) -> list[Strokes]:
    """Track a list of frames in order (convenience for tests and benchmarks)."""
    tr = Tracker(options)
    return [tr.step(f) for f in frames]
