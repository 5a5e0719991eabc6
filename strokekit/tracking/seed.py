"""The seed-000 baseline (strategies 1-5 of seed 000): a new stroke takes the id of a previous
stroke whose start it finds nearby, grows at most max_growth_px a frame, and short strokes are
not carried."""

from __future__ import annotations

import numpy as np

from strokekit.lines.strokeops import cut_pieces
from strokekit.model import Strokes, carry_points, row_norm
from strokekit.sampling import resample_strokes
from strokekit.tracking.options import TrackingOptions


class Seed:
    """`--coherence seed`."""

    name = "seed"

    def track(self, prev: Strokes, cur: Strokes, o: TrackingOptions, next_id: int) -> tuple[Strokes, int]:
        """The tracked `cur` given the previous frame's tracked strokes, and the next unused id."""
        return seed_step(prev, cur, o, next_id)


def seed_step(prev: Strokes, cur: Strokes, o: TrackingOptions, next_id: int) -> tuple[Strokes, int]:
    P = cur.period_px
    S = len(cur)
    L = cur.lengths
    carried = np.flatnonzero(prev.lengths >= o.min_carry_px)  # strategy 5
    dense = resample_strokes(cur, 1.0)
    claims: list[list[tuple[float, float]]] = [[] for _ in range(S)]
    pieces = []  # (stroke, s0, s1, reverse, id)
    if len(carried) and len(dense):
        from scipy.spatial import cKDTree

        st0 = prev.offsets[:-1][carried]
        # (in a moving scene, where the start's object has taken it since)
        X0 = carry_points(prev.surface[st0], prev.face[st0], prev.pose, cur.pose)
        d0 = prev.points[np.minimum(st0 + 1, prev.offsets[1:][carried] - 1)] - prev.points[st0]
        d0 = d0 / np.maximum(row_norm(d0), 1e-12)[:, None]
        q, z = cur.camera.project(X0)
        # A start now behind the camera projects mirrored to a finite pixel: it claims nothing.
        behind = ~((z > 0) | cur.camera.is_ortho)
        q = np.where(behind[:, None], np.nan, q)
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
    ids[fresh] = next_id + np.arange(len(fresh))
    next_id += len(fresh)
    K = len(out)
    return out.replace(ids=ids, u=out.arc_length / P, level=np.zeros(K), level_weight=np.ones(K)), next_id
