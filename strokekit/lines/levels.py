"""Occlusion levels of points: how many surfaces the sight line from each point to the eye
crosses (Freestyle's quantitative invisibility), its own faces left out, every hit of a ray from
one Embree call (`levels`, `count_crossings`), for the hidden-line stage (`lines.occlusion`)."""

from __future__ import annotations

import numpy as np

from strokekit.camera.view import Camera
from strokekit.lines.sightlines import segments
from strokekit.model import row_norm
from strokekit.numba_cache import LazyKernels
from strokekit.scene.occluder import Occluder


def levels(occ: Occluder, points: np.ndarray, camera: Camera, offset: float, lift: np.ndarray | None,
           scale: np.ndarray, limit: int, own: np.ndarray | None = None,
           ends: np.ndarray | None = None) -> np.ndarray:
    """(N,) occlusion level of world points (N, 3): how many surfaces the open segment from
    each point to the eye (parallel cameras: along the projection rays to the near plane)
    crosses, up to `limit`, the point's own faces `own` (N, 2), -1 for none, excluded.

    A point on a mesh edge (`ends` (N, 2): its end vertices, -1 for none) is counted along the
    ray from the point itself (started `offset` x the local size `scale` along): the geometry
    of the definition. That ray grazes the point's own neighbourhood within float32 rounding,
    so its hits closer than 100 lifts to its start are tested again in float64 against the
    exact segment and count only if they are crossings there (a box standing on a floor is not
    hidden by it). A lifted ray would skip a real surface within its lift, and one leaving a
    contour whose back face is nearly edge-on dips under the nearly flat surface beyond (a
    crossing the point does not have). Other points (lines inside faces, whose rays rise off
    the facets by design: lines.contours.view_lift) take the smaller count of the lifted ray
    and of the plain ray: each ray's failures there add crossings."""
    n = len(points)
    on_edge = np.zeros(n, bool) if ends is None or lift is None else ends[:, 0] >= 0
    e = np.flatnonzero(on_edge)
    if n and len(e) == n and not camera.is_ortho and occ.backend == "open3d" and own is not None:
        count = _levels_compiled(occ, points, camera, offset, lift, scale, limit, own)
        if count is not None:
            return count
    c = points - occ.origin
    eps = offset * np.maximum(np.sqrt(np.einsum("ij,ij->i", c, c)), scale)
    count = np.zeros(n, np.int64)
    if n and len(e) == n:  # (every point on an edge: no gathers)
        o, t = segments(occ, points, camera, eps, offset)
        count, _ = count_crossings(occ, o, t, limit, skip=own, verify=(points, t, 100.0 * row_norm(lift) + eps))
        return count
    if len(e):
        P = points[e]
        o, t = segments(occ, P, camera, eps[e], offset)
        reach = 100.0 * row_norm(lift[e]) + eps[e]
        count[e], _ = count_crossings(occ, o, t, limit, skip=None if own is None else own[e],
                                           verify=(P, t, reach))
    rest = np.flatnonzero(~on_edge)
    if len(rest) == 0:
        return count
    P = points[rest]
    start = P if lift is None else P + lift[rest]
    c_rest, _ = count_crossings(occ, *segments(occ, start, camera, eps[rest], offset), limit,
                                     skip=None if own is None else own[rest])
    if lift is not None:
        again = np.flatnonzero(c_rest > 0)
        if len(again):
            plain, _ = count_crossings(occ, *segments(occ, P[again], camera, eps[rest][again], offset), limit,
                                            skip=None if own is None else own[rest][again])
            c_rest[again] = np.minimum(c_rest[again], plain)
    count[rest] = c_rest
    return count


def _levels_compiled(occ: Occluder, points: np.ndarray, camera: Camera, offset: float, lift: np.ndarray,
                     scale: np.ndarray, limit: int, own: np.ndarray) -> np.ndarray | None:
    """levels of points that all lie on mesh edges, for a perspective camera: the same rays,
    hits and counts, the rays built and the hits sorted and filtered by the compiled loops of
    `strokekit.scene.compiled`. None when Embree's list does not come grouped by ray."""
    K = level_kernels()
    n = len(points)
    eye = np.asarray(camera.eye, float)
    eye_tail = offset * np.linalg.norm(eye - occ.origin)
    k = occ.inv_scale
    rays, targets, d_local, length, reach = K.level_rays(
        np.ascontiguousarray(points, float), np.ascontiguousarray(lift, float), np.ascontiguousarray(scale, float),
        eye, occ.origin, k, offset, eye_tail)
    lt, lray, lprim = occ.list_intersections(rays)
    index = occ.face_index if occ.face_index is not None else np.zeros(0, np.int64)
    ok, t, ray, face, close = K.listed_hits(lt, lray, lprim,
                                            index, length, k, np.ascontiguousarray(own, np.int64), reach)
    if not ok:
        return None
    c = np.flatnonzero(close)
    if len(c):  # hits near the start count only where they cross in float64
        r_c = ray[c]
        keep = np.ones(len(t), bool)
        keep[c] = K.crosses(points.take(r_c, axis=0), targets.take(r_c, axis=0), face[c], np.ascontiguousarray(occ.scene.faces, np.int64),
                             occ.scene.vertices)
        t, ray, face = t[keep], ray[keep], face[keep]
    if len(t) == 0:
        return np.zeros(n, np.int64)
    return _crossing_count(occ, t, ray, face, length, d_local, n, limit)[0]


def count_crossings(occ: Occluder, origins: np.ndarray, targets: np.ndarray, limit: int, skip: np.ndarray | None = None,
                    near: tuple[np.ndarray, np.ndarray] | None = None,
                    verify: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(count (N,) int64, first (N,)): how many surfaces the segments origins -> targets (world,
    (N, 3)) cross, at most `limit`, and the distance (world units) to the first crossing (inf:
    none). Callers offset the origins; the target end is open. Hits on the faces `skip`
    (N, 2) of each ray (-1: none) are not crossings; nor, with `near` = (vertices (N, 2),
    distances (N,)), those on faces around those vertices closer than that to the origin; with
    `verify` = (points (N, 3), targets (N, 3), distances (N,)), hits closer than that to the
    origin count only where the segment from the point to the target crosses the triangle in
    float64 (`_crosses`).

    Every hit along each segment comes from one Embree call (open3d's list_intersections).
    A ray through an edge or a vertex that several triangles share may be reported by each of
    them (float32 hit distances a little apart): consecutive hits on triangles that share a
    vertex, facing the ray the same way, within 1e-5 of the scene radius of each other count
    once, whichever triangles Embree reported (crossing a consistently wound surface twice in
    a row flips the side it is crossed from, so two same-side hits in a row are one crossing;
    a ray grazing a fold, in and out, keeps both). open3d's count_intersections is faster but
    returns a number only: it cannot leave out a ray's own faces and counts a shared edge twice
    when Embree reports both triangles at float32 distances a little apart; rays continued past
    each hit (`_count_crossings_stepping`, the path without open3d) are slower and meet a grazed
    triangle again (benchmarks/bench_hidden.py compares the three)."""
    n = len(origins)
    count = np.zeros(n, np.int64)
    first = np.full(n, np.inf)
    if n == 0:
        return count, first
    if occ.backend != "open3d":
        return _count_crossings_stepping(occ, origins, targets, limit, skip, near, verify)
    k = occ.inv_scale
    d_local = (np.asarray(targets, float) - origins) * k
    rays = np.empty((n, 6), np.float32)
    rays[:, :3] = (origins - occ.origin) * k
    rays[:, 3:] = d_local
    lt, lray, lprim = occ.list_intersections(rays)
    t = lt
    ray = lray.astype(np.int64)
    inside = t <= 1.0
    if not inside.all():
        t, ray = t[inside], ray[inside]
        prim = lprim[inside]
    else:
        prim = lprim
    if len(t) == 0:
        return count, first
    o = _order_along_rays(t, ray)  # by ray, then along it
    t, ray, face = t[o].astype(float), ray[o], occ.scene_faces(prim[o])
    length = np.sqrt(np.einsum("ij,ij->i", d_local, d_local))
    dist = t * length.take(ray) / k
    drop = _skipped(occ, ray, face, dist, skip, near)
    if verify is not None:
        close = np.flatnonzero(dist <= verify[2].take(ray))
        if len(close):
            if drop is None:
                drop = np.zeros(len(t), bool)
            r_c = ray[close]
            drop[close] |= ~_crosses(occ, verify[0].take(r_c, axis=0), verify[1].take(r_c, axis=0), face[close])
    if drop is not None:
        t, ray, face = t[~drop], ray[~drop], face[~drop]
        if len(t) == 0:
            return count, first
    count, head = _crossing_count(occ, t, ray, face, length, d_local, n, limit)
    firsts = np.flatnonzero(head)
    first[ray[firsts]] = t[firsts] * length.take(ray[firsts]) / k
    return count, first


def _crossing_count(occ: Occluder, t, ray, face, length, d_local, n, limit):
    """(count (n,), head (K,)): the crossings of each of n rays, at most `limit`, from its hits
    (K >= 1; t along the ray's local direction d_local (n, 3), of norm length (n,), by ray then
    t; scene faces): consecutive hits on triangles that share a vertex, facing the ray alike,
    within 1e-5 (Embree frame) count once (see count_crossings); head marks each ray's first."""
    head = np.empty(len(t), bool)
    head[0] = True
    np.not_equal(ray[1:], ray[:-1], out=head[1:])
    close = ~head[1:] & ((t[1:] - t[:-1]) * length.take(ray[1:]) <= 1e-5)
    dup = np.zeros(len(t), bool)
    if close.any():
        i = np.flatnonzero(close) + 1  # hit i repeats hit i - 1?
        F = occ.scene.faces
        fa, fb = F.take(face[i - 1], axis=0), F.take(face[i], axis=0)
        shared = (fa[:, :, None] == fb[:, None, :]).any(axis=(1, 2))
        d = d_local.take(ray[i], axis=0)
        nrm = occ.scene.face_normals
        side_a = np.einsum("ij,ij->i", nrm.take(face[i - 1], axis=0), d) > 0
        side_b = np.einsum("ij,ij->i", nrm.take(face[i], axis=0), d) > 0
        dup[i] = shared & (side_a == side_b)
    return np.minimum(np.bincount(ray[~dup], minlength=n), int(limit)), head


def _skipped(occ: Occluder, ray, face, dist, skip, near) -> np.ndarray | None:
    """Which hits (ray, scene face, world distance from the origin) are not crossings (see
    count_crossings); None for none."""
    drop = None
    if skip is not None:
        drop = (face == skip[:, 0].take(ray)) | (face == skip[:, 1].take(ray))
    if near is not None:
        verts, reach = near
        close = dist <= reach[ray]
        if close.any():
            i = np.flatnonzero(close)
            f = occ.scene.faces.take(face[i], axis=0)
            v = verts[ray[i]]
            touch = ((f == v[:, :1]) | (f == v[:, 1:])).any(axis=1) & ((v >= 0).any(axis=1))
            hit = np.zeros(len(face), bool)
            hit[i[touch]] = True
            drop = hit if drop is None else drop | hit
    return drop


def _crosses(occ: Occluder, a: np.ndarray, b: np.ndarray, face: np.ndarray) -> np.ndarray:
    """(M,) whether the open segments a -> b (world, (M, 3)) cross the scene faces `face` (M,)
    in float64 (Moller-Trumbore on the closed triangle; a face seen edge-on crosses nothing)."""
    F, V = occ.scene.faces, occ.scene.vertices
    tri = F.take(face, axis=0)
    A = V.take(tri[:, 0], axis=0)
    e1 = V.take(tri[:, 1], axis=0) - A
    e2 = V.take(tri[:, 2], axis=0) - A
    d = b - a
    pv = _cross(d, e2)
    det = np.einsum("ij,ij->i", e1, pv)
    scale = row_norm(_cross(e1, e2)) * row_norm(d)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / det
        tv = a - A
        u = np.einsum("ij,ij->i", tv, pv) * inv
        qv = _cross(tv, e1)
        v = np.einsum("ij,ij->i", d, qv) * inv
        t = np.einsum("ij,ij->i", e2, qv) * inv
    return (np.abs(det) > 1e-12 * scale) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0) & (t < 1)


def _count_crossings_stepping(occ: Occluder, origins: np.ndarray, targets: np.ndarray, limit: int, skip=None,
                              near=None, verify=None):
    """count_crossings without open3d: the segment is cast again from just past each hit (1e-6
    of the local size; a grazing ray can meet its last triangle again: a fallback, slower and
    rougher than the open3d path)."""
    n = len(origins)
    count = np.zeros(n, np.int64)
    first = np.full(n, np.inf)
    active = np.arange(n)
    o = np.asarray(origins, float)
    tgt = np.asarray(targets, float)
    for r in range(int(limit)):
        seg = tgt - o
        length = np.sqrt(np.einsum("ij,ij->i", seg, seg))
        hits = occ.first_hits(o, tgt - o)
        t = np.where(hits["t_hit"] <= 1.0, hits["t_hit"], np.inf).astype(float)
        hit = np.isfinite(t)
        ray_h, face_h, dist_h = active[hit], hits["primitive_ids"][hit], t[hit] * length[hit]
        drop = _skipped(occ, ray_h, face_h, dist_h, skip, near)
        if verify is not None:
            base = np.linalg.norm(o[hit] - origins[ray_h], axis=1)  # how far this round started
            close = np.flatnonzero(base + dist_h <= verify[2][ray_h])
            if len(close):
                drop = np.zeros(len(ray_h), bool) if drop is None else drop
                r_c = ray_h[close]
                drop[close] |= ~_crosses(occ, verify[0][r_c], verify[1][r_c], face_h[close])
        counted = hit.copy()
        if drop is not None:
            counted[np.flatnonzero(hit)[drop]] = False
        if r == 0:
            first[active[counted]] = t[counted] * length[counted]
        count[active[counted]] += 1
        if r + 1 == limit or not hit.any():
            break
        at = o[hit] + t[hit, None] * seg[hit]
        size = np.maximum(np.sqrt(np.einsum("ij,ij->i", at - occ.origin, at - occ.origin)), occ.radius)
        step = t[hit] + 1e-6 * size / np.where(length[hit] > 0, length[hit], 1.0)
        go = step < 1.0
        active = active[hit][go]
        o = o[hit][go] + step[go, None] * seg[hit][go]
        tgt = tgt[hit][go]
        if len(active) == 0:
            break
    return count, first


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """np.cross of (N, 3) rows, the same bits (each component a product minus a product), without
    its generic machinery (its overhead dominates on a frame's rows)."""
    return np.stack([a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1], a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
                     a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]], axis=1)


def _order_along_rays(t: np.ndarray, ray: np.ndarray) -> np.ndarray:
    """np.lexsort((t, ray)): the hits by ray, then along it (ties in list order). Embree's list
    comes grouped by ray in ray order, and within a ray mostly in order already: only the rays
    whose hits are not are sorted (a full lexsort of a frame's hits costs more)."""
    n = len(t)
    if n < 2:
        return np.arange(n)
    same = ray[1:] == ray[:-1]
    if (ray[1:] < ray[:-1]).any():  # not grouped in ray order: the general sort
        return np.lexsort((t, ray))
    bad = same & (t[1:] < t[:-1])
    o = np.arange(n)
    if bad.any():
        mark = np.zeros(int(ray[-1]) + 1, bool)
        mark[ray[1:][bad]] = True
        sel = np.flatnonzero(mark[ray])  # every hit of those rays (contiguous groups)
        o[sel] = sel[np.lexsort((t[sel], ray[sel]))]
    return o


#: The compiled loops of occlusion-level rays (`strokekit.scene.compiled`), imported on first use:
#: drawings of visible lines only never import numba (warmed up with the hidden-line kernels).
LEVEL_KERNELS = LazyKernels("strokekit.scene.compiled")


def level_kernels():
    """The module `strokekit.scene.compiled`, imported (its kernels loaded or compiled) on first use."""
    return LEVEL_KERNELS.kernels()
