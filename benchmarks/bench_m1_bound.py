"""Where the brush paths' M1 goes: the best M1 their ids could reach, and the lost length by cause.

For each model: the brush paths of a 120-frame orbit (3 degrees a frame, 1024 x 1024, PathOptions(),
as `benchmarks/bench_brush.py` draws them). For every pair of frames (f-1, f), the metric's own
correspondence (BRIEF 3, strokekit.sampling.match_samples, both ways, 1 px samples) gives W[i, j],
the matched length (px) between path i of frame f-1 and path j of frame f. M1 = the length of the
cells whose ids are equal / all matched length.

- bound: the per-pair best, a maximum-weight one-to-one matching of W for every pair
  (scipy linear_sum_assignment). It is also reachable by one id chain over the whole sequence:
  M1 compares consecutive frames only and a one-to-one matching keeps ids unique within a frame,
  so giving each path of frame f the id of its partner in f-1 (and fresh ids to the others) scores
  every pair's best at once. What it leaves out is what the paths themselves cost (which strokes
  exist): a path that splits, one strand beside another.
- causes: every cell of two different ids, by the first that applies: the two paths' kinds
  differ ("kind change"); either is shorter than 20 px ("short strand"); else by whether the old
  id lives on in frame f and whether the new id was in frame f-1 ("split", "merge", "swap",
  "relabel"). "[assignable]" cells are in the best matching (ids could win them), "[bound]"
  cells are not (the paths' shapes lose them).

- --drop-short L1,L2,...: what the short strands cost and give. The paths under L px are removed
  from every frame (ids unchanged), then M1 and the recall at 2 px of the exact lines (every 4th
  frame) are measured again: the most M1 that strokes built without those strands could keep,
  against the lines they would leave undrawn.

    python benchmarks/bench_m1_bound.py [--models bunny,fandisk] [--frames 120] [--size 1024] [--drop-short 5,20]
"""

from __future__ import annotations

import argparse

import numpy as np
from bench_brush import FILES, MODELS
from scipy.optimize import linear_sum_assignment
from scipy.spatial import cKDTree

from strokekit.camera.paths import orbit_path
from strokekit.lines.renderer import LineRenderer
from strokekit.metrics.accuracy import accuracy
from strokekit.metrics.coherence import sequence_metrics
from strokekit.model import N_KINDS
from strokekit.options import LineOptions
from strokekit.paths import PathOptions, PathTracker
from strokekit.sampling import match_samples, resample_strokes
from strokekit.scene.load import load_scene

SHORT_PX = 20.0


def pair_cells(A, B, a, b) -> np.ndarray:
    """W (len(A), len(B)): matched length (px) between the paths of two frames (samples a, b)."""
    ab = match_samples(a, B.camera, b, cKDTree(b.p), exact=True)
    ba = match_samples(b, A.camera, a, cKDTree(a.p), exact=True)
    ma, mb = ab >= 0, ba >= 0
    W = np.zeros((len(A), len(B)))
    np.add.at(W, (np.concatenate([a.stroke[ma], a.stroke[ba[mb]]]), np.concatenate([b.stroke[ab[ma]], b.stroke[mb]])),
              np.concatenate([a.w[ma], b.w[mb]]))
    return W


def cause(A, B, i: int, j: int, ida: set, idb: set) -> str:
    if A.kind[i] % N_KINDS != B.kind[j] % N_KINDS:
        return "kind change"
    if min(A.lengths[i], B.lengths[j]) < SHORT_PX:
        return f"short (<{SHORT_PX:.0f} px) strand"
    lives, old = int(A.ids[i]) in idb, int(B.ids[j]) in ida
    if lives and old:
        return "swap: two persisting ids"
    if lives:
        return "split: part of an old path, new id"
    if old:
        return "merge: old path taken by another"
    return "relabel: old id ends, new starts"


def analyse(frames) -> None:
    smp = [resample_strokes(f, 1.0) for f in frames]
    matched = same = best = 0.0
    lost: dict[str, float] = {}
    for f in range(1, len(frames)):
        A, B = frames[f - 1], frames[f]
        W = pair_cells(A, B, smp[f - 1], smp[f])
        eq = A.ids[:, None] == B.ids[None, :]
        matched += W.sum()
        same += W[eq].sum()
        r, c = linear_sum_assignment(-W)
        best += W[r, c].sum()
        opt = np.zeros_like(eq)
        opt[r, c] = True
        ida, idb = set(A.ids.tolist()), set(B.ids.tolist())
        for i, j in zip(*np.nonzero((W > 0) & ~eq)):
            k = cause(A, B, i, j, ida, idb) + (" [assignable]" if opt[i, j] else " [bound]")
            lost[k] = lost.get(k, 0.0) + W[i, j]
    miss = matched - same
    print(f"  M1 {same / matched:.4f}   per-pair best (= best id chain) {best / matched:.4f}   "
          f"lost {miss:.0f} of {matched:.0f} px matched, {best - same:.0f} px of it to ids")
    for k, v in sorted(lost.items(), key=lambda kv: -kv[1]):
        print(f"    {k:48} {v:9.0f} px {v / max(miss, 1e-9):6.1%}  (M1 {v / matched:.4f})")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--models", default="bunny,fandisk")
    ap.add_argument("--frames", type=int, default=120)
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--drop-short", default="", help="lengths (px, comma-separated): M1 and R@2 without the paths under each")
    a = ap.parse_args()
    for name in a.models.split(","):
        sc = load_scene(MODELS / FILES[name])
        r = LineRenderer(sc, LineOptions())
        orbit = orbit_path(sc.center, sc.radius, a.frames, degrees_per_frame=3.0, width=a.size, height=a.size)
        tr = PathTracker(PathOptions())
        frames = [tr.step(r.render(cam, k + 1)).strokes for k, cam in enumerate(orbit.cameras)]
        print(f"{name}: {a.frames}-frame orbit, brush paths")
        analyse(frames)
        if a.drop_short:
            ex = LineRenderer(sc, LineOptions.preset("exact", doubled_px=0.0))
            ks = list(range(0, a.frames, 4))
            exact = [ex.render(orbit.cameras[k], k + 1) for k in ks]
            for L in [0.0] + [float(x) for x in a.drop_short.split(",")]:
                kept = [f.select(f.lengths >= L) for f in frames]
                m1 = sequence_metrics(kept)[1]["M1"]
                r2 = accuracy([kept[k] for k in ks], exact, tols=(2.0,)).recall[2.0]
                share = sum(f.lengths.sum() for f in kept) / max(sum(f.lengths.sum() for f in frames), 1e-9)
                print(f"  without paths under {L:4.0f} px: M1 {m1:.4f}   R@2 {r2:.4f}   {share:6.1%} of the length drawn")


if __name__ == "__main__":
    main()
