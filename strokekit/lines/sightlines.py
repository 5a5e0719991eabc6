"""Sight lines: the open segment from a point to the eye (parallel cameras: along the projection
rays, to the near plane), cast on the scene's ray backend (`Occluder`): whether a point is seen
(`visible`, and the same rays on (3, N) coordinate rows for the visibility stage's hot paths), and
whether the eye sits inside a closed part of the scene (`eye_enclosed`). How many surfaces a
sight line crosses is `strokekit.lines.levels`."""

from __future__ import annotations

import math

import numpy as np

from strokekit.camera.view import Camera
from strokekit.scene.occluder import Occluder


def segments(occ: Occluder, points: np.ndarray, camera: Camera, eps: np.ndarray, offset: float):
    """The open segments from points toward the eye (perspective) or along the projection
    rays to the near plane (parallel), started eps along: (origins, targets), as
    _visible_from casts them; a point on the near plane itself gets an empty segment."""
    if camera.is_ortho:
        _, _, fwd = camera.basis
        toward = np.broadcast_to(-camera.ray_dir, points.shape)
        reach = np.maximum((points - np.asarray(camera.eye, float)) @ fwd - camera.near_distance(occ.radius), 0.0)
        origins = points + np.minimum(eps, 0.5 * reach)[:, None] * toward
        targets = points + reach[:, None] * toward
        return origins, targets
    eye = np.asarray(camera.eye, float)
    d = eye - points
    dist = np.sqrt(np.einsum("ij,ij->i", d, d))
    toward = d / np.where(dist > 0, dist, 1.0)[:, None]
    origins = points + np.minimum(eps, 0.5 * dist)[:, None] * toward
    tail = np.minimum(np.maximum(eps, offset * np.linalg.norm(eye - occ.origin)), 0.25 * dist)
    return origins, eye - tail[:, None] * toward


def visible(occ: Occluder, points: np.ndarray, camera: Camera, offset: float = 1e-5,
            lift: np.ndarray | None = None, scale: np.ndarray | None = None) -> np.ndarray:
    """(N,) True where world points (N, 3) are seen from the camera. `lift` (N, 3), if given,
    moves each ray origin off the surface (world units) before the test.

    The ray starts `offset` x a length toward the eye: the scene radius, or, when `scale` (N,)
    (the local size of the geometry at each point, world units, e.g. its edge length) is
    given, max(|point - scene centre|, scale). float32 errors grow with the coordinates'
    magnitude in the centred frame, so that is the size the offset must beat; a global radius
    would let a huge floor make the offset jump over small nearby occluders.

    With a lift, a point is visible when either the lifted or the plain ray reaches the eye:
    the plain ray can graze the point's own 1-ring (false hits within float32 rounding), the
    lifted one can start inside an object the surface rests on (a box on the floor); each
    failure only ever hides, and a real occluder stops both rays."""
    if scale is None:
        eps = np.full(len(points), offset * occ.radius)
    else:
        c = points - occ.origin
        eps = offset * np.maximum(np.sqrt(np.einsum("ij,ij->i", c, c)), scale)
    if lift is None:
        return _visible_from(occ, points, camera, eps, offset)
    lifted = points + lift
    hit_at = _visible_from(occ, lifted, camera, eps, offset, first_hit=True)
    vis = np.isinf(hit_at)
    # Only a lifted ray blocked right at its start can be the contact case; most hidden
    # samples are hidden by something far away and need no second full ray. The first hit's
    # distance (one closest-hit ray instead of an occlusion ray and a short second one)
    # tells which.
    reach = 100.0 * np.linalg.norm(lift, axis=1) + eps
    again = np.flatnonzero(~vis & (hit_at <= reach))
    if len(again):
        vis[again] = _visible_from(occ, points[again], camera, eps[again], offset)
    return vis


def _visible_from(occ: Occluder, points: np.ndarray, camera: Camera, eps: np.ndarray, offset: float,
                  first_hit: bool = False):
    """Rays from points toward the eye, started eps along. Visibility (N,) bool; with
    `first_hit`, instead the distance to the first hit along the ray (world units, inf where
    the ray reaches the eye)."""
    if camera.is_ortho:
        # Parallel rays toward the camera, as far as the near plane: what lies before it is
        # clipped out of the drawing (clip_segments) and hides nothing either (a section view,
        # a camera placed inside the scene).
        _, _, fwd = camera.basis
        reach = np.maximum((points - np.asarray(camera.eye, float)) @ fwd - camera.near_distance(occ.radius), 0.0)
        if not reach.all():  # a point on the near plane itself: no segment, nothing can hide it
            on = reach > 0
            out = np.full(len(points), np.inf) if first_hit else np.ones(len(points), bool)
            if on.any():
                out[on] = _visible_from(occ, points[on], camera, eps[on], offset, first_hit)
            return out
    # The segment is open at the eye too (perspective): an eye standing on a surface must not
    # see that surface as an occluder of everything; it stops short by the float32 rounding
    # scale there.
    origins, targets = segments(occ, points, camera, eps, offset)
    if first_hit:
        t = occ.segment_hits(origins, targets)
        return t * np.linalg.norm(targets - origins, axis=1)
    return ~occ.occluded_segments(origins, targets)


# --- the same queries on (3, N) coordinate rows (perspective, lifted) -------------------------------
# visible_runs' hot path. Every value is computed by the same float64 operations, in the same
# order, as visible / _visible_from / occluded_segments (so the float32 rays, hence the answers,
# are bit for bit the same); only the memory layout differs, which makes numpy's elementwise loops
# contiguous. np.einsum("ij,ij->i", x, x) sums (x0 x0 + x2 x2) + x1 x1 and np.linalg.norm(x, axis=1)
# sqrt((x0 x0 + x1 x1) + x2 x2): the helpers below keep those orders.

def _rays_rows(occ: Occluder, o: np.ndarray, t: np.ndarray):
    """open3d rays (Embree frame, float32) of the segments between (3, N) origins and targets."""
    rays = np.empty((o.shape[1], 6), np.float32)
    rays[:, :3] = ((o - occ.origin[:, None]) * occ.inv_scale).T
    rays[:, 3:] = ((t - o) * occ.inv_scale).T
    return rays


def _occluded_rows(occ: Occluder, o: np.ndarray, t: np.ndarray) -> np.ndarray:
    """occluded_segments for (3, N) origins and targets (open3d backend)."""
    if o.shape[1] == 0:
        return np.zeros(0, bool)
    return occ.test_occlusions(_rays_rows(occ, o, t))


def _hit_distance_rows(occ: Occluder, o: np.ndarray, t: np.ndarray, faces: bool = False):
    """segment_hits for (3, N) origins and targets, times the segment lengths (world units).
    With `faces`, also the (N,) triangle each ray first meets (meaningless where it meets none)."""
    if o.shape[1] == 0:
        return (np.zeros(0), np.zeros(0, np.int64)) if faces else np.zeros(0)
    r = occ.cast_rays(_rays_rows(occ, o, t))
    f = r["t_hit"].astype(float)
    f = np.where(f <= 1.0, f, np.inf)
    dist = f * np.sqrt(_norm_sq(t - o))
    return (dist, r["primitive_ids"]) if faces else dist


def _visible_from_rows(occ: Occluder, P: np.ndarray, eye: np.ndarray, eps: np.ndarray, eye_eps: float,
                       d: np.ndarray | None = None, dist: np.ndarray | None = None,
                       first_hit: bool = False, faces: bool = False):
    """_visible_from (perspective) for (3, N) points; eye (3, 1); eye_eps = offset x |eye - origin|.
    d = eye - P and dist = its length (einsum order) may be passed when already known. With
    `first_hit` and `faces`, (hit distances, first triangles) (see _hit_distance_rows)."""
    if d is None:
        d = eye - P
        dist = np.sqrt(_einsum_sq(d))
    toward = d / np.where(dist > 0, dist, 1.0)
    origins = P + np.minimum(eps, 0.5 * dist) * toward
    tail = np.minimum(np.maximum(eps, eye_eps), 0.25 * dist)
    targets = eye - tail * toward
    if first_hit:
        return _hit_distance_rows(occ, origins, targets, faces)
    return ~_occluded_rows(occ, origins, targets)


def visible_rows(occ: Occluder, P: np.ndarray, camera: Camera, offset: float, lift: np.ndarray,
                 scale: np.ndarray, retest_front_hits: bool = True) -> np.ndarray:
    """visible(points, camera, offset, lift, scale) for a perspective camera and the open3d
    backend, with points and lift as (3, N) rows.

    `retest_front_hits` False (LineOptions.retest_front_hits, the draft preset): the plain ray
    is not cast where the lifted ray's near first hit is the front side of a triangle, only
    where it is a back side. The plain ray is there for a lifted origin that starts inside an
    object the surface rests on, whose first hit is then that object's back side; a near
    front-side hit is the surface's own relief around the point, where the plain ray mostly
    meets it too: skipping it changes few of the re-tested answers, nearly all on lines edge-on
    in concave corners (docs/accuracy-speed.md, the draft preset)."""
    c = P - occ.origin[:, None]
    eps = offset * np.maximum(np.sqrt(_einsum_sq(c)), scale)
    eye = np.asarray(camera.eye, float)
    eye_eps = offset * np.linalg.norm(eye - occ.origin)
    eye = eye[:, None]
    lifted = P + lift
    d = eye - lifted
    dist = np.sqrt(_einsum_sq(d))
    if retest_front_hits:
        hit_at = _visible_from_rows(occ, lifted, eye, eps, eye_eps, d, dist, first_hit=True)
    else:
        hit_at, tri = _visible_from_rows(occ, lifted, eye, eps, eye_eps, d, dist, first_hit=True, faces=True)
    vis = np.isinf(hit_at)
    reach = 100.0 * np.sqrt(_norm_sq(lift)) + eps
    again = np.flatnonzero(~vis & (hit_at <= reach))
    if not retest_front_hits and len(again):
        # Back side: the triangle's normal points along the ray (toward the eye). A normal
        # perpendicular to the ray (dot 0) keeps its re-test too.
        n = np.take(occ.scene.face_normals, occ.scene_faces(tri.take(again)), axis=0)
        again = again[np.einsum("ij,ji->i", n, d[:, again]) >= 0.0]
    if len(again):
        vis[again] = _visible_from_rows(occ, P[:, again], eye, eps[again], eye_eps)
    return vis


def visible_local(occ: Occluder, P: np.ndarray, camera: Camera, offset: float, lift: np.ndarray,
                  scale: np.ndarray, retest_front_hits: bool = True) -> np.ndarray:
    """visible_rows (the draft preset's path) with points P, lifts and local sizes already in
    the Embree frame (centred on the scene, unit radius) as float64 (3, N) rows: the rays
    are built in fewer passes and rounded to float32 (what Embree takes) once. The ray from
    X + e1 u to eye - e2 u (X the lifted point, u the unit direction to the eye at distance
    r, d = eye - X) starts at X + (e1 / r) d with direction d (r - e1 - e2) / r."""
    eye_w = np.asarray(camera.eye, float)
    eye = ((eye_w - occ.origin) * occ.inv_scale)[:, None]
    eye_eps = offset * math.dist(eye_w, occ.origin) * occ.inv_scale
    eps = offset * np.maximum(np.sqrt(_sq3(P)), scale)
    lifted = P + lift
    d = eye - lifted
    dist = np.sqrt(_sq3(d))  # > 0: the near plane keeps points off the eye
    e1 = np.minimum(eps, 0.5 * dist)
    seg_len = dist - e1 - np.minimum(np.maximum(eps, eye_eps), 0.25 * dist)
    inv = 1.0 / dist
    rays = np.empty((P.shape[1], 6), np.float32)
    rays[:, :3] = (lifted + d * (e1 * inv)).T
    rays[:, 3:] = (d * (seg_len * inv)).T
    r = occ.cast_rays(rays)
    f = r["t_hit"]
    hidden = np.flatnonzero(f <= 1.0)
    vis = np.ones(len(f), bool)
    vis[hidden] = False
    # The contact re-test: only where the hit is near the start (world reach, Embree frame).
    reach = 100.0 * np.sqrt(_sq3(lift.take(hidden, axis=1))) + eps[hidden]
    again = hidden[f[hidden] * seg_len[hidden] <= reach]
    if not retest_front_hits and len(again):
        tri = occ.scene_faces(r["primitive_ids"].take(again))
        again = again[_dot3(occ.scene.face_normal_rows.take(tri, axis=1), d.take(again, axis=1)) >= 0.0]
    if len(again):
        # The plain rays (no lift), from the same points.
        Pa = P.take(again, axis=1)
        d = eye - Pa
        dist = np.sqrt(_sq3(d))
        ea = eps[again]
        e1 = np.minimum(ea, 0.5 * dist)
        seg_len = dist - e1 - np.minimum(np.maximum(ea, eye_eps), 0.25 * dist)
        inv = 1.0 / np.where(dist > 0, dist, 1.0)
        rays = np.empty((len(again), 6), np.float32)
        rays[:, :3] = (Pa + d * (e1 * inv)).T
        rays[:, 3:] = (d * (seg_len * inv)).T
        vis[again] = ~occ.test_occlusions(rays)
    return vis


def eye_enclosed(occ: Occluder, camera: Camera, n: int = 64) -> bool:
    """True when the perspective eye sits inside a closed part of the scene, by ray parity: a
    ray from a point inside a closed surface crosses it an odd number of times, from outside an
    even number, whichever way its faces wind (an inside-out cube encloses its inside as much
    as any). Inside when at least 95% of `n` rays spread over the sphere cross an odd number
    of times: a ray that slips through a hole or a crack, or grazes an edge, may miscount."""
    if camera.is_ortho:
        return False
    k = np.arange(n) + 0.5
    phi = np.arccos(1 - 2 * k / n)
    theta = math.pi * (1 + 5 ** 0.5) * k
    dirs = np.stack([np.cos(theta) * np.sin(phi), np.sin(theta) * np.sin(phi), np.cos(phi)], axis=1)
    eye = np.broadcast_to(np.asarray(camera.eye, float), dirs.shape)
    odd = occ.crossings(eye, dirs) % 2 == 1
    return bool(odd.mean() >= 0.95)


def _sq3(x: np.ndarray) -> np.ndarray:
    """Squared length of each column of a (3, N) array."""
    return x[0] * x[0] + x[1] * x[1] + x[2] * x[2]


def _dot3(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Dot product of the columns of two (3, N) arrays."""
    return x[0] * y[0] + x[1] * y[1] + x[2] * y[2]


def _einsum_sq(x: np.ndarray) -> np.ndarray:
    """np.einsum("ij,ij->i", X, X) of the (N, 3) X whose rows x (3, N) holds, same bits."""
    return (x[0] * x[0] + x[2] * x[2]) + x[1] * x[1]


def _norm_sq(x: np.ndarray) -> np.ndarray:
    """The square of np.linalg.norm(X, axis=1) before its sqrt, X (N, 3) given as rows x (3, N)."""
    return (x[0] * x[0] + x[1] * x[1]) + x[2] * x[2]
