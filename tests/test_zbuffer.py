"""Tests of the z-buffer kernel (strokekit/raster/zbuffer.py) against open3d ray casting (the
ray-cast raster pass, its reference) and of its coverage rules (issue 17)."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import MODELS
from zbuffer_reference import O3DReference, bounds_sphere, exact_hits, grid_positions, look_at, pixel_positions

from strokekit.raster import zbuffer as zb

BUNNY = MODELS / "stanford-bunny.obj"
# A sample counts as "near an edge" closer than this (px) to an edge of the face either side
# reports (or to the near plane's cut of it): there float32 Embree and float64 edge functions may
# legitimately disagree.
EDGE_PX = 1e-2


@pytest.fixture(scope="module")
def bunny():
    if not BUNNY.exists():
        pytest.skip("shared bunny model missing")
    import trimesh

    m = trimesh.load(BUNNY)
    V, F = np.asarray(m.vertices, float), np.asarray(m.faces)
    return V, F, O3DReference(V, F)


def _box(n=4):
    """Closed cube [-1, 1]^3, each side an n x n grid of quads (2 triangles each), outward."""
    import trimesh

    m = trimesh.creation.box(extents=(2.0, 2.0, 2.0))
    for _ in range(int(np.log2(n))):
        m = m.subdivide()
    return np.asarray(m.vertices, float), np.asarray(m.faces)


def compare(V, F, ref, view, ours: zb.ZHits, x, y):
    """Agreement stats of our hits (flattened in sample order) with open3d at the same pixel
    positions x, y."""
    o = ref.cast(view, x, y)
    f = ours.face.reshape(-1)
    fo = o["face"]
    d_ours = exact_hits(V, F, view, f, x, y)
    d_ref = exact_hits(V, F, view, fo, x, y)
    near_edge = (np.nan_to_num(d_ours[3], nan=np.inf) < EDGE_PX) | (np.nan_to_num(d_ref[3], nan=np.inf) < EDGE_PX)
    away = ~near_edge
    agree = f == fo
    both = agree & (f >= 0) & away
    z, zo = ours.depth.reshape(-1).astype(float), o["depth"].astype(float)
    b, bo = ours.bary.reshape(-1, 2).astype(float), o["bary"].astype(float)
    hit = f >= 0
    return {
        "n_away": int(away.sum()),
        "face_agree_away": float(agree[away].mean()),
        "n_disagree": int((~agree).sum()),
        "n_disagree_away": int((~agree & away).sum()),
        "depth_rel_vs_o3d": float(np.max(np.abs(z[both] - zo[both]) / zo[both])) if both.any() else 0.0,
        # Embree's barycentrics are float32 in a unit-radius frame: ~1e-3 off on the bunny's
        # smallest faces (ours agree with the float64 intersection to 3e-8, below).
        "bary_vs_o3d": float(np.max(np.abs(b[both] - bo[both]))) if both.any() else 0.0,
        "bary_vs_o3d_p999": float(np.percentile(np.abs(b[both] - bo[both]), 99.9)) if both.any() else 0.0,
        # Against the float64 ray-plane intersection of our own face: ours is exact to float32.
        "depth_rel_vs_exact": float(np.max(np.abs(z[hit] - d_ours[0][hit]) / d_ours[0][hit])) if hit.any() else 0.0,
        "bary_vs_exact": float(np.max(np.abs(b[hit] - d_ours[1:3, hit].T))) if hit.any() else 0.0,
        "hits": int(hit.sum()),
        "background_ok": bool(np.all(np.isinf(ours.depth.reshape(-1)[~hit]))
                              and np.all(ours.bary.reshape(-1, 2)[~hit] == 0)),
    }


def assert_matches(st, min_hits=1):
    assert st["hits"] >= min_hits
    assert st["face_agree_away"] >= 0.999, st
    assert st["depth_rel_vs_o3d"] < 1e-5, st
    assert st["bary_vs_o3d"] < 1e-2, st
    assert st["bary_vs_o3d_p999"] < 1e-3, st
    assert st["depth_rel_vs_exact"] < 1e-6, st
    assert st["bary_vs_exact"] < 1e-6, st
    assert st["background_ok"], st


def _orbit(V, az, el, dist, **kw):
    c, r = bounds_sphere(V)
    a, e = np.radians(az), np.radians(el)
    d = np.array([np.sin(a) * np.cos(e), np.sin(e), np.cos(a) * np.cos(e)])
    kw.setdefault("near", 1e-4 * r)
    return look_at(c + d * dist * r, c, **kw), c, r


# --- against the ray caster -------------------------------------------------------------------

@pytest.mark.parametrize("az,el,dist,K,size", [(20, 10, 2.8, 1, 1024), (200, 35, 2.2, 2, 512),
                                               (110, -20, 4.0, 2, 512), (300, 60, 1.4, 1, 512)])
def test_bunny_perspective_matches_raycast(bunny, az, el, dist, K, size):
    V, F, ref = bunny
    view, _, _ = _orbit(V, az, el, dist, width=size, height=size * 3 // 4)
    h = zb.rasterize_grid(zb.project(V, F, view), K)
    assert h.face.shape == (size * 3 // 4 * K, size * K)
    assert h.face.dtype == np.int32 and h.depth.dtype == np.float32 and h.bary.dtype == np.float32
    x, y = grid_positions(view, K)
    st = compare(V, F, ref, view, h, x, y)
    assert_matches(st, min_hits=1000)
    assert st["n_disagree_away"] == 0, st


@pytest.mark.parametrize("az,el", [(0, 0), (75, 25), (180, -40)])
def test_bunny_orthographic_matches_raycast(bunny, az, el):
    V, F, ref = bunny
    _, r = bounds_sphere(V)
    view, _, _ = _orbit(V, az, el, 3.0, width=512, height=384, ortho=True, ortho_height=2.4 * r)
    h = zb.rasterize_grid(zb.project(V, F, view), 2)
    st = compare(V, F, ref, view, h, *grid_positions(view, 2))
    assert_matches(st, min_hits=1000)


@pytest.mark.parametrize("ortho", [False, True])
def test_near_plane_cuts_the_bunny(bunny, ortho):
    """A near plane through the middle of the mesh (a section view): triangles cut by it are
    clipped, the inside (back faces) shows, as with rays starting on the near plane."""
    V, F, ref = bunny
    _, r = bounds_sphere(V)
    kw = dict(ortho=True, ortho_height=2.2 * r) if ortho else {}
    view, _, _ = _orbit(V, 30, 15, 2.5, width=512, height=512, near=2.5 * r, **kw)
    p = zb.project(V, F, view)
    z = p.cam[:, 2][F]
    assert ((z.min(axis=1) < view.near) & (z.max(axis=1) > view.near)).sum() > 100  # many straddle
    h = zb.rasterize_grid(p, 1)
    st = compare(V, F, ref, view, h, *grid_positions(view, 1))
    assert_matches(st, min_hits=1000)
    assert np.all(h.depth[h.face >= 0] >= view.near * (1 - 1e-6))


@pytest.mark.parametrize("eye,target,fov", [((0.3, 0.2, 0.1), (1.0, 0.5, -0.7), 100.0),
                                            ((-0.8, -0.6, 0.5), (0.0, 0.0, 0.0), 70.0),
                                            ((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 150.0)])
def test_box_from_inside(eye, target, fov):
    """Camera inside a closed box: most wall triangles cross the near plane. Every sample sees a
    wall (no holes), and matches the rays."""
    V, F = _box(4)
    ref = O3DReference(V, F)
    view = look_at(eye, target, fov_y=fov, width=400, height=300, near=0.05)
    p = zb.project(V, F, view)
    z = p.cam[:, 2][F]
    assert ((z.min(axis=1) < view.near) & (z.max(axis=1) >= view.near)).sum() >= 8
    for K in (1, 2):
        h = zb.rasterize_grid(p, K)
        assert np.all(h.face >= 0), "hole in a closed box seen from inside"
        st = compare(V, F, ref, view, h, *grid_positions(view, K))
        assert_matches(st)


def test_edge_pixels_match_grid_and_raycast(bunny):
    """rasterize_pixels(R) gives, bit for bit, the samples of rasterize_grid(R) in those pixels,
    in _edge_coverage's order, and they match the rays there."""
    V, F, ref = bunny
    view, _, _ = _orbit(V, 40, 20, 2.6, width=320, height=256)
    p = zb.project(V, F, view)
    g1 = zb.rasterize_grid(p, 1)
    f = g1.face
    edge = np.zeros(f.shape, bool)  # pixels whose face differs from a neighbour's
    edge[:, 1:] |= f[:, 1:] != f[:, :-1]
    edge[:, :-1] |= f[:, 1:] != f[:, :-1]
    edge[1:, :] |= f[1:, :] != f[:-1, :]
    edge[:-1, :] |= f[1:, :] != f[:-1, :]
    pixels = np.flatnonzero(edge)
    rng = np.random.default_rng(1)
    pixels = rng.permutation(pixels)  # any order
    assert len(pixels) > 1000
    for R in (2, 4, 8):
        hp = zb.rasterize_pixels(p, pixels, R)
        assert hp.face.shape == (len(pixels), R * R) and hp.bary.shape == (len(pixels), R * R, 2)
        hg = zb.rasterize_grid(p, R)
        py, px = np.divmod(pixels, view.width)
        a, b = np.tile(np.arange(R), R), np.repeat(np.arange(R), R)  # sample b * R + a
        rows = (py[:, None] * R + b[None, :])
        cols = (px[:, None] * R + a[None, :])
        np.testing.assert_array_equal(hp.face, hg.face[rows, cols])
        np.testing.assert_array_equal(hp.depth, hg.depth[rows, cols])
        np.testing.assert_array_equal(hp.bary, hg.bary[rows, cols])
        if R == 4:
            st = compare(V, F, ref, view, hp, *pixel_positions(view, pixels, R))
            assert_matches(st, min_hits=1000)


def test_threads_give_identical_results(bunny):
    import numba

    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("one thread only")
    V, F, _ = bunny
    view, _, _ = _orbit(V, 20, 10, 2.8, width=640, height=480)
    p = zb.project(V, F, view)
    for K in (1, 2):
        a, b = zb.rasterize_grid(p, K, threads=1), zb.rasterize_grid(p, K, threads=2)
        for name in ("face", "depth", "bary"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    pixels = np.flatnonzero(a.face[::2, ::2] >= 0)[::7]
    a, b = zb.rasterize_pixels(p, pixels, 4, threads=1), zb.rasterize_pixels(p, pixels, 4, threads=2)
    for name in ("face", "depth", "bary"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))


# --- coverage rules (exact, synthetic) -----------------------------------------------------------

def _pixel_ortho(W, H):
    """Orthographic view in which world (x, y, z > 0) lands exactly on pixel (x, y)."""
    return zb.View(eye=np.array([W / 2.0, H / 2.0, -10.0]), right=np.array([1.0, 0.0, 0.0]),
                   up=np.array([0.0, -1.0, 0.0]), fwd=np.array([0.0, 0.0, 1.0]), focal_px=1.0, width=W,
                   height=H, ortho=True, near=1e-3)


def _pixel_persp(W, H, z=4.0):
    """Perspective view (eye at the origin) in which the point (x - W/2, y - H/2, z) * ... lands
    exactly on pixel (x, y) for points at depth z: world X = (x - W/2) * z / f with f = z."""
    return zb.View(eye=np.zeros(3), right=np.array([1.0, 0.0, 0.0]), up=np.array([0.0, -1.0, 0.0]),
                   fwd=np.array([0.0, 0.0, 1.0]), focal_px=z, width=W, height=H, ortho=False, near=1e-3)


def _coverage_counts(V, F, view, K=1):
    """(per-sample count of the triangles covering it, drawn one at a time, and the mesh's
    own face buffer)."""
    counts = 0
    for fi in range(len(F)):
        h = zb.rasterize_grid(zb.project(V, F[fi:fi + 1], view), K)
        counts = counts + (h.face >= 0)
    return counts, zb.rasterize_grid(zb.project(V, F, view), K).face


def _world(view, pts_px, z=4.0):
    """World points at depth z for pixel positions (N, 2), for the exact views above."""
    pts = np.asarray(pts_px, float)
    if view.ortho:
        return np.column_stack([pts, np.full(len(pts), z)])
    W, H = view.width, view.height
    return np.column_stack([(pts[:, 0] - W / 2) * z / view.focal_px, (pts[:, 1] - H / 2) * z / view.focal_px,
                            np.full(len(pts), z)])


@pytest.mark.parametrize("make_view", [_pixel_ortho, _pixel_persp])
@pytest.mark.parametrize("diag", ["main", "anti"])
@pytest.mark.parametrize("flip", [False, True])
def test_quad_diagonal_through_sample_centres_covered_once(make_view, diag, flip):
    """A quad whose corners and diagonal lie on sample centres: every sample on the shared
    diagonal belongs to exactly one triangle, the quad has no hole, and the top-left rule takes
    the quad's left and top sides but not its right and bottom ones: exactly 8 x 8 samples."""
    W = H = 16
    view = make_view(W, H)
    c = np.array([[2.5, 3.5], [10.5, 3.5], [10.5, 11.5], [2.5, 11.5]])  # x 2.5..10.5, y 3.5..11.5
    V = _world(view, c)
    F = np.array([[0, 1, 2], [0, 2, 3]]) if diag == "main" else np.array([[0, 1, 3], [1, 2, 3]])
    if flip:  # the other winding (back side towards the camera)
        F = F[:, ::-1].copy()
    counts, face = _coverage_counts(V, F, view)
    assert counts.max() == 1, "a sample covered twice"
    expect = np.zeros((H, W), bool)
    expect[3:11, 2:10] = True
    np.testing.assert_array_equal(counts == 1, expect)
    np.testing.assert_array_equal(face >= 0, expect)


@pytest.mark.parametrize("make_view", [_pixel_ortho, _pixel_persp])
def test_fan_and_grid_on_sample_centres_covered_once(make_view):
    """Triangles around a vertex on a sample centre, and a triangulated grid whose vertices and
    edges (horizontal, vertical, diagonal) pass through sample centres, mixed windings: inside
    the mesh every sample is covered exactly once."""
    W = H = 24
    view = make_view(W, H)
    rng = np.random.default_rng(3)
    n = 5
    g = np.array([[2.5 + 4 * i, 2.5 + 4 * j] for j in range(n) for i in range(n)])
    faces = []
    for j in range(n - 1):
        for i in range(n - 1):
            a, b, c, d = j * n + i, j * n + i + 1, (j + 1) * n + i + 1, (j + 1) * n + i
            t = [[a, b, c], [a, c, d]] if rng.random() < 0.5 else [[a, b, d], [b, c, d]]
            faces += [tt[::-1] if rng.random() < 0.5 else tt for tt in t]
    # A fan around the centre vertex (12, 12) replacing nothing: drawn as its own test below.
    V = _world(view, g)
    F = np.array(faces)
    counts, face = _coverage_counts(V, F, view)
    assert counts.max() == 1
    inner = np.zeros((H, W), bool)
    inner[2:18, 2:18] = True  # [2.5, 18.5) in both axes
    np.testing.assert_array_equal(counts == 1, inner)
    np.testing.assert_array_equal(face >= 0, inner)
    # Fan of 8 triangles around (12.5, 12.5) with spokes through sample centres.
    ring = np.array([[16.5, 12.5], [16.5, 16.5], [12.5, 16.5], [8.5, 16.5], [8.5, 12.5], [8.5, 8.5],
                     [12.5, 8.5], [16.5, 8.5]])
    V2 = _world(view, np.vstack([[12.5, 12.5], ring]))
    F2 = np.array([[0, 1 + k, 1 + (k + 1) % 8] for k in range(8)])
    F2[::3] = F2[::3, ::-1]
    counts, face = _coverage_counts(V2, F2, view)
    assert counts.max() == 1
    inner = np.zeros((H, W), bool)
    inner[8:16, 8:16] = True
    np.testing.assert_array_equal(counts == 1, inner)


@pytest.mark.parametrize("K", [1, 2, 4])
def test_random_shared_edges_covered_once_perspective(K):
    """A jittered, tilted grid mesh in perspective, supersampled: no sample covered twice by
    neighbours, none missed inside."""
    rng = np.random.default_rng(7)
    n = 9
    xs, ys = np.meshgrid(np.linspace(-1, 1, n), np.linspace(-1, 1, n))
    P = np.column_stack([xs.ravel(), ys.ravel(), np.zeros(n * n)])
    P[:, :2] += rng.uniform(-0.08, 0.08, (n * n, 2)) * (np.abs(P[:, :2]) < 0.99)
    P[:, 2] = 0.3 * P[:, 0] + 0.2 * P[:, 1]
    F = []
    for j in range(n - 1):
        for i in range(n - 1):
            a, b, c, d = j * n + i, j * n + i + 1, (j + 1) * n + i + 1, (j + 1) * n + i
            F += [[a, b, c], [a, c, d]]
    F = np.array(F)
    view = look_at((0.4, 0.3, 3.0), (0.0, 0.0, 0.0), fov_y=50, width=48, height=40)
    counts, face = _coverage_counts(P, F, view, K)
    assert counts.max() == 1
    # Inside the mesh's outline (a sample inside the grid's hull of boundary vertices) no hole:
    # checked against the union of the triangles, which is the same set.
    np.testing.assert_array_equal(counts == 1, face >= 0)
    assert (face >= 0).sum() > 0.3 * face.size


def test_quad_straddling_near_plane():
    """A long quad from behind the camera to far in front: both triangles are clipped, their
    shared diagonal crosses the near plane, and the clipped pieces still cover every sample
    once; matches the rays."""
    V = np.array([[-1.0, -0.5, -2.0], [1.0, -0.5, -2.0], [1.0, -0.5, 6.0], [-1.0, -0.5, 6.0]])
    F = np.array([[0, 1, 2], [0, 2, 3]])
    for ortho in (False, True):
        view = (look_at((0.0, 0.0, 0.0), (0.0, -0.3, 1.0), fov_y=90, width=64, height=48, near=0.01) if not ortho
                else look_at((0.0, 0.0, 0.0), (0.0, -0.3, 1.0), width=64, height=48, ortho=True, ortho_height=2.0,
                             near=0.01))
        p = zb.project(V, F, view)
        assert np.any(p.cam[:, 2] < view.near) and np.any(p.cam[:, 2] > view.near)
        counts, face = _coverage_counts(V, F, view, 2)
        assert counts.max() == 1
        h = zb.rasterize_grid(p, 2)
        ref = O3DReference(V, F)
        st = compare(V, F, ref, view, h, *grid_positions(view, 2))
        assert_matches(st, min_hits=100)


def test_single_triangle_straddling_near_plane_one_corner_in_front():
    """One corner in front of the near plane (clipped to a triangle) and two in front (a quad):
    both drawn, matching the rays."""
    for V in (np.array([[-3.0, -1.0, -1.0], [3.0, -1.0, -1.0], [0.0, 0.5, 4.0]]),
              np.array([[-3.0, -1.0, 4.0], [3.0, -1.0, 4.0], [0.0, 0.5, -1.0]])):
        F = np.array([[0, 1, 2]])
        view = look_at((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), fov_y=100, width=80, height=60, near=0.1)
        h = zb.rasterize_grid(zb.project(V, F, view), 1)
        st = compare(V, F, O3DReference(V, F), view, h, *grid_positions(view, 1))
        assert_matches(st, min_hits=100)


# --- misc ----------------------------------------------------------------------------------------

def test_background_and_behind_camera():
    V = np.array([[0.0, 0.0, -5.0], [1.0, 0.0, -5.0], [0.0, 1.0, -5.0]])  # all behind the eye
    view = look_at((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), width=8, height=6)
    h = zb.rasterize_grid(zb.project(V, np.array([[0, 1, 2]]), view), 2)
    assert h.face.shape == (12, 16) and np.all(h.face == -1) and np.all(np.isinf(h.depth)) and np.all(h.bary == 0)
    h = zb.rasterize_grid(zb.project(V, np.zeros((0, 3), int), view), 1)
    assert np.all(h.face == -1)
    h = zb.rasterize_pixels(zb.project(V, np.array([[0, 1, 2]]), view), np.zeros(0, int), 4)
    assert h.face.shape == (0, 16)
    with pytest.raises(ValueError):
        zb.rasterize_pixels(zb.project(V, np.array([[0, 1, 2]]), view), np.array([3, 3]), 2)


def test_workspace_reuse_gives_same_results(bunny):
    V, F, _ = bunny
    view, _, _ = _orbit(V, 20, 10, 2.8, width=256, height=256)
    p = zb.project(V, F, view)
    w = zb.Workspace()
    a = zb.rasterize_grid(p, 2)
    b1 = zb.rasterize_grid(p, 2, work=w)
    b1 = zb.ZHits(b1.face.copy(), b1.depth.copy(), b1.bary.copy())
    view2, _, _ = _orbit(V, 90, 10, 2.8, width=256, height=256)
    zb.rasterize_grid(zb.project(V, F, view2), 2, work=w)  # another frame in between
    b2 = zb.rasterize_grid(p, 2, work=w)
    for x in (b1, b2):
        for name in ("face", "depth", "bary"):
            np.testing.assert_array_equal(getattr(a, name), getattr(x, name))


def test_sample_offsets_are_cast_pixels_rays():
    view = look_at((1.0, 2.0, 3.0), (0.0, 0.0, 0.0), width=10, height=6)
    ax, ay = zb.sample_offsets(view, 2)
    f = view.focal_px
    np.testing.assert_array_equal(ax, ((np.arange(20) + 0.5) / 2 - 5.0) / f)
    np.testing.assert_array_equal(ay, (3.0 - (np.arange(12) + 0.5) / 2) / f)


def test_view_from_camera_duck_typed():
    class Cam:  # the attributes strokekit's Camera has
        eye = (0.0, 0.0, 5.0)
        basis = (np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, -1.0]))
        focal_px = 100.0
        width, height, is_ortho = 64, 48, False

    v = zb.view_from_camera(Cam(), near=0.01)
    assert v.width == 64 and v.near == 0.01 and not v.ortho
    np.testing.assert_array_equal(v.fwd, [0.0, 0.0, -1.0])


@pytest.mark.parametrize("ortho", [False, True])
def test_shared_edge_through_sample_centre_rounded(ortho):
    """Shared edges through a sample centre at random slopes, with end points that are not exact
    in float64, so the edge functions are rounded: the sample still belongs to exactly one of the
    two triangles (both compute the same rounded value, with opposite signs)."""
    rng = np.random.default_rng(11)
    W = H = 16
    view = _pixel_ortho(W, H) if ortho else _pixel_persp(W, H, z=3.0)
    bad = 0
    for trial in range(300):
        s = np.array([7.5, 8.5])  # a sample centre
        d = rng.normal(size=2)
        d /= np.linalg.norm(d)
        a, b = s + d * rng.uniform(1, 5) / 3.0, s - d * rng.uniform(1, 5) / 3.0
        nrm = np.array([-d[1], d[0]])
        c1, c2 = s + nrm * rng.uniform(2, 5) + d * rng.uniform(-1, 1), s - nrm * rng.uniform(2, 5)
        V = _world(view, np.array([a, b, c1, c2]), z=3.0)
        F = np.array([[0, 1, 2], [1, 0, 3]]) if trial % 2 else np.array([[0, 1, 2], [0, 1, 3]])
        counts, _ = _coverage_counts(V, F, view)
        bad += counts[8, 7] != 1
    assert bad == 0


def test_tile_partition_does_not_change_results(bunny, monkeypatch):
    """The tiles are what threads share out: any tiling gives the same arrays (each sample is the
    minimum of (depth, face id) over the faces covering it)."""
    V, F, _ = bunny
    view, _, _ = _orbit(V, 60, 25, 2.4, width=300, height=200)
    out = []
    for tile in (16, 64, 256):
        monkeypatch.setattr(zb, "TILE", tile)
        p = zb.project(V, F, view)
        g = zb.rasterize_grid(p, 2)
        e = zb.rasterize_pixels(p, np.arange(0, 300 * 200, 7), 4)
        out.append((g, e))
    for g, e in out[1:]:
        for a, b in ((out[0][0], g), (out[0][1], e)):
            for name in ("face", "depth", "bary"):
                np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
