"""Visibility of feature edges (BRIEF 2): clipping, screen-space sampling, Embree occlusion rays
and bisection of every visibility change.

A point X is visible when the open segment from X to the eye meets no triangle. The ray starts a
small offset (relative to the scene radius, never absolute) from X toward the eye. The Embree
scene is built in coordinates centred on the scene and scaled to unit radius: float32 keeps its
precision far from the origin, and a scene scaled or moved as a whole gives Embree the same
numbers, so the same occlusion answers (the strokes are invariant under similarity).
"""

from __future__ import annotations

import numpy as np

from strokekit.camera.view import Camera
from strokekit.lines.sightlines import visible, visible_local, visible_rows
from strokekit.model import FeatureEdges, VisibleRuns, row_norm
from strokekit.options import LineOptions
from strokekit.scene.occluder import Occluder


def clipped_on_screen(a: np.ndarray, b: np.ndarray, camera: Camera, near: float):
    """World segments a -> b (N, 3) clipped to the view and projected: t0, t1 (N,) the clip
    (clip_segments), idx (M,)
    the segments with something left (a segment clipped to a single point still counts when it
    is not degenerate in 3D), ab (M, 3) their world direction b - a, A, B (M, 3) the clipped
    ends, pa, pb (M, 2) px and za, zb (M,) their projections and depths, L (M,) screen length px."""
    t0, t1 = clip_segments(a, b, camera, near)
    idx = np.flatnonzero(t1 > t0 + 0.0)
    a_i, b_i = np.take(a, idx, axis=0), np.take(b, idx, axis=0)
    ab = b_i - a_i
    A = a_i + t0[idx, None] * ab
    B = a_i + t1[idx, None] * ab
    pa, za = camera.project(A)
    pb, zb = camera.project(B)
    return t0, t1, idx, ab, A, B, pa, za, pb, zb, row_norm(pb - pa)


def world_between(A: np.ndarray, B: np.ndarray, za: np.ndarray, zb: np.ndarray, ortho: bool,
                  seg_i: np.ndarray, s_i: np.ndarray) -> np.ndarray:
    """World points of segments A -> B (M, 3) at screen fractions s_i (K,) along segments seg_i
    (K,): perspective-correct from the ends' depths za, zb (M,); linear for parallel cameras."""
    if ortho:
        lam = s_i
    else:
        z0, z1 = za.take(seg_i), zb.take(seg_i)
        lam = s_i * z0 / ((1 - s_i) * z1 + s_i * z0)
    A_i = A.take(seg_i, axis=0)  # (take: fancy indexing of rows costs several times more)
    return A_i + lam[:, None] * (B.take(seg_i, axis=0) - A_i)


def clip_segments(a: np.ndarray, b: np.ndarray, camera: Camera, near: float) -> tuple[np.ndarray, np.ndarray]:
    """Parametric clip of world segments a + t (b - a) against the near plane and the four image
    borders (Cyrus-Beck against the view frustum, seed 001 section 5). Returns (t0, t1), each (N,);
    t0 > t1 where nothing is left."""
    right, up, fwd = camera.basis
    eye = np.asarray(camera.eye, float)
    qa, qb = a - eye, b - eye
    W, H, f = camera.width, camera.height, camera.focal_px
    cam_a = np.stack([qa @ right, qa @ up, qa @ fwd], axis=1)
    cam_b = np.stack([qb @ right, qb @ up, qb @ fwd], axis=1)
    xa, ya, za = cam_a.T
    xb, yb, zb = cam_b.T
    if camera.is_oblique:  # the image-plane offsets of a sheared parallel projection
        kx, ky = camera.shear
        xa, ya, xb, yb = xa + kx * za, ya + ky * za, xb + kx * zb, yb + ky * zb
    # g >= 0 inside, linear along the segment: near plane, then left, right, top, bottom.
    if camera.is_ortho:
        planes = [(za - near, zb - near), (f * xa + W / 2, f * xb + W / 2), (W / 2 - f * xa, W / 2 - f * xb),
                  (f * ya + H / 2, f * yb + H / 2), (H / 2 - f * ya, H / 2 - f * yb)]
    else:
        planes = [(za - near, zb - near), (f * xa + W / 2 * za, f * xb + W / 2 * zb),
                  (W / 2 * za - f * xa, W / 2 * zb - f * xb), (f * ya + H / 2 * za, f * yb + H / 2 * zb),
                  (H / 2 * za - f * ya, H / 2 * zb - f * yb)]
    t0 = np.zeros(len(a))
    t1 = np.ones(len(a))
    # Segments with both ends inside every plane keep [0, 1]; the clip below runs on the others
    # only (elementwise, so the same numbers as running it on all).
    g = np.stack([x for pair in planes for x in pair])
    cut = np.flatnonzero((g < 0).any(axis=0))
    if len(cut) == 0:
        return t0, t1
    g = g[:, cut]
    c0, c1 = t0[cut], t1[cut]
    for k in range(0, len(g), 2):
        ga, gb = g[k], g[k + 1]
        denom = ga - gb
        with np.errstate(divide="ignore", invalid="ignore"):
            t = ga / denom
        enter = (ga < 0) & (gb >= 0)
        leave = (ga >= 0) & (gb < 0)
        out = (ga < 0) & (gb < 0)
        c0 = np.where(enter, np.maximum(c0, t), c0)
        c1 = np.where(leave, np.minimum(c1, t), c1)
        c1 = np.where(out, -1.0, c1)
    t0[cut], t1[cut] = c0, c1
    return t0, t1


def _runs_from_changes(start_visible: np.ndarray, end_visible: np.ndarray, cs: np.ndarray, s_change: np.ndarray,
                       rising: np.ndarray):
    """Visible runs (segment, s0, s1), sorted by segment and s0, from the segments visible at their
    start (start_visible) and at their end (end_visible) and the changes of visibility: segment
    cs at parameter s_change, hidden -> visible where `rising`. Runs of zero length are kept."""
    on_seg = np.concatenate([start_visible, cs[rising]])
    on_s = np.concatenate([np.zeros(len(start_visible)), s_change[rising]])
    off_seg = np.concatenate([end_visible, cs[~rising]])
    off_s = np.concatenate([np.ones(len(end_visible)), s_change[~rising]])
    o_on = np.lexsort((on_s, on_seg))
    o_off = np.lexsort((off_s, off_seg))
    run_seg = on_seg[o_on]
    s0, s1 = on_s[o_on], off_s[o_off]
    assert np.array_equal(run_seg, off_seg[o_off]), "visibility events must pair up"
    good = s1 >= s0
    return run_seg[good], s0[good], s1[good]


def visible_runs(features: FeatureEdges, camera: Camera, occluder: Occluder, options: LineOptions,
                 scene_radius: float) -> VisibleRuns:
    """Clip, sample every `sample_spacing_px` on screen, test occlusion, bisect each change to
    `bisection_tol_px`, and return the visible pieces; segments shorter than `whole_edge_px` on
    screen are tested at their middle only and kept whole or dropped."""
    a, b = features.a, features.b
    near = camera.near_distance(scene_radius)
    if (not options.bisect_changes and features.lift is not None and not camera.is_ortho
            and occluder.backend == "open3d"):
        return _visible_runs_sampled(features, camera, occluder, options, near)
    t0, t1, idx, ab, A, B, pa, za, pb, zb, L = clipped_on_screen(a, b, camera, near)
    n_int = np.maximum(1, np.ceil(L / options.sample_spacing_px).astype(np.int64))
    # Samples: n_int + 1 per segment, uniform in screen space; one, in the middle, for a segment
    # shorter than whole_edge_px (it is both its first and last sample: the segment becomes one
    # run or none, with no change to bisect).
    whole = L < options.whole_edge_px
    counts = np.where(whole, 1, n_int + 1)
    starts = np.cumsum(counts) - counts
    seg = np.repeat(np.arange(len(idx)), counts)
    k = np.arange(counts.sum()) - np.repeat(starts, counts)
    s = np.where(whole[seg], 0.5, k / np.repeat(n_int, counts))

    def world_at(seg_i, s_i):
        return world_between(A, B, za, zb, camera.is_ortho, seg_i, s_i)

    lift = None if features.lift is None else features.lift[idx]
    # Local size for the ray offset: the segment's world length (see sightlines.visible).
    size = row_norm(ab)
    offset = options.occlusion_offset
    retest = options.retest_front_hits
    if lift is not None and not camera.is_ortho and occluder.backend == "open3d":
        # The same samples and rays on (3, N) rows (sightlines.visible_rows): the per-segment
        # arrays are gathered once for the samples and once for the bisected changes.
        At, Dt, liftT = A.T.copy(), (B - A).T.copy(), lift.T.copy()

        def visible_at(seg_i, s_i):
            z0, z1 = za.take(seg_i), zb.take(seg_i)
            lam = s_i * z0 / ((1 - s_i) * z1 + s_i * z0)
            return visible_rows(occluder, At.take(seg_i, axis=1) + lam * Dt.take(seg_i, axis=1), camera, offset,
                                         liftT.take(seg_i, axis=1), size.take(seg_i),
                                         retest)

        def bisect_visible(cs):
            """visible(m, mid): visibility at parameters mid (m,) of the first m changes cs."""
            A_c, D_c, lift_c, size_c = At.take(cs, axis=1), Dt.take(cs, axis=1), liftT.take(cs, axis=1), size.take(cs)
            z0, z1 = za.take(cs), zb.take(cs)

            def at(mid, m):
                lam = mid * z0[:m] / ((1 - mid) * z1[:m] + mid * z0[:m])
                return visible_rows(occluder, A_c[:, :m] + lam * D_c[:, :m], camera, offset, lift_c[:, :m], size_c[:m],
                                             retest)
            return at
    else:
        def visible_at(seg_i, s_i):
            return visible(occluder, world_at(seg_i, s_i), camera, offset,
                                    None if lift is None else lift[seg_i], size[seg_i])

        def bisect_visible(cs):
            return lambda mid, m: visible_at(cs[:m], mid)
    vis = visible_at(seg, s)
    # Changes of visibility between consecutive samples of one segment.
    same = seg[1:] == seg[:-1]
    change = np.flatnonzero(same & (vis[1:] != vis[:-1]))
    if len(change):
        cs = seg[change]
        lo, hi = s[change].copy(), s[change + 1].copy()
        vis_lo = vis[change]
        # Each bracket halves until it is within the tolerance: short edges' brackets need fewer
        # steps. Sorted by their number of steps, the brackets still open are a prefix.
        if not options.bisect_changes:  # the middle of the bracket
            lo = hi = 0.5 * (lo + hi)
        else:
            width_px = (hi - lo) * L[cs]
            steps = np.ceil(np.log2(np.maximum(width_px, 1e-300) / options.bisection_tol_px))
            steps = np.maximum(steps, 0).astype(np.int64)
            order = np.argsort(-steps, kind="stable")
            cs, lo, hi, vis_lo, steps = cs[order], lo[order], hi[order], vis_lo[order], steps[order]
            visible_mid = bisect_visible(cs)
            for i in range(int(steps[0])):
                m = int(np.searchsorted(-steps, -i, side="left"))  # brackets with steps > i
                mid = 0.5 * (lo[:m] + hi[:m])
                go_hi = visible_mid(mid, m) == vis_lo[:m]  # the change lies in [mid, hi]
                lo[:m] = np.where(go_hi, mid, lo[:m])
                hi[:m] = np.where(go_hi, hi[:m], mid)
        # The run endpoint is the visible side of the final bracket.
        s_change = np.where(vis_lo, lo, hi)
        rising = ~vis_lo  # hidden -> visible: a run starts
    else:
        cs = np.zeros(0, np.int64)
        s_change = np.zeros(0)
        rising = np.zeros(0, bool)
    seg_ids = np.arange(len(idx))
    run_seg, s0, s1 = _runs_from_changes(seg_ids[vis[starts]], seg_ids[vis[starts + counts - 1]], cs, s_change,
                                         rising)
    X0, X1 = world_at(run_seg, s0), world_at(run_seg, s1)
    p0, _ = camera.project(X0)
    p1, _ = camera.project(X1)
    return visible_runs_of(features, idx[run_seg], t0, t1, s0, s1, X0, X1, p0, p1)


def visible_runs_of(features: FeatureEdges, fe, t0, t1, s0, s1, X0, X1, p0, p1) -> VisibleRuns:
    """VisibleRuns of the runs on feature edges fe, each from parameter s0 to s1 of its clipped
    segment (t0, t1: the clip of every feature edge). A run end keys on its mesh vertex where it
    is the unclipped edge end (so chaining links runs through shared vertices), on a fresh
    negative key otherwise."""
    r = len(fe)
    unique_key = -(np.arange(2 * r, dtype=np.int64) + 1)
    va, vb = features.va[fe], features.vb[fe]
    key0 = np.where((s0 == 0.0) & (t0[fe] == 0.0) & (va >= 0), va, unique_key[0::2])
    key1 = np.where((s1 == 1.0) & (t1[fe] == 1.0) & (vb >= 0), vb, unique_key[1::2])
    return VisibleRuns(edge=fe, X0=X0, X1=X1, p0=p0, p1=p1, key0=key0, key1=key1, kind=features.kind[fe],
                       face=features.face[fe])


def _visible_runs_sampled(features: FeatureEdges, camera: Camera, occluder: Occluder, options: LineOptions,
                          near: float) -> VisibleRuns:
    """visible_runs without bisection (`bisect_changes` False, the draft preset) for a
    perspective camera, the open3d backend and lifted rays: every sample in one Embree call, and
    each visibility change placed in the middle of the bracket between its two samples (within
    sample_spacing_px / 2 of the change). Segments whose ends project inside the image are not
    clipped; segments shorter than `whole_edge_px` (most of a draft frame) are one ray each and,
    when visible, one run whose ends are the segment's ends, taken as they are (no
    re-projection); only the longer segments go through sampling and run assembly. The rays are
    built in the Embree frame (sightlines.visible_local), in float64 and rounded to float32 once at
    the end, as the other path does: built in float32, a ray from an edge resting on a floor, seen
    at a grazing angle, started inside the floor."""
    a, b = features.a, features.b
    N = len(a)
    W, H = camera.width, camera.height
    p, z = camera.project_fused(np.concatenate([a, b]))
    with np.errstate(invalid="ignore"):
        ok = (z >= near) & (p[:, 0] >= 0.0) & (p[:, 0] <= W) & (p[:, 1] >= 0.0) & (p[:, 1] <= H)
    out = np.flatnonzero(~(ok[:N] & ok[N:]))
    t0, t1 = np.zeros(N), np.ones(N)
    A, B = a, b
    pa, pb, za, zb = p[:N], p[N:], z[:N], z[N:]
    if len(out):  # clip the others (Cyrus-Beck) and project their clipped ends
        a_o, b_o = a.take(out, axis=0), b.take(out, axis=0)
        t0o, t1o = clip_segments(a_o, b_o, camera, near)
        t0[out], t1[out] = t0o, t1o
        ab_o = b_o - a_o
        A, B = a.copy(), b.copy()
        A_o, B_o = a_o + t0o[:, None] * ab_o, a_o + t1o[:, None] * ab_o
        A[out], B[out] = A_o, B_o
        po, zo = camera.project_fused(np.concatenate([A_o, B_o]))
        pa, pb, za, zb = pa.copy(), pb.copy(), za.copy(), zb.copy()
        pa[out], pb[out], za[out], zb[out] = po[:len(out)], po[len(out):], zo[:len(out)], zo[len(out):]
    idx = np.flatnonzero(t1 > t0)
    lift = features.lift
    if len(idx) < N:
        A, B, pa, pb = A.take(idx, axis=0), B.take(idx, axis=0), pa.take(idx, axis=0), pb.take(idx, axis=0)
        za, zb, a, b, lift = za[idx], zb[idx], a.take(idx, axis=0), b.take(idx, axis=0), lift.take(idx, axis=0)
    D = B - A
    L = row_norm(pb - pa)
    whole = L < options.whole_edge_px
    w_seg = np.flatnonzero(whole)
    l_seg = np.flatnonzero(~whole)
    nw = len(w_seg)
    # Samples: the middle of every short segment, then n_int + 1 along every long one.
    n_int = np.maximum(1, np.ceil(L[l_seg] / options.sample_spacing_px).astype(np.int64))
    counts = n_int + 1
    starts = np.cumsum(counts) - counts
    seg_l = np.repeat(l_seg, counts)
    s_l = (np.arange(len(seg_l)) - np.repeat(starts, counts)) / np.repeat(n_int, counts)
    seg = np.concatenate([w_seg, seg_l])
    s = np.concatenate([np.full(nw, 0.5), s_l])
    # Per segment, in the Embree frame: start, direction, lift, local size.
    k = occluder.inv_scale
    At = (A.T - occluder.origin[:, None]) * k
    Dt = (D * k).T
    liftT = (lift * k).T
    size = row_norm(b - a) * k  # the segment's world length (sightlines.visible)
    offset, retest = options.occlusion_offset, options.retest_front_hits

    def lam_at(seg_i, s_i):
        z0, z1 = za.take(seg_i), zb.take(seg_i)
        return s_i * z0 / ((1 - s_i) * z1 + s_i * z0)

    lam = lam_at(seg, s)
    P = At.take(seg, axis=1) + lam * Dt.take(seg, axis=1)
    vis = visible_local(occluder, P, camera, offset, liftT.take(seg, axis=1), size.take(seg), retest)
    runs_w = w_seg[vis[:nw]]
    vis_l = vis[nw:]
    if len(vis_l):
        # A visible sample whose neighbours along its segment are hidden stands for a piece
        # narrower than two spacings that one sample cannot size: without bisection it would be
        # drawn a spacing long, where `exact` mostly finds a sliver under half a pixel. Dropped.
        last = starts + counts - 1
        prev_vis = np.empty(len(vis_l), bool)
        prev_vis[1:] = vis_l[:-1]
        prev_vis[starts] = False
        next_vis = np.empty(len(vis_l), bool)
        next_vis[:-1] = vis_l[1:]
        next_vis[last] = False
        vis_l = vis_l & (prev_vis | next_vis)
    # Long segments: a change between consecutive samples is placed between them.
    same = seg_l[1:] == seg_l[:-1]
    change = np.flatnonzero(same & (vis_l[1:] != vis_l[:-1]))
    cs = seg_l[change]
    s_change = 0.5 * (s_l[change] + s_l[change + 1])
    rising = ~vis_l[change]
    run_l, s0_l, s1_l = _runs_from_changes(l_seg[vis_l[starts]], l_seg[vis_l[starts + counts - 1]], cs, s_change,
                                           rising)
    A_l, D_l = np.take(A, run_l, axis=0), np.take(D, run_l, axis=0)
    X0_l = A_l + lam_at(run_l, s0_l)[:, None] * D_l
    X1_l = A_l + lam_at(run_l, s1_l)[:, None] * D_l
    m = len(run_l)
    p_l, _ = camera.project_fused(np.concatenate([X0_l, X1_l]))
    # Both kinds of runs, in segment order (a long segment's runs are in order along it).
    run_seg = np.concatenate([runs_w, run_l])
    order = np.argsort(run_seg, kind="stable")
    run_seg = run_seg[order]
    s0 = np.concatenate([np.zeros(len(runs_w)), s0_l])[order]
    s1 = np.concatenate([np.ones(len(runs_w)), s1_l])[order]
    X0 = np.concatenate([np.take(A, runs_w, axis=0), X0_l]).take(order, axis=0)
    X1 = np.concatenate([np.take(B, runs_w, axis=0), X1_l]).take(order, axis=0)
    p0 = np.concatenate([np.take(pa, runs_w, axis=0), p_l[:m]]).take(order, axis=0)
    p1 = np.concatenate([np.take(pb, runs_w, axis=0), p_l[m:]]).take(order, axis=0)
    return visible_runs_of(features, idx[run_seg], t0, t1, s0, s1, X0, X1, p0, p1)
