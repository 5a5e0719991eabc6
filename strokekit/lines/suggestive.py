"""Suggestive contours (DeCarlo, Finkelstein, Rusinkiewicz & Santella 2003).

A suggestive contour is where the radial curvature k_r (the normal curvature of the surface in
the direction w, the view vector projected onto the tangent plane) crosses zero while its
derivative along w is positive, on the part of the surface that faces the eye. They continue
the true contours into the surface: the places that would become contours under a small change
of view.

Curvature: the scene's per-vertex curvature tensors (`Scene.curvature_tensors`, after
Rusinkiewicz 2004), averaged over each vertex's one-ring SMOOTH_PASSES times (scans are noisy).
The derivative D_w k_r is the gradient of the piecewise-linear k_r field (each vertex's k_r uses
that vertex's own view vector, so the view's change along w is included) taken along w, per face.
"""

from __future__ import annotations

import numpy as np

from strokekit.camera.view import Camera
from strokekit.lines.contours import zero_set_segments
from strokekit.lines.facing import FrameView
from strokekit.model import KIND_INDEX, FeatureEdges
from strokekit.options import LineOptions
from strokekit.scene.load import Scene

#: One-ring averaging passes of the curvature tensor used by default (scans such as the bunny
#: are noisy at the scale of a face; a clean torus keeps its curvature through them).
SMOOTH_PASSES = 3


def radial_curvature(scene: Scene, camera: Camera, smooth_passes: int = SMOOTH_PASSES):
    """Per vertex: (k_r (V,), ndotv (V,), w (V, 3)) with v the unit vector to the eye, w = v - n (n.v)
    the view projected on the tangent plane (length sin theta) and k_r = w.S.w / |w|^2
    (1 / world unit; 0 where w vanishes)."""
    n = scene.vertex_normals
    if camera.is_ortho:
        view = np.broadcast_to(-camera.view_dir, n.shape)  # (-fwd but for oblique rays)
    else:
        view = np.asarray(camera.eye, float) - scene.vertices
        view = view / np.linalg.norm(view, axis=1)[:, None]
    ndotv = np.einsum("ij,ij->i", n, view)
    w = view - n * ndotv[:, None]
    S = scene.curvature_tensors(smooth_passes)
    w2 = np.einsum("ij,ij->i", w, w)
    ok = w2 > 1e-24
    kr = np.where(ok, np.einsum("vi,vij,vj->v", w, S, w) / np.where(ok, w2, 1.0), 0.0)
    return kr, ndotv, w


def face_gradients(scene: Scene, values: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(S, 3) world gradient of the linear interpolant of per-vertex `values` (V,) on `faces`."""
    f = scene.faces[faces]
    P = scene.vertices[f]
    n = scene.face_normals[faces]
    g = np.zeros((len(faces), 3))
    # grad = sum_k value_k (n x e_k) / (2A), e_k the edge opposite vertex k, counter-clockwise.
    for k in range(3):
        e = P[:, (k + 2) % 3] - P[:, (k + 1) % 3]
        g += values[f[:, k]][:, None] * np.cross(n, e)
    return g / (2.0 * scene.face_areas[faces])[:, None]


def suggestive_contour_edges(view: FrameView, options: LineOptions | None = None,
                             smooth_passes: int | None = None, return_tests: bool = False):
    """Suggestive contour segments of one frame (kind "suggestive"), one per face, endpoints on
    mesh edges (chaining keys V + edge index, as smooth contours).

    Kept where (1) all three vertices and the face itself face the eye (n.v > 0), (2) k_r changes
    sign across the face and its largest |k_r| there is at least `suggestive_kr_threshold` / R,
    (3) the derivative test T = R^2 D_w k_r tan(theta) > `suggestive_derivative_threshold`, with
    R the scene radius (so the test does not depend on the scene's scale), D_w k_r the derivative
    along the unit projected view direction and tan(theta) = |w| / n.v (as DeCarlo et al.'s
    D_w k_r / cos(theta) with unnormalized w: it removes lines where the eye looks straight down
    the normal, where they are unstable). With `return_tests`, also returns T (S,) per segment."""

    scene, camera = view.scene, view.camera
    opts = options or LineOptions()
    R = scene.radius
    kr, ndotv, w = radial_curvature(scene, camera, SMOOTH_PASSES if smooth_passes is None else smooth_passes)
    f = scene.faces
    front = (ndotv[f] > 0).all(axis=1) & view.front_facing
    if opts.suggestive_kr_threshold > 0:
        front &= np.abs(kr[f]).max(axis=1) >= opts.suggestive_kr_threshold / R
    zs = zero_set_segments(scene, kr, front)
    faces, ia, ib = zs.faces, zs.ia, zs.ib
    test = np.zeros(0)
    if len(faces):
        grad = face_gradients(scene, kr, faces)
        wm = w[f[faces]].mean(axis=1)
        wl = np.linalg.norm(wm, axis=1)
        dwkr = np.einsum("ij,ij->i", grad, wm) / np.maximum(wl, 1e-300)
        tan_theta = wl / np.maximum(ndotv[f[faces]].mean(axis=1), 1e-300)
        test = R * R * dwkr * tan_theta
        keep = test > opts.suggestive_derivative_threshold
        faces, ia, ib, test = faces[keep], ia[keep], ib[keep], test[keep]
    if len(faces) == 0:
        out = FeatureEdges.empty()
        return (out, test) if return_tests else out
    pts = zs.interpolate(scene, scene.vertices)
    key = zs.keys  # V + edge index
    # Lines on front faces: a ray to the eye leaves the face on its open side; a small lift
    # along the face normal keeps float32 rounding in the neighbouring faces from catching it.
    lift = scene.face_normals[faces] * (0.25 * scene.face_scale()[faces] + 1e-6 * R)[:, None]
    out = FeatureEdges(a=pts[ia], b=pts[ib], kind=np.full(len(faces), KIND_INDEX["suggestive"], np.int8),
                       va=key[ia], vb=key[ib], face=faces.astype(np.int64), lift=lift)
    return (out, test) if return_tests else out
