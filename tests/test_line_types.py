"""Smooth contours, suggestive contours and intersection lines (issue 8).

Each test checks geometry against an analytic answer (sphere contour circle, torus radial
curvature, box-box intersection polygon) or a property the issue states (no stroke reversal
except at cusps, closed intersection loops, touching objects give nothing)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh
from scipy.spatial import cKDTree

from strokekit.camera.view import Camera
from strokekit.lines.contours import smooth_contour_edges
from strokekit.lines.facing import FrameView
from strokekit.lines.features import feature_edges
from strokekit.lines.intersections import intersection_edges
from strokekit.lines.renderer import LineRenderer
from strokekit.lines.suggestive import suggestive_contour_edges
from strokekit.metrics.accuracy import screen_reversals, smooth_contour_wrongly_hidden
from strokekit.model import KIND_INDEX, KINDS
from strokekit.options import LineOptions
from strokekit.scene.load import build_scene, load_scene

MODELS = Path(__file__).resolve().parents[1].parent / "shared" / "models"


def torus_scene(R=1.0, r=0.35, nu=240, nv=96):
    """Torus around z (major radius R, tube radius r), outward normals, nu x nv quads split in two."""
    u = np.linspace(0, 2 * np.pi, nu, endpoint=False)
    v = np.linspace(0, 2 * np.pi, nv, endpoint=False)
    U, Vv = np.meshgrid(u, v, indexing="ij")
    P = np.stack([(R + r * np.cos(Vv)) * np.cos(U), (R + r * np.cos(Vv)) * np.sin(U), r * np.sin(Vv)], -1)
    i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    a, b = i * nv + j, ((i + 1) % nu) * nv + j
    c, d = ((i + 1) % nu) * nv + (j + 1) % nv, i * nv + (j + 1) % nv
    F = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    return P.reshape(-1, 3), F


def two_meshes(m1, m2):
    v = np.vstack([m1[0], m2[0]])
    f = np.vstack([m1[1], m2[1] + len(m1[0])])
    fo = np.r_[np.zeros(len(m1[1])), np.ones(len(m2[1]))]
    return build_scene(v, f, fo, objects=("a", "b"))


def box(extents, center):
    m = trimesh.creation.box(extents=extents)
    m.apply_translation(center)
    return np.asarray(m.vertices), np.asarray(m.faces)


def point_segment_distance(p, a, b):
    """(N,) distance from 2D points p (N, 2) to the nearest of segments a-b (M, 2)."""
    d = b - a
    L2 = np.maximum((d * d).sum(1), 1e-300)
    t = np.clip(((p[:, None, :] - a[None]) * d[None]).sum(-1) / L2[None], 0, 1)
    q = a[None] + t[..., None] * d[None]
    return np.linalg.norm(p[:, None, :] - q, axis=-1).min(axis=1)


def sample_segments(a, b, n=9):
    s = np.linspace(0, 1, n)[:, None, None]
    return (a[None] * (1 - s) + b[None] * s).reshape(-1, a.shape[1])


# --- smooth contours ------------------------------------------------------------------------


@pytest.fixture(scope="module")
def sphere():
    m = trimesh.creation.icosphere(subdivisions=6, radius=1.0)
    return build_scene(m.vertices, m.faces)


SPHERE_EYE = np.array([0.3, 0.5, 4.0])


def sphere_circle_px(cam, eye):
    """Dense pixel samples of the analytic contour circle of the unit sphere seen from `eye`."""
    d = np.linalg.norm(eye)
    u = -eye / d
    a1 = np.cross(u, [0.0, 1.0, 0.0])
    a1 /= np.linalg.norm(a1)
    a2 = np.cross(u, a1)
    th = np.linspace(0, 2 * np.pi, 400_000, endpoint=False)
    circ = eye / d ** 2 + np.sqrt(1 - 1 / d ** 2) * (np.cos(th)[:, None] * a1 + np.sin(th)[:, None] * a2)
    return cam.project(circ)[0]


def test_sphere_smooth_contour_on_analytic_circle(sphere):
    """Rendered smooth contour strokes lie within 0.05 px of the analytic circle at 1024 x 1024,
    closer on average than the mesh contour, and are one closed, fully visible stroke."""
    cam = Camera(eye=tuple(SPHERE_EYE), target=(0, 0, 0), fov_y=40, width=1024, height=1024)
    circle = cKDTree(sphere_circle_px(cam, SPHERE_EYE))
    st = LineRenderer(sphere, LineOptions(contours="smooth")).render(cam)
    assert set(st.kind.tolist()) == {KIND_INDEX["smooth_contour"]}
    assert len(st) == 1
    pts = st.points
    assert np.allclose(pts[0], pts[-1], atol=1e-6)  # closed
    dense = sample_segments(pts[:-1], pts[1:])
    err, _ = circle.query(dense)
    assert err.max() < 0.05
    # Fully visible: the drawn length is the circle's length (nothing wrongly hidden).
    circ_px = sphere_circle_px(cam, SPHERE_EYE)
    circumference = np.linalg.norm(np.diff(np.vstack([circ_px, circ_px[:1]]), axis=0), axis=1).sum()
    assert abs(st.lengths.sum() / circumference - 1) < 1e-3
    # The mesh contour (zig-zag over vertices) is further from the circle on average.
    E = sphere.edges[FrameView(sphere, cam).silhouettes]
    pa, _ = cam.project(sphere.vertices[E[:, 0]])
    pb, _ = cam.project(sphere.vertices[E[:, 1]])
    mesh_err, _ = circle.query(sample_segments(pa, pb))
    assert err.mean() < 0.5 * mesh_err.mean()


def test_smooth_contours_replace_mesh_silhouettes(sphere):
    """contours="smooth" swaps silhouette edges for smooth_contour segments; mesh stays default."""
    cam = Camera(eye=tuple(SPHERE_EYE), target=(0, 0, 0))
    fe_mesh = feature_edges(FrameView(sphere, cam), LineOptions())
    fe_smooth = feature_edges(FrameView(sphere, cam), LineOptions(contours="smooth"))
    assert set(fe_mesh.kind.tolist()) == {KIND_INDEX["silhouette"]}
    assert set(fe_smooth.kind.tolist()) == {KIND_INDEX["smooth_contour"]}
    # Smooth contour endpoints lie on the zero set of the interpolated n.(P - eye).
    n = sphere.vertex_normals
    assert fe_smooth.lift is not None and fe_smooth.lift.shape == fe_smooth.a.shape
    assert np.all(fe_smooth.va >= len(sphere.vertices))  # keys are V + edge index (no cusp on a sphere)
    np.testing.assert_allclose(np.einsum("ij,ij->i", fe_smooth.a, fe_smooth.a), 1.0, atol=1e-5)
    assert len(n) == len(sphere.vertices)


@pytest.mark.parametrize("scale, shift", [(1e-3, 1e5), (1e4, 0.0)])
def test_smooth_contour_scale_and_ortho(sphere, scale, shift):
    """Scaled / far-translated spheres and an orthographic view: the smooth contour stays on the
    analytic circle (radius 1 around the view axis for ortho) and fully visible (lifts are
    relative to the mesh, not absolute)."""
    sc = build_scene(sphere.vertices * scale + shift, sphere.faces)
    c = np.full(3, shift)
    cam = Camera(eye=tuple(c + scale * np.array([0.0, 0.0, 5.0])), target=tuple(c), projection="orthographic",
                 ortho_height=2.5 * scale, width=1024, height=1024)
    st = LineRenderer(sc, LineOptions(contours="smooth")).render(cam)
    assert len(st) == 1
    r_px = np.linalg.norm(st.points - 512.0, axis=1) / cam.focal_px / scale
    assert np.abs(r_px - 1).max() < 2e-4
    assert abs(st.lengths.sum() / (2 * np.pi * cam.focal_px * scale) - 1) < 1e-3


def contour_truth_wrongly_hidden(scene, cams):
    """Share of smooth contour length reported hidden although a visible exact mesh contour
    (BRIEF 2) runs within 1 px on screen and two face sizes in space."""
    return smooth_contour_wrongly_hidden(scene, cams, tol_px=1.0)[0]


def orbit_cams(scene, n=4, dist=3.0):
    out = []
    for k in range(n):
        a, el = 2 * np.pi * k / n + 0.3, 0.5 * np.sin(k)
        eye = scene.center + scene.radius * dist * np.array([np.cos(a) * np.cos(el), np.sin(el), np.sin(a) * np.cos(el)])
        out.append(Camera(eye=tuple(eye), target=tuple(scene.center), fov_y=40))
    return out


def test_torus_smooth_contour_not_wrongly_hidden():
    """Below 0.1 % of the torus's smooth contour is reported hidden where the exact mesh contour
    is visible; without the lift the rays graze the faces and far more is lost."""
    sc = build_scene(*torus_scene(nu=160, nv=64))
    frac = contour_truth_wrongly_hidden(sc, orbit_cams(sc))
    assert frac < 1e-3


@pytest.mark.skipif(not (MODELS / "stanford-bunny.obj").exists(), reason="shared models absent")
def test_bunny_smooth_contour_not_wrongly_hidden():
    """The bunny scan's bumps make grazing rays hit nearby facets: the lift keeps the wrongly
    hidden share of its smooth contour below 0.1 % (it is ~27 % without)."""
    sc = load_scene(MODELS / "stanford-bunny.obj")
    assert contour_truth_wrongly_hidden(sc, orbit_cams(sc, 6)) < 1e-3


@pytest.mark.skipif(not (MODELS / "stanford-bunny.obj").exists(), reason="shared models absent")
def test_bunny_smooth_contour_reverses_only_at_cusps():
    """On the bunny, two linked smooth contour segments never turn back on screen: every screen
    tangent reversal is a detected cusp (key -1), and strokes never reverse."""
    sc = load_scene(MODELS / "stanford-bunny.obj")
    cam = orbit_cams(sc, 3)[1]
    counts = []
    for split in (False, True):
        counts.append(screen_reversals(smooth_contour_edges(FrameView(sc, cam), split_cusps=split), cam))
    assert counts[0] > 0  # the bunny's contour does have cusps
    assert counts[1] == 0
    st = LineRenderer(sc, LineOptions(contours="smooth", kinds=("silhouette",))).render(cam)
    sop = st.stroke_of_point
    seg = np.diff(st.points, axis=0)
    same = sop[1:] == sop[:-1]
    idx = np.flatnonzero(same[1:] & same[:-1])
    assert (np.einsum("ij,ij->i", seg[idx], seg[idx + 1]) < -1e-12).sum() == 0


# --- suggestive contours --------------------------------------------------------------------

RT, rt = 1.0, 0.35


def torus_frame(u, v):
    cu, su, cv, sv = np.cos(u), np.sin(u), np.cos(v), np.sin(v)
    P = np.stack([(RT + rt * cv) * cu, (RT + rt * cv) * su, rt * sv], -1)
    n = np.stack([cv * cu, cv * su, sv], -1)
    eu, ev = np.stack([-su, cu, 0 * u], -1), np.stack([-sv * cu, -sv * su, cv], -1)
    return P, n, eu, ev, cv / (RT + rt * cv), np.full_like(u, 1 / rt)


def torus_radial_curvature(u, v, eye):
    """Analytic k_r (principal curvatures cos v / (R + r cos v) along u, 1 / r along v), n.v, w."""
    P, n, eu, ev, ku, kv = torus_frame(u, v)
    view = eye - P
    view /= np.linalg.norm(view, axis=-1, keepdims=True)
    nd = (n * view).sum(-1)
    w = view - n * nd[..., None]
    a, b = (w * eu).sum(-1), (w * ev).sum(-1)
    return (ku * a * a + kv * b * b) / (a * a + b * b), nd, a, b, P


def analytic_suggestive(eye, scene_radius, N=1200):
    """Points of the torus where k_r = 0, n.v > 0 and D_w k_r > 0, with the test value
    R^2 D_w k_r tan(theta) of each, from the closed-form curvature on a fine parameter grid."""
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, 2 * N, endpoint=False),
                       np.linspace(0, 2 * np.pi, N, endpoint=False), indexing="ij")
    kr, nd, _, _, _ = torus_radial_curvature(u, v, eye)
    pts, tests = [], []
    steps = (2 * np.pi / (2 * N), 2 * np.pi / N)
    for ax in (0, 1):
        k2, nd2 = np.roll(kr, -1, ax), np.roll(nd, -1, ax)
        m = (kr * k2 < 0) & (nd > 0) & (nd2 > 0)
        t = kr[m] / (kr[m] - k2[m])
        uu = u[m] + (t * steps[0] if ax == 0 else 0)
        vv = v[m] + (t * steps[1] if ax == 1 else 0)
        _, ndx, a, b, X = torus_radial_curvature(uu, vv, eye)
        wl, h = np.hypot(a, b), 1e-5
        du, dv = h * (a / wl) / (RT + rt * np.cos(vv)), h * (b / wl) / rt
        D = (torus_radial_curvature(uu + du, vv + dv, eye)[0] - torus_radial_curvature(uu - du, vv - dv, eye)[0]) / (2 * h)
        pts.append(X)
        tests.append(scene_radius ** 2 * D * wl / ndx)
    return np.concatenate(pts), np.concatenate(tests)


def test_curvature_tensor_on_torus():
    """Per-vertex curvature tensors have the torus's principal curvatures (and 0 along n)."""
    sc = build_scene(*torus_scene(nu=200, nv=80))
    ev = np.sort(np.linalg.eigvalsh(sc.curvature_tensors()), axis=1)
    rho = np.hypot(sc.vertices[:, 0], sc.vertices[:, 1])
    cv = (rho - RT) / rt
    expect = np.sort(np.stack([np.zeros_like(cv), cv / (RT + rt * cv), np.full_like(cv, 1 / rt)], 1), axis=1)
    assert np.abs(ev - expect).max() < 0.02 / rt


@pytest.mark.parametrize("eye", [(0.0, -4.0, 2.5), (3.0, 1.0, 1.2)])
def test_torus_suggestive_contours_where_theory_puts_them(eye):
    """Suggestive contours on a torus lie on the analytic zero set of the radial curvature with
    positive derivative (precision), and every strong analytic piece is drawn (recall)."""
    eye = np.array(eye)
    sc = build_scene(*torus_scene())
    cam = Camera(eye=tuple(eye), target=(0, 0, 0), fov_y=40)
    thr = 0.05
    fe = suggestive_contour_edges(FrameView(sc, cam), LineOptions(suggestive_derivative_threshold=thr))
    assert len(fe) > 20 and set(fe.kind.tolist()) == {KIND_INDEX["suggestive"]}
    X, T = analytic_suggestive(eye, sc.radius)
    M = sample_segments(fe.a, fe.b, 5)
    d_prec, _ = cKDTree(X[T > thr]).query(M)
    d_rec, _ = cKDTree(M).query(X[T > 1.0])
    # Face size ~ 0.026 (tube) x 0.035 (ring); the lines sit well inside one face of theory.
    assert np.median(d_prec) < 0.003 and np.quantile(d_prec, 0.95) < 0.01 and d_prec.max() < 0.06
    assert np.quantile(d_rec, 0.95) < 0.01 and d_rec.max() < 0.04
    # Only on front faces.
    fn = sc.face_normals[fe.face]
    assert np.all(np.einsum("ij,ij->i", fn, eye - 0.5 * (fe.a + fe.b)) > 0)


def test_sphere_has_no_suggestive_contours(sphere):
    """k_r = 1/r > 0 everywhere on a sphere: no zero crossing, no suggestive contour."""
    cam = Camera(eye=tuple(SPHERE_EYE), target=(0, 0, 0))
    assert len(suggestive_contour_edges(FrameView(sphere, cam), LineOptions(suggestive_derivative_threshold=0.0))) == 0


# --- intersection lines ---------------------------------------------------------------------

BOX_B = ((1.0, 1.1, 1.2), (0.93, 0.31, 0.17))


def analytic_box_intersection():
    """3D segments of (boundary of A = [-1,1]^3) ∩ (boundary of box B), per face of A: the
    outline of B's cross-section in the face plane, clipped to the face (shapely)."""
    from shapely.geometry import box as sbox

    ext, ctr = np.array(BOX_B[0]), np.array(BOX_B[1])
    lo, hi = ctr - ext / 2, ctr + ext / 2
    segs = []
    for ax in range(3):
        o1, o2 = [k for k in range(3) if k != ax]
        for c in (-1.0, 1.0):
            if not lo[ax] < c < hi[ax]:
                continue
            section = sbox(lo[o1], lo[o2], hi[o1], hi[o2]).exterior
            cut = section.intersection(sbox(-1, -1, 1, 1))
            for g in getattr(cut, "geoms", [cut]):
                xy = np.asarray(g.coords)
                for p, q in zip(xy[:-1], xy[1:]):
                    a3, b3 = np.zeros(3), np.zeros(3)
                    a3[ax] = b3[ax] = c
                    a3[[o1, o2]], b3[[o1, o2]] = p, q
                    segs.append((a3, b3))
    a, b = np.array(segs).transpose(1, 0, 2)
    return a, b


@pytest.fixture(scope="module")
def boxes():
    return two_meshes(box((2, 2, 2), (0, 0, 0)), box(*BOX_B))


def test_box_intersection_matches_analytic_polyline(boxes):
    """Two interpenetrating boxes: every intersection segment lies within 0.01 px of the
    analytic polyline and covers it (both ways), and the segments form closed loops."""
    cam = Camera(eye=(3.0, 2.2, 4.0), target=(0.2, 0.1, 0.0), fov_y=40, width=1024, height=1024)
    fe = intersection_edges(boxes)
    assert len(fe) > 0 and set(fe.kind.tolist()) == {KIND_INDEX["intersection"]}
    A, B = analytic_box_intersection()
    pa, _ = cam.project(A)
    pb, _ = cam.project(B)
    fa, _ = cam.project(fe.a)
    fb, _ = cam.project(fe.b)
    assert point_segment_distance(sample_segments(fa, fb, 17), pa, pb).max() < 0.01
    assert point_segment_distance(sample_segments(pa, pb, 65), fa, fb).max() < 0.01
    np.testing.assert_allclose(np.linalg.norm(fe.b - fe.a, axis=1).sum(),
                               np.linalg.norm(B - A, axis=1).sum(), rtol=1e-9)
    _, deg = np.unique(np.r_[fe.va, fe.vb], return_counts=True)
    assert np.all(deg == 2)
    # Through the pipeline: visible intersection strokes stay on the analytic polyline.
    st = LineRenderer(boxes, LineOptions(kinds=("intersection",))).render(cam)
    assert st.lengths.sum() > 50
    assert point_segment_distance(st.points, pa, pb).max() < 0.01


@pytest.mark.parametrize("center", [(1.5, 0.2, 0.1), (1.5, 1.5, 1.5), (1.5, 1.5, 0.3)])
def test_touching_boxes_give_no_intersection(center):
    """Boxes sharing part of a face, a corner or an edge touch but do not cross: no line."""
    sc = two_meshes(box((2, 2, 2), (0, 0, 0)), box((1, 1, 1), center))
    assert len(intersection_edges(sc)) == 0


def test_torus_through_cylinder_gives_closed_loops():
    """A cylinder through the torus tube (twice) meets the torus surface in four closed loops."""
    cyl = trimesh.creation.cylinder(radius=0.15, height=3.0, sections=48)
    cyl.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [0, 1, 0]))
    sc = two_meshes(torus_scene(nu=160, nv=64), (np.asarray(cyl.vertices), np.asarray(cyl.faces)))
    fe = intersection_edges(sc)
    keys, inv = np.unique(np.r_[fe.va, fe.vb], return_inverse=True)
    assert np.all(np.bincount(inv) == 2)  # every endpoint joins exactly two segments: closed
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n = len(fe)
    g = coo_matrix((np.ones(n), (inv[:n], inv[n:])), shape=(len(keys), len(keys)))
    n_loops, _ = connected_components(g, directed=False)
    assert n_loops == 4
    # Each loop circles the cylinder axis (x) at radius 0.15 where it meets the tube.
    np.testing.assert_allclose(np.hypot(fe.a[:, 1], fe.a[:, 2]), 0.15, atol=0.15 * (1 - np.cos(np.pi / 48)) + 1e-9)


def test_feature_edges_select_new_kinds(boxes):
    """--kinds selects each new kind on its own; the default kinds draw none of them."""
    cam = Camera(eye=(3.0, 2.2, 4.0), target=(0.2, 0.1, 0.0))
    for kind in ("smooth_contour", "intersection"):
        fe = feature_edges(FrameView(boxes, cam), LineOptions(kinds=(kind,)))
        assert set(fe.kind.tolist()) == {KIND_INDEX[kind]}, kind
    default = feature_edges(FrameView(boxes, cam), LineOptions())
    new = {KIND_INDEX[k] for k in ("smooth_contour", "suggestive", "intersection")}
    assert not new & set(default.kind.tolist())
    assert KINDS[int(default.kind[0])] in LineOptions().kinds


# --- smooth contours with normals split at creases ---------------------------------------------


def _canonical_matches(p, q, tol):
    """True if polylines p, q (n, 2) are the same within `tol` px, up to direction and, for closed
    ones, the starting point."""
    if len(p) != len(q):
        return False
    closed = np.allclose(p[0], p[-1], atol=tol) and np.allclose(q[0], q[-1], atol=tol)
    cands = [q, q[::-1]]
    if closed:
        ring = q[:-1]
        cands = [np.vstack([np.roll(r, -k, axis=0), np.roll(r, -k, axis=0)[:1]])
                 for r in (ring, ring[::-1]) for k in range(len(ring))]
    return any(np.abs(p - c).max() < tol for c in cands)


def strokes_by_kind(st):
    out = {}
    for i in range(len(st)):
        out.setdefault(KINDS[int(st.kind[i])], []).append(st.points[st.stroke(i)])
    return out


def box_on_slab():
    """A box standing on a thin ground slab (two objects, every crease 90 degrees)."""
    return two_meshes(box((1.0, 0.8, 1.2), (0.0, 0.4, 0.0)), box((4.0, 0.2, 3.0), (0.0, -0.1, 0.0)))


@pytest.mark.parametrize("cam", [
    Camera(eye=(2.5, 2.0, 3.5), target=(0.0, 0.3, 0.0), fov_y=40, width=1024, height=1024),
    Camera(eye=(-3.0, 1.2, 1.0), target=(0.0, 0.3, 0.0), fov_y=40, width=1024, height=1024),
    Camera(eye=(0.7, 3.0, 2.0), target=(0.0, 0.0, 0.0), projection="orthographic", ortho_height=5.0,
           width=1024, height=1024),
    # The eye in the plane of the box's +x face: that face is edge-on, decided as in mesh mode.
    Camera(eye=(0.5, 4.0, -2.0), target=(0.0, 0.3, 0.0), fov_y=40, width=1024, height=1024),
])
def test_box_smooth_contours_are_the_mesh_silhouettes(cam):
    """Flat faces with normals split at their 90 degree creases hold no smooth contour: with
    contours="smooth" a box on a slab is drawn exactly as with mesh contours (the silhouette
    strokes become smooth_contour strokes, point for point within 1e-6 px, partly hidden ones
    included; the creases are the same strokes)."""
    sc = box_on_slab()
    mesh = strokes_by_kind(LineRenderer(sc, LineOptions(contours="mesh")).render(cam))
    smooth = strokes_by_kind(LineRenderer(sc, LineOptions(contours="smooth")).render(cam))
    mesh["smooth_contour"] = mesh.pop("silhouette")
    assert sorted(mesh) == sorted(smooth)
    for kind, strokes in mesh.items():
        assert len(strokes) == len(smooth[kind]), kind
        left = list(smooth[kind])
        for p in strokes:
            k = next(i for i, q in enumerate(left) if _canonical_matches(p, q, 1e-6))
            left.pop(k)
    # No zero crossing inside the flat faces: every smooth contour segment lies on a mesh edge.
    fe = smooth_contour_edges(FrameView(sc, cam))
    assert np.all((fe.va < len(sc.vertices)) & (fe.vb < len(sc.vertices)))


def cylinder_scene(R=0.5, H=2.0, sections=128):
    m = trimesh.creation.cylinder(radius=R, height=H, sections=sections)
    return build_scene(np.asarray(m.vertices), np.asarray(m.faces))


@pytest.mark.parametrize("eye", [(3.0, 1.5, 3.0), (-2.5, 2.0, -2.0), (2.0, -3.0, -1.5)])
def test_cylinder_smooth_sides_and_sharp_rims(eye):
    """A cylinder (axis z, flat caps, 90 degree rims): the smooth contour on the sides is the pair
    of analytic tangent lines (within 0.05 px at 1024 x 1024), the caps' rims come from the
    sharp-edge fallback (pieces on the rim polygon, the far half of one rim and the near half of
    the other), and all of it chains into one closed stroke that draws every segment."""
    R, H = 0.5, 2.0
    sc = cylinder_scene(R, H)
    V = len(sc.vertices)
    eye = np.array(eye)
    cam = Camera(eye=tuple(eye), target=(0, 0, 0), up=(0, 0, 1), fov_y=40, width=1024, height=1024)
    fe = smooth_contour_edges(FrameView(sc, cam))
    on_rim = (np.abs(np.abs(fe.a[:, 2]) - H / 2) < 1e-12) & (np.abs(np.abs(fe.b[:, 2]) - H / 2) < 1e-12)
    side = ~on_rim
    # Tangent lines: phi = atan2(e_y, e_x) +- acos(R / rho_e), for every height.
    base, half = np.arctan2(eye[1], eye[0]), np.arccos(R / np.hypot(eye[0], eye[1]))
    lines = []
    for ph in (base + half, base - half):
        a = np.array([[R * np.cos(ph), R * np.sin(ph), -H / 2], [R * np.cos(ph), R * np.sin(ph), H / 2]])
        lines.append(cam.project(a)[0])
    ends = np.vstack([cam.project(fe.a[side])[0], cam.project(fe.b[side])[0]])
    assert side.sum() >= 4  # each line crosses at least the two triangles of one side quad
    err = np.min([point_segment_distance(ends, ln[:1], ln[1:]) for ln in lines], axis=0)
    assert err.max() < 0.05
    # Both lines are present, from rim to rim.
    for ln in lines:
        d = point_segment_distance(sample_segments(ln[:1], ln[1:], 33), cam.project(fe.a[side])[0],
                                   cam.project(fe.b[side])[0])
        assert d.max() < 0.05
    # Rim pieces: on the rim edges, where the cap and the side (interpolated) face opposite ways.
    rim_len = np.linalg.norm(fe.b[on_rim] - fe.a[on_rim], axis=1).sum()
    assert abs(rim_len / (2 * np.pi * R) - 1) < 0.02  # half of each rim
    assert np.all(np.abs(np.hypot(fe.a[on_rim, 0], fe.a[on_rim, 1]) - R) < 1e-3)
    # Chained without gaps: one closed stroke as long as all segments together.
    st = LineRenderer(sc, LineOptions(contours="smooth", kinds=("silhouette",))).render(cam)
    assert len(st) == 1 and set(st.kind.tolist()) == {KIND_INDEX["smooth_contour"]}
    assert np.allclose(st.points[0], st.points[-1], atol=1e-9)
    seg_px = np.linalg.norm(cam.project(fe.b)[0] - cam.project(fe.a)[0], axis=1).sum()
    assert abs(st.lengths.sum() / seg_px - 1) < 1e-6
    # The side segments reach the rims on split-edge keys that rim pieces share.
    keys = np.r_[fe.va, fe.vb]
    split_keys = keys[keys >= V + len(sc.edges)]
    assert len(split_keys) == 8 and np.all(np.unique(split_keys, return_counts=True)[1] == 2)


def test_sphere_smooth_contour_unchanged_by_split_normals(sphere):
    """A sphere has no crease: split normals are the vertex normals, and the smooth contour is
    bit for bit the zero set of the vertex normal view function (no sharp-edge pieces)."""
    from strokekit.lines.contours import phong_points, zero_set_segments
    from strokekit.scene.tables import view_function

    sn = sphere.split_normals(60.0)
    assert not sn.split.any() and np.array_equal(sn.corner, sphere.faces)
    assert np.array_equal(sn.normals, sphere.vertex_normals)
    cam = Camera(eye=tuple(SPHERE_EYE), target=(0, 0, 0))
    fe = smooth_contour_edges(FrameView(sphere, cam))
    zs = zero_set_segments(sphere, view_function(sphere, cam))
    pts = phong_points(sphere, zs, sphere.vertex_normals)
    assert np.array_equal(fe.a, pts[zs.ia]) and np.array_equal(fe.b, pts[zs.ib])
    V = len(sphere.vertices)
    assert np.array_equal(fe.va, V + zs.edges[zs.ia]) and np.array_equal(fe.vb, V + zs.edges[zs.ib])


def test_crease_threshold_splits_normals():
    """Corners share a normal only across edges gentler than the crease threshold: a 64-sided
    cylinder's side edges turn by 5.6 degrees, so a threshold of 5 degrees splits every side
    edge too (the sides become flat facets: no smooth contour inside a face), 60 only the rims."""
    sc = cylinder_scene(sections=64)
    H = 2.0
    ez = sc.vertices[sc.edges][:, :, 2]  # (E, 2) heights of each edge's ends
    on_circle = (np.linalg.norm(sc.vertices[sc.edges][:, :, :2], axis=-1) > 0.25).all(axis=1)  # not a cap's spoke
    rim = (ez[:, 0] == ez[:, 1]) & (np.abs(ez[:, 0]) == H / 2) & on_circle
    side = ez[:, 0] == -ez[:, 1]  # from one rim to the other: vertical side edges and the diagonals
    vertical = side & (np.abs(sc.vertices[sc.edges[:, 0], :2] - sc.vertices[sc.edges[:, 1], :2]).max(axis=1) < 1e-12)
    assert rim.sum() == 128 and vertical.sum() == 64
    fn = sc.face_normals
    cap = np.abs(fn[:, 2]) > 0.5
    smooth, facets = sc.split_normals(60.0), sc.split_normals(5.0)
    assert np.array_equal(smooth.split, rim)
    assert np.array_equal(facets.split, rim | vertical)  # the rims and the vertical side edges
    # A corner's normal: a cap's is the cap's; a side corner's is radial at 60 degrees (the
    # angle-weighted mean of the two side faces at it), its own face's at 5 degrees.
    P = sc.vertices[sc.faces[~cap]]  # (side faces, 3, 3) corner positions
    radial = P * [1, 1, 0] / np.linalg.norm(P[..., :2], axis=-1, keepdims=True)
    for sn in (smooth, facets):
        n = sn.normals[sn.corner]  # (F, 3, 3)
        assert np.abs(n[cap] - fn[cap][:, None, :]).max() < 1e-12
    assert np.abs(smooth.normals[smooth.corner][~cap] - radial).max() < 1e-9
    assert np.abs(facets.normals[facets.corner][~cap] - fn[~cap][:, None, :]).max() < 1e-12
    cam = Camera(eye=(3.0, 1.5, 3.0), target=(0, 0, 0), up=(0, 0, 1))
    fe = smooth_contour_edges(FrameView(sc, cam), crease_angle_deg=5.0)
    V = len(sc.vertices)
    assert np.all((fe.va < V) & (fe.vb < V))
    np.testing.assert_array_equal(np.sort(np.sort(np.c_[fe.va, fe.vb], axis=1), axis=0),
                                  np.sort(sc.edges[FrameView(sc, cam).silhouettes], axis=0))
