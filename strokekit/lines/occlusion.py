"""Occlusion levels of feature edges: the pieces of every candidate edge with the number
of surfaces that hide them (Freestyle's quantitative invisibility, Line Art's occlusion levels),
split where the level changes, for hidden-line drawings (`LineOptions.occlusion`).

The level of a point is the number of triangles the open segment from it to the eye (parallel
cameras: along the projection rays, to the near plane) crosses, its own faces excluded
(level 0 is visible; `lines.levels` counts them, every hit of a ray from one Embree call).

Where levels change (Appel's observation, the basis of Freestyle's QI): a ray from a point on
the edge gains or loses surfaces where the point passes behind the outline of the scene (its
contour edges, borders, non-manifold edges) in the image. So every clipped edge is cut where its
image crosses the image of an outline edge lying in front of it (`outline_crossings`: exact to
float64, no tolerance), and one level is counted per piece: nearly every change of level lies at
such a crossing. The other changes
(an edge that pierces a surface, faces the camera sees edge-on, the rounding at a grazing ray)
are caught as in `visibility.visible_runs`: a piece longer than `sample_spacing_px` gets a
sample every spacing, and a change between two samples is bisected to `bisection_tol_px` (a
middle with a third level splits the bracket: 0 -> 1 -> 2 between two samples gives two
changes). A piece after a crossing whose change Appel's rule gives clearly (`crossing_deltas`)
takes the level before it plus that change instead of a ray, as long as the next counted sample
of its edge agrees (`_sample_levels`).

A piece's level is written into its kind: code = kind + len(KINDS) * level (model.MAX_OCCLUSION),
so that chaining, the cleanup of doubled lines and tracking, which keep kinds apart, keep levels
apart too, and a stroke has one level.
"""

from __future__ import annotations

import numpy as np

from strokekit.camera.view import Camera
from strokekit.lines.facing import FrameView
from strokekit.lines.kernels import kernels
from strokekit.lines.levels import levels
from strokekit.lines.visibility import clip_segments, clipped_on_screen, visible_runs_of, world_between
from strokekit.model import MAX_OCCLUSION, N_KINDS, FeatureEdges, VisibleRuns, row_norm
from strokekit.options import LineOptions
from strokekit.scene.load import Scene
from strokekit.scene.occluder import Occluder

#: Halvings at most (a 2^60 px bracket): the loop ends when every bracket is within tolerance.
MAX_HALVINGS = 60
#: Image-space grid cell (px) for finding the pairs of edges that may cross.
GRID_PX = 8.0


def occlusion_runs(features: FeatureEdges, view: FrameView, occluder: Occluder, options: LineOptions) -> VisibleRuns:
    """The pieces of the feature edges whose occlusion level lies in `options.occlusion`
    (lo, hi), each with its level in its kind code. Without `bisect_changes` (the draft preset)
    a change between two samples lies in the middle of their bracket; changes at outline
    crossings are exact in every preset."""
    scene, camera = view.scene, view.camera
    lo_level, hi_level = options.occlusion
    limit = min(hi_level, MAX_OCCLUSION) + 1  # counting further changes nothing kept
    a, b = features.a, features.b
    near = camera.near_distance(scene.radius)
    t0, t1, idx, ab, A, B, pa, za, pb, zb, L = clipped_on_screen(a, b, camera, near)
    n = len(idx)
    lift = None if features.lift is None else features.lift[idx]
    size = row_norm(ab)

    def world_at(seg_i, s_i):
        return world_between(A, B, za, zb, camera.is_ortho, seg_i, s_i)

    own, ends = own_faces(scene, features, idx)

    def level_at(seg_i, s_i):  # (rows gathered by take: fancy indexing costs several times more)
        return levels(occluder, world_at(seg_i, s_i), camera, options.occlusion_offset,
                               None if lift is None else lift.take(seg_i, axis=0), size.take(seg_i), limit,
                               own.take(seg_i, axis=0), ends.take(seg_i, axis=0))

    # Pieces between the outline crossings; samples at the middles of equal parts of each piece,
    # one part per sample_spacing_px (whole_edge_px: a short segment is one piece, one sample).
    cx_seg, cx_s, cx_edge, cx_end, cx_gap = outline_crossings(
        view, near, pa, pb, za, zb, np.where(features.va[idx] >= 0, features.va[idx], -1),
        np.where(features.vb[idx] >= 0, features.vb[idx], -1), edges=True)
    whole = L < options.whole_edge_px
    keep_cx = np.flatnonzero(~whole[cx_seg])
    if len(keep_cx) < len(cx_seg):
        cx_seg, cx_s, cx_edge, cx_end, cx_gap = (x[keep_cx] for x in (cx_seg, cx_s, cx_edge, cx_end, cx_gap))
    # What each crossing does to the level (Appel's rule), for mesh edges, where it can say.
    cx_delta = crossing_deltas(scene, camera, occluder, cx_edge, cx_end, cx_gap, ab.take(cx_seg, axis=0),
                               own.take(cx_seg, axis=0))
    cx_delta[ends[cx_seg, 0] < 0] = NO_DELTA
    p_seg = np.concatenate([np.arange(n), cx_seg])
    p_s0 = np.concatenate([np.zeros(n), cx_s])
    p_delta = np.concatenate([np.full(n, NO_DELTA), cx_delta])
    o = _by_segment_then_s(p_seg, p_s0)
    p_seg, p_s0, p_delta = p_seg[o], p_s0[o], p_delta[o]
    last = np.empty(len(p_seg), bool)
    last[-1:] = True
    np.not_equal(p_seg[1:], p_seg[:-1], out=last[:-1])
    p_s1 = np.where(last, 1.0, np.roll(p_s0, -1))
    parts = np.maximum(1, np.ceil((p_s1 - p_s0) * L[p_seg] / options.sample_spacing_px)).astype(np.int64)
    parts[whole[p_seg]] = 1
    smp_piece = np.repeat(np.arange(len(p_seg)), parts)
    k = np.arange(parts.sum()) - np.repeat(np.cumsum(parts) - parts, parts)
    seg = p_seg[smp_piece]
    s = p_s0[smp_piece] + (k + 0.5) / parts[smp_piece] * (p_s1 - p_s0)[smp_piece]
    first_smp = np.cumsum(parts) - parts
    lev = _sample_levels(seg, s, first_smp, p_delta, last, limit, level_at)
    # Changes: at a crossing (exact), or between two samples of one piece (bisected).
    piece_lev = lev[first_smp]
    at_cx = np.flatnonzero(~last[:-1] & (lev[first_smp[1:] - 1] != piece_lev[1:])) + 1  # piece starts
    same_piece = smp_piece[1:] == smp_piece[:-1]
    inner = np.flatnonzero(same_piece & (lev[1:] != lev[:-1]))
    cs, c_lo, c_hi = seg[inner], s[inner], s[inner + 1]
    lev_left, lev_right = lev[inner], lev[inner + 1]
    if len(cs) and not options.bisect_changes:
        mid = 0.5 * (c_lo + c_hi)
        c_lo, c_hi = mid, mid.copy()
    elif len(cs):
        cs, c_lo, c_hi, lev_left, lev_right = _bisect_levels(cs, c_lo, c_hi, lev_left, lev_right, L, level_at,
                                                             options.bisection_tol_px)
    # Runs: from each segment's start and each change's right end, to the next change's left end
    # or the segment's end; the level is the one at the run's start.
    seg_ids = np.arange(n)
    r_seg = np.concatenate([seg_ids, p_seg[at_cx], cs])
    r_s0 = np.concatenate([np.zeros(n), p_s0[at_cx], c_hi])
    r_lev = np.concatenate([piece_lev[np.roll(last, 1)], piece_lev[at_cx],
                            lev_right])
    e_seg = np.concatenate([p_seg[at_cx], cs, seg_ids])
    e_s1 = np.concatenate([p_s0[at_cx], c_lo, np.ones(n)])
    o_start = _by_segment_then_s(r_seg, r_s0)
    o_end = _by_segment_then_s(e_seg, e_s1)
    run_seg, s0, level = r_seg[o_start], r_s0[o_start], r_lev[o_start]
    s1 = e_s1[o_end]
    assert np.array_equal(run_seg, e_seg[o_end]), "level changes must pair up"
    keep = (level >= lo_level) & (level <= hi_level) & (s1 >= s0)
    run_seg, s0, s1, level = run_seg[keep], s0[keep], s1[keep], level[keep]
    X0, X1 = world_at(run_seg, s0), world_at(run_seg, s1)
    p0, _ = camera.project(X0)
    p1, _ = camera.project(X1)
    runs = visible_runs_of(features, idx[run_seg], t0, t1, s0, s1, X0, X1, p0, p1)
    code = runs.kind.astype(np.int64) + N_KINDS * np.minimum(level, MAX_OCCLUSION)
    return VisibleRuns(edge=runs.edge, X0=runs.X0, X1=runs.X1, p0=runs.p0, p1=runs.p1, key0=runs.key0,
                       key1=runs.key1, kind=code.astype(np.int8), face=runs.face)


def _by_segment_then_s(seg: np.ndarray, s: np.ndarray) -> np.ndarray:
    """np.lexsort((s, seg)). Its inputs here are mostly runs already in that order (segment starts
    or ends, and the crossings sorted by segment and s): a stable sort on the segment alone,
    which finds the runs and merges them, gives the same order when s then ascends within each
    segment (checked; the lexsort otherwise)."""
    o = np.argsort(seg, kind="stable")
    so, ss = seg.take(o), s.take(o)
    if len(o) > 1 and not ((so[1:] != so[:-1]) | (ss[1:] >= ss[:-1])).all():
        return np.lexsort((s, seg))
    return o


def _sample_levels(seg, s, first_smp, p_delta, last, limit, level_at):
    """(M,) the level of every sample (segment seg, parameter s; pieces starting at samples
    first_smp, `last` the last piece of its segment), as level_at counts it, with fewer rays.

    Appel's rule: at an outline crossing whose delta is known (p_delta per piece; NO_DELTA:
    unknown) the level is the one of the sample before plus the delta. The first sample of such
    a piece is not counted when a counted sample further on checks its chain: the next counted
    sample of the segment (the piece's second sample, or the first of a later piece; the last
    piece's first sample is counted unless the piece has a second one) must equal the chain's
    level plus what lies between (0 inside a piece, the known delta at a crossing). Where a check fails, cannot be made (an unknown
    delta) or a chain meets the counting limit (a count held at `limit` says nothing exact) or
    leaves [0, limit), every sample of the segment is counted: the levels are then the counts."""
    m = len(seg)
    d = np.zeros(m, np.int64)
    d[first_smp] = p_delta  # (a segment's first piece: NO_DELTA, never propagated)
    known = d != NO_DELTA
    prop = np.zeros(m, bool)
    # (a last piece only when its own second sample, counted, checks it)
    two = np.append(first_smp[1:], m) - first_smp >= 2
    prop[first_smp[~last | two]] = True
    prop &= known
    need = np.flatnonzero(~prop)
    lev = np.zeros(m, np.int64)
    lev[need] = level_at(seg.take(need), s.take(need))
    if not prop.any():
        return lev
    d_known = np.where(known, d, 0)
    anchor = need[np.cumsum(~prop) - 1]  # the counted sample each chain starts from
    cd = np.cumsum(d_known)
    lev_p = lev.take(anchor) + (cd - cd.take(anchor))
    bad = prop & ((lev.take(anchor) >= limit) | (lev_p < 0) | (lev_p >= limit))
    # Each chain ends at a counted sample of its segment: it must agree.
    end = np.flatnonzero(~prop[1:] & prop[:-1]) + 1
    # (a count held at the limit agrees with any chain that reaches it: it checks nothing)
    bad[end - 1] |= ~known[end] | (lev[end] != lev_p[end - 1] + d_known[end]) | (lev[end] >= limit)
    if bad.any():
        redo_seg = np.zeros(int(seg.max()) + 1, bool)
        redo_seg[seg[bad]] = True
        redo = np.flatnonzero(prop & redo_seg[seg])
        lev[redo] = level_at(seg.take(redo), s.take(redo))
        prop[redo] = False
    lev[prop] = lev_p[prop]
    return lev


def own_faces(scene: Scene, features: FeatureEdges, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(faces (n, 2), vertices (n, 2)) of the features idx: a mesh edge's two faces (the first two
    of a non-manifold one) and end vertices; a line inside a face, that face and no vertex (-1)."""
    V = len(scene.vertices)
    va, vb = features.va[idx], features.vb[idx]
    faces = np.full((len(idx), 2), -1, np.int64)
    faces[:, 0] = features.face[idx]
    ends = np.full((len(idx), 2), -1, np.int64)
    mesh = (va >= 0) & (vb >= 0) & (va < V) & (vb < V)
    if mesh.any():
        lo, hi = np.minimum(va[mesh], vb[mesh]), np.maximum(va[mesh], vb[mesh])
        keys = scene.edge_keys
        q = lo * (V + 1) + hi
        pos = np.clip(np.searchsorted(keys, q), 0, len(keys) - 1)
        found = keys[pos] == q
        m = np.flatnonzero(mesh)[found]
        faces[m] = scene.edge_faces.take(pos[found], axis=0)
        ends[m, 0], ends[m, 1] = va[m], vb[m]
    return faces, ends


def outline_edges(view: FrameView) -> np.ndarray:
    """The scene edges where what hides a point can change: contour edges (a front and a back
    face), borders and non-manifold edges (those not manifold)."""
    return np.flatnonzero(view.silhouettes | ~view.scene.is_manifold)


def outline_crossings(view: FrameView, near: float, pa, pb, za, zb, va, vb, edges: bool = False):
    """(segment (K,), s (K,)): where the image of each clipped segment pa -> pb (px; view depths
    za, zb at its ends; mesh vertices va, vb, -1 for none) crosses the image of an outline edge
    (`outline_edges`, clipped alike) that lies in front of it there, at screen parameter 0 < s < 1,
    sorted by segment then s, each place once. Edges that share a vertex with the segment meet it
    at its end, not across it, and are skipped. With `edges`, also per place: the scene edge
    crossed (-1 where several meet there), the place's distance (px) to the nearer end of its
    image and the relative depth gap (zf - zc) / zf of the outline in front of the segment."""
    scene, camera = view.scene, view.camera
    eid = outline_edges(view)
    E = scene.edges.take(eid, axis=0)
    none = (np.zeros(0, np.int64), np.zeros(0))
    if edges:
        none = none + (np.zeros(0, np.int64), np.zeros(0), np.zeros(0))
    if len(E) == 0 or len(pa) == 0:
        return none
    V = scene.vertices
    Va, Vb = V.take(E[:, 0], axis=0), V.take(E[:, 1], axis=0)
    c0, c1 = clip_segments(Va, Vb, camera, near)
    ok = np.flatnonzero(c1 > c0)
    if len(ok) == 0:
        return none
    if len(ok) < len(E):
        E, c0, c1, Va, Vb, eid = (E.take(ok, axis=0), c0[ok], c1[ok], Va.take(ok, axis=0), Vb.take(ok, axis=0),
                                  eid[ok])
    qa, wa = camera.project(Va + c0[:, None] * (Vb - Va))
    qb, wb = camera.project(Va + c1[:, None] * (Vb - Va))
    # Candidate pairs from a grid, the cheap depth and box tests, then the crossing's: one
    # compiled pass (in numpy, the candidate pairs alone were large temporaries).
    f_pair, s, c_pair, u, gap = kernels().outline_crossings(
        np.ascontiguousarray(pa), np.ascontiguousarray(pb), za, zb, np.ascontiguousarray(va),
        np.ascontiguousarray(vb), qa, qb, wa, wb, np.ascontiguousarray(E[:, 0]), np.ascontiguousarray(E[:, 1]),
        bool(camera.is_ortho), GRID_PX)
    # One place once: two outline edges meeting at a vertex on the segment report it twice.
    new = np.ones(len(s), bool)
    new[1:] = (f_pair[1:] != f_pair[:-1]) | (s[1:] - s[:-1] > 1e-12)
    if not edges:
        return f_pair[new], s[new]
    head = np.flatnonzero(new)
    merged = np.minimum.reduceat(c_pair, head) != np.maximum.reduceat(c_pair, head) if len(head) else new[:0]
    c_head = c_pair[head]
    u = u[head]
    end_px = np.minimum(u, 1 - u) * row_norm(qb - qa).take(c_head)
    return f_pair[head], s[head], np.where(merged, -1, eid.take(c_head)), end_px, gap[head]


#: crossing_deltas' value where it cannot say (the level is counted there instead).
NO_DELTA = np.iinfo(np.int64).min


def crossing_deltas(scene: Scene, camera: Camera, occluder: Occluder, edge: np.ndarray, end_px: np.ndarray,
                    gap: np.ndarray, ab: np.ndarray, own: np.ndarray) -> np.ndarray:
    """(K,) how the occlusion level of a segment changes where it passes behind outline edge
    `edge` (K,) (outline_crossings; -1: several, no answer), moving along ab (K, 3) (its world
    direction): Appel's rule, the faces of the edge on the side the ray sweeps into count +1, on
    the side it leaves -1 (a contour's two faces lie on one side: +-2; a border's one: +-1).
    A face's side is its third vertex's side of the plane through the edge and the eye (parallel
    projections: along the projection rays). NO_DELTA where the geometry is too close to a
    tie to trust it over a counted ray: a non-manifold edge, a face of the segment's own `own`
    (K, 2) or one the occluder leaves out, a face or the segment within 1e-6 (relative) of the
    plane, the outline within 1e-6 (relative depth `gap`) in front of the segment, or the place
    within 1e-3 px (`end_px`) of the ends of the edge's image."""
    kept = occluder.kept_faces
    view = camera.ray_dir if camera.is_ortho else camera.eye
    return kernels().crossing_deltas(
        np.ascontiguousarray(edge, np.int64), end_px, gap, np.ascontiguousarray(ab), np.ascontiguousarray(own),
        scene.edges.astype(np.int64, copy=False), scene.edge_faces, scene.edge_face_count.astype(np.int64, copy=False),
        scene.faces.astype(np.int64, copy=False), scene.vertices, np.asarray(view, float), bool(camera.is_ortho),
        np.zeros(0, bool) if kept is None else kept, NO_DELTA)


def _bisect_levels(cs, lo, hi, lev_lo, lev_hi, L, level_at, tol_px):
    """Every change of level inside the brackets (segment cs, parameters lo < hi, levels lev_lo at
    lo and lev_hi at hi), each bracket halved until it is within tol_px on screen: the half whose
    ends differ is kept; a middle whose level is neither end's splits the bracket in two, both
    halved on (a level jumping 0 -> 1 -> 2 between two samples gives two changes). One
    level_at call per halving for all brackets still open. Returns the changes (segment, left
    end, right end, left level, right level), in no order."""
    cs, lo, hi, lev_lo, lev_hi = cs.copy(), lo.copy(), hi.copy(), lev_lo.copy(), lev_hi.copy()
    for _ in range(MAX_HALVINGS):
        open_ = np.flatnonzero((hi - lo) * L.take(cs) > tol_px)
        if len(open_) == 0:
            break
        mid = 0.5 * (lo.take(open_) + hi.take(open_))
        lm = level_at(cs.take(open_), mid)
        left = lm == lev_lo.take(open_)  # the change lies in [mid, hi]
        right = ~left & (lm == lev_hi.take(open_))  # in [lo, mid]
        split = ~left & ~right
        lo[open_[left]] = mid[left]
        hi[open_[right]] = mid[right]
        if split.any():  # [lo, mid] keeps lev_lo -> lm; a new bracket [mid, hi] goes lm -> lev_hi
            k = open_[split]
            cs = np.concatenate([cs, cs.take(k)])
            lo = np.concatenate([lo, mid[split]])
            hi = np.concatenate([hi, hi.take(k)])
            lev_lo = np.concatenate([lev_lo, lm[split]])
            lev_hi = np.concatenate([lev_hi, lev_hi.take(k)])
            hi[k] = mid[split]
            lev_hi[k] = lm[split]
    return cs, lo, hi, lev_lo, lev_hi
