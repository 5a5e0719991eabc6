"""The compiled steps of the tracker and the brush paths (the kernels of strokekit.tracking and
strokekit.paths) give what the numpy and k-d tree steps they stand in for give (tests/oracles.py,
the line pass's numpy operations, scipy's cKDTree), to the bit, on inputs made to tie: points on
a lattice (equal distances everywhere), repeated points, pairs exactly at the cover radius."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import oracles
import pytest

from strokekit.camera.view import Camera
from strokekit.lines.strokeops import query_tree
from strokekit.model import N_KINDS, Strokes
from strokekit.paths import cover_kernels, pieces_kernels
from strokekit.paths import votes_kernels as path_votes_kernels
from strokekit.paths.cover import covering_samples, on_drawing
from strokekit.paths.pieces import LinkPairs, link_pieces, one_label_per_path
from strokekit.paths.votes import CONTOUR, kind_class
from strokekit.sampling import Samples, match_samples, resample_strokes
from strokekit.tracking import grid_kernels, joins_kernels, sort_kernels, strokeops_kernels, ufit_kernels, votes_kernels
from strokekit.tracking.grid import SampleGrid, match_pieces
from strokekit.tracking.joins import gather_paths, touching_paths
from strokekit.tracking.strokeops import cut_pieces, drop_hairpins, insert_points, resample, select, with_arcs
from strokekit.tracking.ufit import fit_u
from strokekit.tracking.votes import assign_ids, sample_labels, segment_by_votes, u_trend

#: Every kernel by name.
K = SimpleNamespace(**{n: getattr(m, n) for m in (sort_kernels, grid_kernels, strokeops_kernels, votes_kernels,
                                                  ufit_kernels, joins_kernels, path_votes_kernels, cover_kernels,
                                                  pieces_kernels)
                       for n in dir(m) if hasattr(getattr(m, n), "py_func")})

def _points(rng, n, lattice):
    """n points in a 40 px square: on a half-pixel lattice (ties everywhere, repeats) or not."""
    if lattice:
        return rng.integers(0, 80, (n, 2)) * 0.5
    return rng.random((n, 2)) * 40.0


def _samples(rng, n, lattice):
    p = _points(rng, n, lattice)
    a = rng.random(n) * np.pi
    t = np.c_[np.cos(a), np.sin(a)]
    if lattice:  # (tangents along the axes and diagonals: dot products tie too)
        t = np.round(t * 2) / 2
        t /= np.maximum(np.linalg.norm(t, axis=1), 1e-12)[:, None]
    stroke = np.sort(rng.integers(0, max(1, n // 8), n))
    w = np.where(rng.random(n) < 0.5, 1.0, 0.5 + rng.random(n))
    return Samples(p=p, X=np.c_[p, np.ones(n)], u=rng.random(n) * 5, t=t, ids=np.zeros(n, np.int64), stroke=stroke,
                   s=np.arange(n) * 1.0, w=w)


def _strokes(pts, counts, surface=None, face=None, ids=None, u=None) -> Strokes:
    """Strokes of kind 0 and level 0 from the points pts (N, 2), counts[i] of them in stroke i;
    surface (N, 3), face (N,), u (N,) zeros and ids 0..S-1 unless given. (Callers draw the
    given ones from their rng in the order they always did.)"""
    N, S = len(pts), len(counts)
    return Strokes(points=pts, surface=np.zeros((N, 3)) if surface is None else surface,
                   face=np.zeros(N, np.int64) if face is None else face,
                   offsets=np.r_[0, np.cumsum(counts)].astype(np.int64), kind=np.zeros(S, np.int64),
                   ids=np.arange(S) if ids is None else ids, u=np.zeros(N) if u is None else u, level=np.zeros(S),
                   level_weight=np.ones(S), camera=None, frame=0, period_px=10.0)


def test_arcs_are_the_strokes_own():
    """with_arcs (the kernel arcs): Strokes' segment_lengths, arc_length, lengths and global_arc,
    to the bit; strokes with an empty one are left to the properties."""
    rng = np.random.default_rng(3)
    for _ in range(20):
        counts = rng.integers(1, 9, int(rng.integers(1, 12)))
        pts = rng.random((int(counts.sum()), 2)) * rng.choice([1.0, 1e3])
        mine, ref = with_arcs(_strokes(pts, counts)), _strokes(pts, counts)
        assert "global_arc" in mine.__dict__
        for k in ("segment_lengths", "arc_length", "lengths"):
            np.testing.assert_array_equal(getattr(mine, k), getattr(ref, k))
        for a, b in zip(mine.global_arc, ref.global_arc):
            np.testing.assert_array_equal(a, b)
    empty = with_arcs(_strokes(np.zeros((2, 2)), np.array([2, 0])))
    assert "segment_lengths" not in empty.__dict__


@pytest.mark.parametrize("lattice", [True, False])
def test_grid_cells_hold_their_points_in_index_order(lattice):
    """grid_index: every cell's points in index order (a stable sort by cell), and their
    coordinates in that order."""
    rng = np.random.default_rng(7)
    for cell in (0.5, 2.0, 3.0):
        p = _points(rng, 500, lattice).astype(float)
        x0, y0, c, nx, ny, start, order, ps = K.grid_index(p, cell)
        cx = np.minimum(((p[:, 0] - x0) / c).astype(np.int64), nx - 1)
        cy = np.minimum(((p[:, 1] - y0) / c).astype(np.int64), ny - 1)
        key = cy * nx + cx
        np.testing.assert_array_equal(order, np.argsort(key, kind="stable"))
        np.testing.assert_array_equal(start, np.concatenate(([0], np.bincount(key, minlength=nx * ny).cumsum())))
        np.testing.assert_array_equal(ps, p[order])


@pytest.mark.parametrize("lattice", [False, True])
def test_grid_queries_are_the_trees(lattice):
    rng = np.random.default_rng(1 + lattice)
    for _ in range(20):
        p = _points(rng, int(rng.integers(1, 300)), lattice)
        q = np.r_[_points(rng, 200, lattice), p[:20], [[-50.0, 3.0], [400.0, 400.0]]]
        tree, grid = query_tree(p), SampleGrid(p, float(rng.choice([1.0, 3.0, 6.0])))
        for k in (1, 2, 16):
            for bound in (1.5, 3.0 + 1e-9, 6.0):
                d0, i0 = tree.query(q, k=k, distance_upper_bound=bound)
                d1, i1 = grid.query(q, k=k, distance_upper_bound=bound)
                assert np.array_equal(d0, d1) and np.array_equal(i0, i1)
                # as a set: the same neighbours, in an order of equal distances of its own
                d2, i2 = grid.query(q, k=k, distance_upper_bound=bound, as_set=True)
                assert np.array_equal(d0, d2)
                assert np.array_equal(np.sort(i0.reshape(len(q), -1), axis=1), np.sort(i2.reshape(len(q), -1), axis=1))


@pytest.mark.parametrize("lattice", [False, True])
def test_grid_cover_bridges_and_lookback_are_the_trees(lattice):
    rng = np.random.default_rng(3 + lattice)
    for _ in range(20):
        n = int(rng.integers(2, 400))
        D = _samples(rng, n, lattice)
        kind = rng.integers(0, 3, D.stroke.max() + 1)  # silhouette, smooth contour, crease
        run = np.cumsum(rng.random(n) < 0.2)
        rank = rng.permutation(run.max() + 1)
        tree, grid = query_tree(D.p), SampleGrid(D.p, 3.0)
        for radius in (2.0, 1.0):  # (lattice points: many pairs exactly at the radius)
            ref = covering_samples(D, kind, run, rank, radius, tree)
            assert np.array_equal(ref, covering_samples(D, kind, run, rank, radius, grid))
            # (cells narrower than the radius: searched sample by sample)
            assert np.array_equal(ref, covering_samples(D, kind, run, rank, radius, SampleGrid(D.p, 1.5)))
        pa, pb = _points(rng, 30, lattice), _points(rng, 30, lattice)
        assert np.array_equal(on_drawing(tree, pa, pb, D=D), on_drawing(grid, pa, pb, D=D))
        pa, pb = D.p[rng.integers(0, n, 30)], D.p[rng.integers(0, n, 30)]  # (bridges between samples)
        assert np.array_equal(on_drawing(tree, pa, pb, D=D), on_drawing(grid, pa, pb, D=D))
        # the lookback: line samples (their surface points seen by an identity-like camera) to
        # the previous paths' samples
        src = _samples(rng, 200, lattice)
        cam = _Flat()
        m0, q0 = match_samples(src, cam, D, tree, radius_px=6.0, min_tangent_dot=0.65, k=2, return_projected=True,
                               piece_distance=True)
        m1, q1 = match_pieces(src, cam, D, 6.0, 0.65, k=2)
        assert np.array_equal(m0, m1) and np.array_equal(q0, q1)


def test_lookback_in_crowded_windows_is_the_trees():
    """The lookback where a window holds many samples (a dense crowd): the tree's matches."""
    rng = np.random.default_rng(37)
    for lattice in (False, True):
        D = _samples(rng, 3000, lattice)
        src = _samples(rng, 300, lattice)
        cam = _Flat()
        m0, q0 = match_samples(src, cam, D, query_tree(D.p), radius_px=6.0, min_tangent_dot=0.65, k=2,
                               return_projected=True, piece_distance=True)
        m1, q1 = match_pieces(src, cam, D, 6.0, 0.65, k=2)
        assert np.array_equal(m0, m1) and np.array_equal(q0, q1)


class _Flat:
    """A camera that draws a surface point (x, y, z) at pixel (x, y)."""

    is_ortho = True

    def project(self, X):
        return X[:, :2].copy(), X[:, 2].copy()


def test_segment_runs_are_segment_by_votes():
    rng = np.random.default_rng(5)
    for _ in range(50):
        n = int(rng.integers(1, 300))
        counts = rng.integers(1, 40, n // 10 + 1)
        stroke = np.repeat(np.arange(len(counts)), counts)[:n]
        n = len(stroke)
        w = np.where(rng.random(n) < 0.7, 1.0, rng.random(n))
        s = np.zeros(n)
        for k in range(stroke.max() + 1):
            on = stroke == k
            s[on] = np.cumsum(w[on]) - 0.5 * w[on]
        lengths = np.bincount(stroke, weights=w)
        dense = Samples(p=np.zeros((n, 2)), X=np.zeros((n, 3)), u=np.zeros(n), t=np.zeros((n, 2)),
                        ids=np.zeros(n, np.int64), stroke=stroke, s=s, w=w)
        V = int(rng.integers(0, 2 * n))
        vm, vid, vw = rng.integers(0, n, V), rng.integers(0, 6, V), rng.random(V).round(1)
        vw = np.where(rng.random(V) < 0.5, vw, rng.random(V))  # (sums that round to ties, and not)
        assert np.array_equal(oracles.sample_labels(n, vm, vid, vw), sample_labels(n, vm, vid, vw))
        for min_px in (1.5, 6.0):
            a = oracles.segment_by_votes(dense, lengths, vm, vid, vw, min_px)
            b = segment_by_votes(dense, lengths, vm, vid, vw, min_px)
            assert all(np.array_equal(x, y) for x, y in zip(a, b))


def test_sorts_trends_links_and_hairpins_are_the_numpy_ones():
    rng = np.random.default_rng(7)
    for trial in range(200):
        n = int(rng.integers(1, 300))
        a, b = rng.integers(0, rng.integers(1, 6), n), rng.integers(0, rng.integers(1, 5), n)
        s = np.round(rng.random(n) * 10, int(rng.integers(0, 3)))
        s = (np.sort(s), -np.sort(-s), s)[trial % 3]  # in order, reversed, mixed; ties
        u, label = rng.random(n).round(1), rng.integers(0, 4, a.max() + 1)
        assert np.array_equal(oracles.u_trend(a, b, label, s, u, a.max() + 2), u_trend(a, b, label, s, u, a.max() + 2))
    for trial in range(100):
        S = int(rng.integers(1, 12))
        counts = rng.integers(1, 8, S)
        N = int(counts.sum())
        # ends on a coarse lattice: many meet, three or more at a point
        pts = np.cumsum(rng.normal(0, 0.6, (N, 2)), axis=0)
        if trial % 2:
            pts = np.round(pts)
        st = _strokes(pts, counts)
        label = rng.integers(-1, 3, S)
        for lab in (None, label):
            ref = oracles.touching_paths(st, 2.0, 120.0, label=lab, other_tol_px=1.5)
            got = oracles.touching_paths(st, 2.0, 120.0, label=lab, other_tol_px=1.5, link=K.link_paths)
            assert all(np.array_equal(x, y) for x, y in zip(ref, got))
        got = touching_paths(st, 2.0, 120.0)  # (chain_touching's: no labels)
        assert all(np.array_equal(x, y) for x, y in zip(oracles.touching_paths(st, 2.0, 120.0), got))
        # the brush paths' linking, its candidates compiled (bridges refused by a rule of their own)
        kinded = st.replace(kind=rng.integers(0, 2, S).astype(np.int8)) if trial % 3 == 0 else st
        for tol, other, free in ((2.0, 1.5, 0.5), (1.5, 2.5, 1.0)):
            def bridge_ok(pa, pb):
                return np.floor(pa[:, 0] * 3 + pb[:, 1] * 7) % 3 != 0
            ref = oracles.touching_paths(kinded, tol, 120.0, label=label, other_tol_px=other, bridge_ok=bridge_ok,
                                         free_px=free, link=K.link_paths)
            got = link_pieces(kinded, tol, 120.0, label, other, bridge_ok, free_px=free)
            assert all(np.array_equal(x, y) for x, y in zip(ref, got))
            # linked twice from one LinkPairs (as a frame with orphans is): the second labels' links
            # are theirs, whatever bridge verdicts the first left
            pairs = LinkPairs.of(kinded, max(tol, other), 120.0)
            for lab in (label, np.where(rng.random(S) < 0.5, -1, label)):
                ref = oracles.touching_paths(kinded, tol, 120.0, label=lab, other_tol_px=other, bridge_ok=bridge_ok,
                                             free_px=free, link=K.link_paths)
                got = link_pieces(kinded, tol, 120.0, lab, other, bridge_ok, free_px=free, pairs=pairs)
                assert all(np.array_equal(x, y) for x, y in zip(ref, got))
        at = rng.integers(0, N, int(rng.integers(0, N + 1)))
        full = st.replace(surface=rng.random((N, 3)), face=rng.integers(0, 99, N), u=rng.random(N))
        for strokes, where in ((full, at), (full, None), (full.replace(u=None), at)):
            ref, kept = oracles.drop_hairpins(strokes, 90.0, 1.0, at=where, return_kept=True)
            got, kept2 = drop_hairpins(strokes, 90.0, 1.0, at=where, return_kept=True)
            assert np.array_equal(kept, kept2) and (got is strokes) == (ref is strokes)
            for f in ("points", "surface", "face", "u", "offsets"):
                x, y = getattr(ref, f), getattr(got, f)
                assert (x is None and y is None) or np.array_equal(x, y), f


def test_resampling_is_resample_strokes():
    rng = np.random.default_rng(9)
    for _ in range(100):
        S = int(rng.integers(1, 10))
        counts = rng.integers(1, 9, S)  # (one-point strokes too)
        N = int(counts.sum())
        pts = np.cumsum(rng.normal(0, 3.0, (N, 2)), axis=0)
        pts[rng.random(N) < 0.2] = 0.0  # (repeated points: zero-length segments)
        st = _strokes(pts, counts, surface=rng.random((N, 3)), ids=np.arange(S) + 7, u=rng.random(N))
        # (surface points seen by a perspective camera: some behind it, some on its plane)
        cam = Camera(eye=(0.0, 0.0, 10.0), target=(0.0, 0.0, 0.0), fov_y=40, width=400, height=300)
        X = rng.normal(0, 6.0, (N, 3))
        X[rng.random(N) < 0.1, 2] = 10.0
        seen = st.replace(surface=X, camera=cam)
        for step in (1.0, 4.0, 0.3):
            for strokes in (st, seen):
                a, b = resample_strokes(strokes, step), resample(strokes, step)
                for f in ("p", "X", "u", "t", "ids", "stroke", "s", "w"):
                    assert np.array_equal(getattr(a, f), getattr(b, f)), f


def test_id_assignment_is_assign_ids():
    rng = np.random.default_rng(11)
    for _ in range(300):
        n = int(rng.integers(0, 40))
        S = int(rng.integers(1, 12))
        cs, ci = rng.integers(0, S, n), rng.integers(0, 15, n)
        cw = np.where(rng.random(n) < 0.3, 0.0, rng.integers(1, 5, n) * 0.5)  # (ties, and weightless pairs)
        for min_w in (0.0, 1.0):
            a = oracles.assign_ids(S, cs, ci, cw, 20, min_w)
            b = assign_ids(S, cs, ci, cw, 20, min_w)
            assert np.array_equal(a[0], b[0]) and a[1] == b[1]


def _id_claims_numpy(path_of, p_label, plen, label_weight, vk, vid, vw, ok, ok_k, oid, ow, known, S):
    """paths.votes.path_ids' claims as numpy steps (the code id_claims replaced)."""
    lk = np.flatnonzero(p_label >= 0)
    cs = np.concatenate([path_of[lk], path_of[vk], path_of[ok_k]]).astype(np.int64)
    ci = np.concatenate([p_label[lk], vid, oid[ok]]).astype(np.int64)
    cw = np.concatenate([label_weight * plen[lk], vw, ow[ok]])
    if len(cs) == 0:  # (no claims: _path_ids gives fresh ids before the sums)
        return cs, ci, cw
    K = len(known)
    w = np.bincount(cs * K + np.searchsorted(known, ci), weights=cw, minlength=S * K)
    nz = np.flatnonzero(w)
    return nz // K, known[nz % K], w[nz]


def test_id_claims_are_the_numpy_sums():
    rng = np.random.default_rng(43)
    for trial in range(300):
        S = int(rng.integers(1, 15))
        known = np.unique(rng.integers(0, 60, int(rng.integers(1, 20))))
        P = int(rng.integers(0, 30))
        path_of = rng.integers(0, S, P)
        p_label = np.where(rng.random(P) < 0.3, -1, known[rng.integers(0, len(known), P)])
        # (weights that tie, cancel to zero and do not: sums whose order shows)
        plen = np.where(rng.random(P) < 0.5, rng.integers(0, 4, P) * 0.5, rng.random(P) * 7.0)
        V = int(rng.integers(0, 80)) if P else 0
        vk, vid = rng.integers(0, max(P, 1), V), known[rng.integers(0, len(known), V)]
        vw = np.where(rng.random(V) < 0.5, rng.integers(-2, 3, V) * 0.25, rng.random(V) * 0.1)
        O = int(rng.integers(0, 40))
        ok = rng.random(O) < 0.6 if P else np.zeros(O, bool)
        ok_k = rng.integers(0, max(P, 1), int(ok.sum()))
        oid, ow = known[rng.integers(0, len(known), O)], np.where(rng.random(O) < 0.5, 0.1, rng.random(O))
        if trial % 5 == 0:  # (ids beyond `known`: the sums' cells as the dense ones alias them)
            vid = rng.integers(0, 70, V)
        a = _id_claims_numpy(path_of, p_label, plen, 0.25, vk, vid, vw, ok, ok_k, oid, ow, known, S)
        b = K.id_claims(path_of, p_label, plen, 0.25, vk, vid, vw, ok, ok_k, oid, ow, known)
        for x, y in zip(a, b):
            assert x.dtype == y.dtype and x.tobytes() == y.tobytes()


def _carried_numpy(rm, rq, sub, kind_d, Dstroke, kind_v, Vp, Vt, Vw, Vu, Vs, Vstroke, Vids, Dw, Dt, step):
    """carried's votes and other matches as numpy steps: the kind classes per stroke then per
    sample (kind_class), the other matches as carried_votes took them (the code carried's own
    classes and other matches replaced), the votes one by one in the kernel's arithmetic."""
    cls_v = kind_class(kind_v).astype(np.int64).take(Vstroke)
    cls_d = kind_class(kind_d).astype(np.int64).take(Dstroke)
    votes = []
    for i in np.flatnonzero(rm >= 0):
        j, h = rm[i], sub[i]
        if cls_d[h] != cls_v[j]:
            continue
        off = (rq[i, 0] - Vp[j, 0]) * Vt[j, 0] + (rq[i, 1] - Vp[j, 1]) * Vt[j, 1]
        off = min(max(off, -0.5 * Vw[j]), 0.5 * Vw[j])
        nx = j + 1 if j + 1 < len(Vp) and Vstroke[j + 1] == Vstroke[j] else j
        pv = j - 1 if j >= 1 and Vstroke[j - 1] == Vstroke[j] else j
        ds = Vs[nx] - Vs[pv]
        slope = (Vu[nx] - Vu[pv]) / ds if ds > 0 else 0.0
        votes.append((h, Vids[j], Vu[j] + off * slope, step * Dw[h], np.sign(Vt[j, 0] * Dt[h, 0] + Vt[j, 1] * Dt[h, 1])))
    cols = list(zip(*votes)) if votes else [[]] * 5
    x = np.flatnonzero(rm >= 0)
    x = x[cls_d[sub[x]] != cls_v[rm[x]]]
    hx = sub[x]
    return (np.array(cols[0], np.int64), np.array(cols[1], np.int64), np.array(cols[2], float), np.array(cols[3], float),
            np.array(cols[4], float), hx, Vids[rm[x]], step * Dw[hx])


def test_carried_votes_are_the_numpy_ones():
    rng = np.random.default_rng(47)
    for trial in range(100):
        V = _samples(rng, int(rng.integers(1, 80)), trial % 2 == 1)
        D = _samples(rng, int(rng.integers(1, 80)), trial % 2 == 0)
        # (kind codes of every kind and occlusion level: classes that agree and that do not)
        kind_v = rng.integers(0, 3 * N_KINDS, V.stroke.max() + 1)
        kind_d = rng.integers(0, 3 * N_KINDS, D.stroke.max() + 1)
        step = int(rng.integers(1, 3))
        sub = np.arange(0, len(D), step)
        rm = np.where(rng.random(len(sub)) < 0.2, -1, rng.integers(0, len(V), len(sub)))
        rq = D.p[sub] + rng.normal(0, 1.0, (len(sub), 2))
        Vs = np.where(rng.random(len(V)) < 0.2, 0.0, V.s)  # (repeated arc lengths: no slope)
        args = (rm, rq, sub, kind_d, D.stroke, kind_v)
        rest = (V.p, V.t, V.w, V.u, Vs, V.stroke, V.ids, D.w, D.t, step)
        a = _carried_numpy(*args, *rest)
        b = K.carried(*args, CONTOUR, N_KINDS, *rest)
        for x, y in zip(a, b):
            assert x.dtype == y.dtype and x.tobytes() == y.tobytes()


def test_inner_knots_are_piecewise_us():
    rng = np.random.default_rng(53)
    for _ in range(100):
        S = int(rng.integers(0, 12))
        # (lengths of whole knot spacings, shorter than one, zero: every count of inner knots)
        L = np.where(rng.random(S) < 0.3, rng.integers(0, 5, S) * 16.0, rng.random(S) * 90.0)
        pw = oracles.PiecewiseU(L, 16.0)
        if S == 0:  # (PiecewiseU.inner_knot_s needs a stroke; the kernel gives none)
            assert all(len(x) == 0 for x in K.inner_knots(pw.n, pw.h))
            continue
        a = (pw.inner_knot_stroke(), pw.inner_knot_s())
        for x, y in zip(a, K.inner_knots(pw.n, pw.h)):
            assert x.dtype == y.dtype and x.tobytes() == y.tobytes()


def test_band_terms_are_piecewise_fits():
    rng = np.random.default_rng(13)
    for _ in range(50):
        S = int(rng.integers(1, 8))
        L = rng.random(S) * 80 + rng.integers(0, 2, S) * 0.5
        pw = oracles.PiecewiseU(L, 16.0)
        V = int(rng.integers(1, 200))
        st = rng.integers(0, S, V)
        s = rng.random(V) * L[st]
        u, w = rng.random(V) * 4, np.where(rng.random(V) < 0.2, 0.0, rng.random(V))
        args = (st, s, u, w, rng.random(S), rng.random(S) * 0.1, 0.1, 3e-4 * 100, 1e-3)
        assert np.array_equal(pw.fit(*args), pw.fit(*args, band_terms=K.band_terms))


def _pieces_numpy(cover, run, s, w, r_s0, r_s1, vm):
    """brush_step's pieces and vote landing as numpy steps (the code the kernels replaced)."""
    keep = cover < 0
    N = len(run)
    start = np.r_[True, (keep[1:] != keep[:-1]) | (run[1:] != run[:-1])]
    first = np.flatnonzero(start)
    last = np.r_[first[1:] - 1, N - 1]
    fr = run[first]
    head = np.r_[True, fr[1:] != fr[:-1]]
    tail = np.r_[fr[1:] != fr[:-1], True]
    s0 = np.where(head, r_s0[fr], s[first] - 0.5 * w[first])
    s1 = np.where(tail, r_s1[fr], s[last] + 0.5 * w[last])
    sel = keep[first] & ((s1 - s0 >= 1.0) | (head & tail)) & (s1 > s0)
    p_run, p_s0, p_s1 = fr[sel], s0[sel], s1[sel]
    smp_piece = np.searchsorted(first[sel], np.arange(N), side="right") - 1
    smp_piece[(smp_piece < 0) | (np.arange(N) > last[sel][np.maximum(smp_piece, 0)])] = -1
    hit = np.where(cover[vm] >= 0, cover[vm], vm)
    vk = smp_piece[hit]
    ok = vk >= 0
    vk = vk[ok]
    s_in = np.clip(s[hit[ok]] - p_s0[vk], 0.0, (p_s1 - p_s0)[vk])
    return p_run, p_s0, p_s1, smp_piece, ok, vk, s_in


def test_pieces_and_vote_landing_are_the_numpy_steps():
    rng = np.random.default_rng(17)
    for _ in range(200):
        N = int(rng.integers(1, 200))
        run = np.cumsum(rng.random(N) < 0.1)
        run -= run[0]
        w = np.where(rng.random(N) < 0.7, 1.0, rng.random(N))
        s = np.cumsum(w) - 0.5 * w
        R = run.max() + 1
        r_s0 = np.array([s[run == r][0] - 0.5 * w[run == r][0] for r in range(R)])
        r_s1 = np.array([s[run == r][-1] + 0.5 * w[run == r][-1] for r in range(R)])
        cover = np.where(rng.random(N) < 0.3, rng.integers(0, N, N), -1)
        cover = np.where((cover >= 0) & (np.roll(cover, 1) >= 0) & (rng.random(N) < 0.5), -1, cover)
        vm = rng.integers(0, N, int(rng.integers(0, 2 * N)))
        p_run, p_s0, p_s1, smp = K.pieces_of_runs(cover, run, s, w, r_s0, r_s1, 1.0)
        ok, vk, s_in = K.votes_landing(vm, cover, smp, s, p_s0, p_s1)
        ref = _pieces_numpy(cover, run, s, w, r_s0, r_s1, vm)
        for x, y in zip(ref, (p_run, p_s0, p_s1, smp, ok, vk, s_in)):
            assert np.array_equal(x, y)


def _end_votes_numpy(vk, s_in, u, vid, label, plen, P, reach):
    """EndVotes.of in numpy: the own votes in a stable sort by (piece, s_in), their first and last
    per piece."""
    K = len(plen)
    ue, d, slope = np.full((K, 2), np.nan), np.full((K, 2), np.inf), np.ones(K)
    lab = label[vk]
    sel = np.flatnonzero((lab >= 0) & (vid == lab))
    o = sel[np.lexsort((s_in[sel], vk[sel]))]
    for k in np.unique(vk[o]):
        mine = o[vk[o] == k]
        lo, hi = mine[0], mine[-1]
        ue[k] = u[lo], u[hi]
        d[k] = [x if x <= reach else np.inf for x in (s_in[lo], plen[k] - s_in[hi])]
        span = s_in[hi] - s_in[lo]
        if span >= 4.0:
            b = np.abs(u[hi] - u[lo]) * P / span
            slope[k] = b if 0.25 <= b <= 4.0 else 1.0
    return ue, d, slope


def test_end_votes_and_continuing_links_are_the_numpy_ones():
    """end_votes: per piece the own votes nearest its ends, as a stable lexsort by (piece, arc
    length) orders them (ties on a half-pixel lattice: the first, the last), and the slope between
    them; continuing_links: the links of one label whose ends' u differ by what the gap explains."""
    rng = np.random.default_rng(23)
    for _ in range(300):
        npc, V = int(rng.integers(1, 12)), int(rng.integers(0, 60))
        plen = rng.integers(1, 24, npc) * 0.5
        vk = rng.integers(0, npc, V)
        s_in = np.minimum(rng.integers(0, 48, V) * 0.5, plen[vk])
        u = np.where(rng.random(V) < 0.5, s_in / 10.0, rng.random(V) * 3.0)
        label = rng.integers(-1, 3, npc)
        vid = rng.integers(0, 3, V)
        got = K.end_votes(vk, s_in, u, vid, label, plen, 10.0, 4.0)
        ref = _end_votes_numpy(vk, s_in, u, vid, label, plen, 10.0, 4.0)
        for x, y in zip(ref, got):
            assert np.array_equal(x, y, equal_nan=True)
        L = int(rng.integers(0, 20))
        ra, rb = rng.integers(0, npc, L), rng.integers(0, npc, L)
        ea, eb = rng.random(L) < 0.5, rng.random(L) < 0.5
        gap, tier = rng.integers(0, 12, L) * 0.5, rng.integers(0, 3, L)
        ue, d, slope = ref
        ia, ib = ea.astype(np.int64), eb.astype(np.int64)
        reach = gap + d[ra, ia] + d[rb, ib]
        with np.errstate(invalid="ignore"):
            want = (tier == 2) & (reach < np.inf) & (
                np.abs(ue[ra, ia] - ue[rb, ib]) * 10.0 <= 0.5 * (slope[ra] + slope[rb]) * (reach + 3.0))
        assert np.array_equal(K.continuing_links(ra, ea, rb, eb, gap, tier, ue, d, slope, 10.0, 3.0), want)


def test_u_fit_is_the_numpy_one():
    """fit_u (vote groups, shift, piecewise system and evaluation compiled) gives what its numpy
    steps give, to the bit: strokes, u, slopes and the vote groups the ids are assigned from;
    linear (no knots) too, votes of many ids on one stroke too."""
    from strokekit.paths.options import path_tracking

    rng = np.random.default_rng(19)
    for trial in range(100):
        S = int(rng.integers(1, 6))
        counts = rng.integers(2, 8, S)
        N = int(counts.sum())
        pts = np.cumsum(rng.normal(0, 8.0 if trial % 3 else 40.0, (N, 2)), axis=0)
        cur = _strokes(pts, counts, surface=rng.random((N, 3)))
        V = int(rng.integers(1, 300))
        st = rng.integers(0, S, V)
        s = rng.random(V) * cur.lengths[st]
        n_ids = 80 if trial % 4 == 0 else S + 2
        u, vid, w = s / 10.0 + rng.normal(0, 0.3, V) + rng.integers(0, 3, V), rng.integers(0, n_ids, V), rng.random(V)
        for o in (path_tracking(), path_tracking().__class__(knot_spacing_px=0.0)):
            ref = oracles.fit_u(cur, cur, st, s, u, vid, w, o)
            got = fit_u(cur, cur, st, s, u, vid, w, o)
            assert np.array_equal(ref[0].points, got[0].points) and np.array_equal(ref[0].offsets, got[0].offsets)
            for x, y in zip((ref[1], ref[2], *ref[3]), (got[1], got[2], *got[3])):
                assert np.array_equal(x, y)
        none = fit_u(cur, cur, st[:0], s[:0], u[:0], vid[:0], w[:0], path_tracking())
        ref = oracles.fit_u(cur, cur, st[:0], s[:0], u[:0], vid[:0], w[:0], path_tracking())
        assert np.array_equal(ref[1], none[1]) and np.array_equal(ref[2], none[2])


def test_cover_pair_by_pair_is_sample_by_sample():
    """The cover found pair by pair over neighbouring cells is what a search of every sample's
    window finds (dense samples, many runs, ranks and distances that tie); cells no wider than
    the radius are refused (the caller makes wider ones)."""
    rng = np.random.default_rng(31)
    sure = 0
    for trial in range(60):
        n = int(rng.integers(2, 600))
        D = _samples(rng, n, trial % 2 == 1)
        sk = rng.integers(0, 2, n)
        contour = rng.random(n) < 0.9
        run = np.cumsum(rng.random(n) < 0.1)
        rank = rng.permutation(run.max() + 1)
        grid = SampleGrid(D.p, float(rng.choice([2.5, 3.0, 6.0])))
        for radius in (2.0, 1.0):
            args = (D.p, D.t, D.w, sk, contour, run, rank, *grid.index, radius, 0.9)
            a = np.full(n, -1, np.int64)
            ok = K.cover(*args, a)
            assert not ok or np.array_equal(a, _cover_each(*args))  # (not ok: the caller asks the tree)
            sure += ok
            assert not K.cover(D.p, D.t, D.w, sk, contour, run, rank, *SampleGrid(D.p, radius).index, radius, 0.9, a)
    assert sure > 30


def _cover_each(p, t, w, sk, contour, run, rank_of_run, x0, y0, cell, nx, ny, start, order, ps, radius, min_dot):
    """cover's answer sample by sample (every pair within the radius looked at from each side), in
    plain Python: the rule of paths.stage.covering_samples."""
    out = np.full(len(p), -1, np.int64)
    r2 = radius * radius
    for x in range(len(p)):
        if not contour[x]:
            continue
        best = None
        for y in range(len(p)):
            if not contour[y] or run[y] == run[x] or sk[y] != sk[x]:
                continue
            ddx, ddy = p[y, 0] - p[x, 0], p[y, 1] - p[x, 1]
            d2 = ddx * ddx + ddy * ddy
            if d2 > r2 or not rank_of_run[run[y]] < rank_of_run[run[x]]:
                continue
            if not abs(ddx * t[x, 0] + ddy * t[x, 1]) <= 0.5 * (w[x] + w[y]) - 0.25:
                continue
            if not abs(t[y, 0] * t[x, 0] + t[y, 1] * t[x, 1]) >= min_dot:
                continue
            key = (rank_of_run[run[y]], d2, y)
            if best is None or key < best:
                best = key
        if best is not None:
            out[x] = best[2]
    return out


def _cover_runs_numpy(cover, smp_piece, path_of, stroke, s, w):
    """paths.stage._finish's covered runs as numpy steps (the code cover_runs replaced)."""
    cs = np.flatnonzero(cover >= 0)
    ck = smp_piece[cover[cs]]
    cs, ck = cs[ck >= 0], ck[ck >= 0]
    c_path = path_of[ck]
    brk = np.r_[True, (np.diff(cs) != 1) | (stroke[cs][1:] != stroke[cs][:-1]) | (c_path[1:] != c_path[:-1])] \
        if len(cs) else np.zeros(0, bool)
    f = np.flatnonzero(brk)
    g = np.r_[f[1:] - 1, len(cs) - 1] if len(f) else f
    cl = stroke[cs[f]] if len(f) else np.zeros(0, np.int64)
    c0 = s[cs[f]] - 0.5 * w[cs[f]] if len(f) else np.zeros(0)
    c1 = s[cs[g]] + 0.5 * w[cs[g]] if len(f) else np.zeros(0)
    cp = c_path[f] if len(f) else np.zeros(0, np.int64)
    return cl, c0, c1, cp


def test_covered_runs_and_selections_are_the_numpy_ones():
    from strokekit.paths.stage import concat_two

    rng = np.random.default_rng(41)
    for _ in range(100):
        N = int(rng.integers(1, 300))
        stroke = np.sort(rng.integers(0, 6, N))
        w = np.where(rng.random(N) < 0.7, 1.0, rng.random(N))
        s = np.cumsum(w) - 0.5 * w
        cover = np.where(rng.random(N) < 0.5, rng.integers(0, N, N), -1)
        n_pieces = int(rng.integers(1, 10))
        smp_piece = np.where(rng.random(N) < 0.8, rng.integers(0, n_pieces, N), -1)
        path_of = rng.integers(0, 4, n_pieces)
        ref = _cover_runs_numpy(cover, smp_piece, path_of, stroke, s, w)
        got = K.cover_runs(cover, smp_piece, path_of, stroke, s, w)
        for x, y in zip(ref, got):
            assert np.array_equal(x, y) and x.dtype == y.dtype
        S = int(rng.integers(1, 8))
        counts = rng.integers(1, 6, S)
        M = int(counts.sum())
        st = _strokes(rng.random((M, 2)), counts, surface=rng.random((M, 3)), face=rng.integers(0, 9, M),
                      u=rng.random(M))
        mask = rng.random(S) < 0.5
        a, b = st.select(mask), select(st, mask)
        for f in ("points", "surface", "face", "u", "offsets", "kind", "ids", "level", "level_weight"):
            assert np.array_equal(getattr(a, f), getattr(b, f)), f
        a, b = Strokes.concat([st.select(mask), st.select(~mask)]), concat_two(st.select(mask), st.select(~mask))
        for f in ("points", "surface", "face", "u", "offsets", "kind", "ids", "level", "level_weight"):
            x, y = getattr(a, f), getattr(b, f)
            assert np.array_equal(x, y) and x.dtype == y.dtype, f


def _one_label_numpy(group: np.ndarray, pos: np.ndarray, label: np.ndarray) -> np.ndarray:
    """paths.pieces.one_label_per_path as numpy steps (the code one_label replaced)."""
    K = len(group)
    order = np.lexsort((pos, group))
    g, lab = group[order], label[order]
    start = np.r_[True, g[1:] != g[:-1]]
    idx = np.arange(K)
    # Forward fill within the group, then backward fill the leading unlabelled pieces.
    known = lab >= 0
    seg = np.cumsum(start) - 1
    f = np.maximum.accumulate(np.where(known, idx, -1))
    fl = np.where((f >= 0) & (seg[np.maximum(f, 0)] == seg), lab[np.maximum(f, 0)], -1)
    b = np.minimum.accumulate(np.where(known, idx, K)[::-1])[::-1]
    bl = np.where((b < K) & (seg[np.minimum(b, K - 1)] == seg), lab[np.minimum(b, K - 1)], -1)
    fill = np.where(fl >= 0, fl, bl)
    cut = start | np.r_[False, (fill[1:] != fill[:-1]) & ~start[1:]]
    if not cut[~start].any():
        return group
    out = np.empty(K, np.int64)
    out[order] = np.cumsum(cut) - 1
    return out


def test_cover_table_is_the_numpy_one():
    """_finish's covers: the drawn pieces and covered runs joined and ordered as np.lexsort orders
    them (many ties in path, line and start: the joined order decides)."""
    rng = np.random.default_rng(59)
    for _ in range(200):
        S = int(rng.integers(0, 8))
        P, C = int(rng.integers(0, 30)), int(rng.integers(0, 30))
        top = S + 2 if rng.random() < 0.2 else max(S, 1)  # (paths beyond S: bincount's longer counts)
        path_of, cp = rng.integers(0, top, P), rng.integers(0, top, C)
        p_line, cl = rng.integers(0, 4, P), rng.integers(0, 4, C)
        p_s0, c0 = rng.integers(0, 4, P) * 0.5, rng.integers(0, 4, C) * 0.5
        p_s0[rng.random(P) < 0.2] = -0.0  # (-0.0 ties 0.0)
        p_s1, c1 = p_s0 + rng.random(P), c0 + rng.random(C)
        allp, alll = np.r_[path_of, cp], np.r_[p_line, cl]
        all0, all1 = np.r_[p_s0, c0], np.r_[p_s1, c1]
        drawn = np.r_[np.ones(P, bool), np.zeros(C, bool)]
        o = np.lexsort((all0, alll, ~drawn, allp))
        counts = np.bincount(allp, minlength=S)
        ref = (np.r_[0, counts.cumsum()].astype(np.int64), alll[o].astype(np.int64), all0[o], all1[o], drawn[o])
        got = K.cover_table(path_of, p_line, p_s0, p_s1, cl, c0, c1, cp, S)
        for x, y in zip(ref, got):
            assert x.dtype == y.dtype and x.tobytes() == y.tobytes()


def test_one_label_per_path_is_the_numpy_one():
    rng = np.random.default_rng(43)
    for _ in range(200):
        K = int(rng.integers(1, 60))
        group = rng.integers(0, int(rng.integers(1, 12)), K)
        pos = rng.permutation(K)
        label = np.where(rng.random(K) < 0.5, -1, rng.integers(0, 4, K))
        assert np.array_equal(_one_label_numpy(group, pos, label), one_label_per_path(group, pos, label))


def test_stable_sorts_are_numpys():
    """argsort (a natural merge sort) is numpy's stable argsort, in runs, against them, with ties;
    sorted_unique is np.unique; u_trend at a scale where its keys' runs could touch sorts all
    keys at once (the same trend as the numpy one)."""
    rng = np.random.default_rng(47)
    for _ in range(200):
        n = int(rng.integers(0, 300))
        x = np.round(rng.random(n) * 20, int(rng.integers(0, 3)))
        cut = np.sort(rng.integers(0, n + 1, int(rng.integers(0, 6))))
        for a, b in zip(cut[:-1], cut[1:]):  # (runs in order and against it)
            x[a:b] = np.sort(x[a:b])[:: 1 if rng.random() < 0.5 else -1]
        assert np.array_equal(K.argsort(x), x.argsort(kind="stable"))
        xi = rng.integers(-50, 50, n)
        assert np.array_equal(K.sorted_unique(xi), np.unique(xi))
    for _ in range(20):
        n = int(rng.integers(2, 200))
        a, b = rng.integers(0, 4, n), rng.integers(0, 3, n)
        s = np.round(rng.random(n) * 10, 1) * 1e12  # (R * top beyond 2**40)
        u, label = rng.random(n).round(1), rng.integers(0, 3, a.max() + 1)
        assert np.array_equal(oracles.u_trend(a, b, label, s, u, a.max() + 2), u_trend(a, b, label, s, u, a.max() + 2))


def test_gathered_paths_are_gather_paths():
    rng = np.random.default_rng(53)
    for _ in range(200):
        S = int(rng.integers(1, 12))
        counts = rng.integers(1, 6, S)
        N = int(counts.sum())
        pts = np.round(rng.random((N, 2)) * 3)  # (coarse: joint points that repeat)
        st = _strokes(pts, counts)
        group = rng.integers(0, int(rng.integers(1, S + 1)), S)
        pos = rng.permutation(S)
        rev = rng.random(S) < 0.4
        ref, got = oracles.gather_paths(st, group, rev, pos), gather_paths(st, group, rev, pos)
        for f in ("order", "c0", "src", "new_g", "joint", "drop", "path_sorted", "first", "n_path"):
            x, y = getattr(ref, f), getattr(got, f)
            assert np.array_equal(x, y) and x.dtype == y.dtype, f


def test_jump_order_is_lexsort():
    rng = np.random.default_rng(59)
    for trial in range(200):
        n = int(rng.integers(1, 300))
        st, vid = rng.integers(0, int(rng.integers(1, 6)), n), rng.integers(0, [2, 30, 10**6][trial % 3], n)
        s = np.round(rng.random(n) * 10, int(rng.integers(0, 3)))
        u = s / 3.0 + rng.integers(0, 2, n) * (3 if trial % 2 else 0)
        o, jumps = K.jump_order(st, vid, s, u, 3.0, 2.0)
        ref = np.lexsort((s, vid, st))
        assert np.array_equal(o, ref)
        same = (st[ref][1:] == st[ref][:-1]) & (vid[ref][1:] == vid[ref][:-1])
        step = np.diff(u[ref]) - np.diff(s[ref]) / 3.0
        assert jumps == bool((same & (np.abs(step) >= 2.0) & (np.round(step) != 0)).any())


def test_vote_groups_are_the_numpy_ones():
    """The compiled vote groups (bucketed by stroke, each bucket sorted by id) are np.unique's
    groups, their bincount weights and first_max_per_group's primaries."""
    from strokekit.tracking.votes import first_max_per_group, unique_inverse

    rng = np.random.default_rng(29)
    for trial in range(100):
        V = int(rng.integers(1, 400))
        S = int(rng.integers(1, 20))
        st = rng.integers(0, S, V)
        vid = rng.integers(0, [3, 40, 1000][trial % 3], V)
        w = np.where(rng.random(V) < 0.3, 1.0, rng.random(V))  # (ties of group weights)
        M = int(vid.max()) + 1
        ukey, ginv = unique_inverse(st * M + vid)
        gw = np.bincount(ginv, weights=w)
        primary = np.zeros(len(gw), bool)
        primary[first_max_per_group(ukey // M, gw)] = True
        gk, gi, gw2, p2 = K.vote_groups(st, vid, w)
        assert np.array_equal(gk, np.c_[ukey // M, ukey % M]) and np.array_equal(gi, ginv)
        assert np.array_equal(gw2, gw) and np.array_equal(p2, primary)


def test_is_in_is_np_isin():
    """The sorted search the brush paths use for id membership gives np.isin's mask: empty sides,
    repeats, unsorted values, negative ids (-1: no parent), values past either end."""
    from strokekit.tracking.votes import is_in

    rng = np.random.default_rng(31)
    for trial in range(200):
        x = rng.integers(-2, [5, 50, 10000][trial % 3], int(rng.integers(0, 60)))
        y = rng.integers(-1, [5, 50, 10000][trial % 3], int(rng.integers(0, 60)))
        assert np.array_equal(is_in(x, y), np.isin(x, y))


def test_inserted_points_are_insert_points():
    rng = np.random.default_rng(23)
    for trial in range(100):
        S = int(rng.integers(1, 6))
        counts = rng.integers(1, 8, S)
        N = int(counts.sum())
        pts = np.cumsum(rng.normal(0, 3.0, (N, 2)), axis=0)
        pts[rng.random(N) < 0.2] = 0.0  # (zero-length segments)
        st = _strokes(pts, counts, surface=rng.random((N, 3)), face=rng.integers(0, 9, N), u=rng.random(N))
        K = int(rng.integers(0, 20))
        stroke = rng.integers(0, S, K)
        s = rng.random(K) * st.lengths[stroke]
        s = np.where(rng.random(K) < 0.2, np.minimum(np.round(s), st.lengths[stroke]), s)  # (on points, ties)
        if trial % 3:  # (in order along the strokes, as the knots come; else not)
            o = np.lexsort((s, stroke))
            stroke, s = stroke[o], s[o]
        a, b = oracles.insert_points(st, stroke, s), insert_points(st, stroke, s)
        for f in ("points", "surface", "face", "u", "offsets"):
            assert np.array_equal(getattr(a, f), getattr(b, f)), f


def test_cut_pieces_are_cut_pieces():
    """The compiled cut_pieces is the line pass's (numpy) one: pieces, reversed ones too."""
    from strokekit.lines import strokeops

    rng = np.random.default_rng(29)
    for _ in range(100):
        S = int(rng.integers(1, 6))
        counts = rng.integers(2, 8, S)
        N = int(counts.sum())
        pts = np.cumsum(rng.normal(0, 3.0, (N, 2)), axis=0)
        pts[rng.random(N) < 0.15] = 0.0  # (zero-length segments)
        st = _strokes(pts, counts, surface=rng.random((N, 3)), face=rng.integers(0, 9, N), u=rng.random(N))
        K = int(rng.integers(0, 12))
        stroke = rng.integers(0, S, K)
        L = st.lengths[stroke]
        s0 = np.where(rng.random(K) < 0.3, 0.0, rng.random(K) * L * 0.5)
        s1 = np.where(rng.random(K) < 0.3, L, s0 + rng.random(K) * (L - s0))
        rev = rng.random(K) < 0.5
        for r in (None, rev):
            a, b = strokeops.cut_pieces(st, stroke, s0, s1, r), cut_pieces(st, stroke, s0, s1, r)
            for f in ("points", "surface", "face", "u", "offsets", "kind", "ids", "level", "level_weight"):
                assert np.array_equal(getattr(a, f), getattr(b, f)), f


def test_a_ctrl_c_in_a_compiled_loop_stays_a_keyboard_interrupt():
    from strokekit.numba_cache import keyboard_interrupts

    def in_loop():  # what the interpreter raises when one lands as a loop hands back its arrays
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as k:
            raise SystemError("CPUDispatcher(line_fit) returned a result with an exception set") from k

    with pytest.raises(KeyboardInterrupt):
        with keyboard_interrupts():
            in_loop()
    with pytest.raises(SystemError):
        with keyboard_interrupts():
            raise SystemError("not an interrupt")
    # A chain that loops back on itself is walked once: the SystemError comes out, no hang.
    a, b = SystemError("a"), ValueError("b")
    a.__cause__, b.__cause__ = b, a
    with pytest.raises(SystemError, match="a"):
        with keyboard_interrupts():
            raise a


@pytest.mark.parametrize("points, cell", [([[0.0, 0.0], [1e12, 1e12], [5.0, 5.0]], 1e-9),
                                          ([[0.0, 0.0], [1e12, -1e12], [5.0, 5.0]], 4.0),
                                          ([[-1e308, 0.0], [1e308, 1.0], [0.5, 0.5]], 4.0)])
def test_sample_grid_answers_as_the_tree_for_points_spread_beyond_what_cells_can_count(points, cell):
    """Points spread so wide that their cells' count overflows int64 (or their spread is not
    finite): the grid still answers as the k-d tree, with no crash and no write out of bounds."""
    import warnings

    from scipy.spatial import cKDTree

    p = np.array(points)
    q = np.array([[1.0, 1.0], [4.0, 6.0]])
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # (no overflow warning either)
        d, i = SampleGrid(p, cell).query(q, k=2, distance_upper_bound=20.0)
    dt, it = cKDTree(p).query(q, k=2, distance_upper_bound=20.0)
    assert np.array_equal(i, it) and np.allclose(d, dt)


def test_an_infinite_search_radius_is_refused():
    """The lookback's grid needs a finite radius; TrackingOptions says so as a usage error."""
    from strokekit.errors import UsageError
    from strokekit.tracking.options import TrackingOptions

    with pytest.raises(UsageError, match="search_radius_px must be a finite number"):
        TrackingOptions(search_radius_px=np.inf)


def test_brush_paths_refuse_lines_with_non_finite_points():
    """A NaN line point is an error, not a frame silently drawn without paths."""
    from strokekit.paths import PathOptions, PathTracker

    lines = _strokes(np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 5.0], [np.nan, 5.0]]), [2, 2])
    with pytest.raises(ValueError, match="non-finite"):
        PathTracker(PathOptions()).step(lines)


def _corner_cuts_numpy(strokes, p_line, p_s0, p_s1, smp, d_s, cos_min):
    """paths.compiled.corner_cuts in numpy: the vertices turning past acos(cos_min), each piece cut
    at those more than 0.5 px inside it, the samples following their part."""
    P, st, arc = strokes.points, strokes.stroke_of_point, strokes.arc_length
    d = P[1:] - P[:-1]
    ln = np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1])
    i = np.arange(1, len(P) - 1)
    i = i[(st[i - 1] == st[i]) & (st[i + 1] == st[i])]
    i = i[(ln[i - 1] > 1e-6) & (ln[i] > 1e-6)]
    i = i[(d[i - 1, 0] * d[i, 0] + d[i - 1, 1] * d[i, 1]) / (ln[i - 1] * ln[i]) < cos_min]
    owner, s0, s1, first, cuts = [], [], [], [], []
    for q in range(len(p_line)):
        c = arc[i[(st[i] == p_line[q]) & (arc[i] > p_s0[q] + 0.5) & (arc[i] < p_s1[q] - 0.5)]]
        first.append(len(owner))
        cuts.append(c)
        b = np.r_[p_s0[q], c, p_s1[q]]
        owner += [q] * (len(c) + 1)
        s0 += list(b[:-1])
        s1 += list(b[1:])
    out = smp.copy()
    for k in np.flatnonzero(smp >= 0):
        q = smp[k]
        out[k] = first[q] + np.count_nonzero(cuts[q] < d_s[k])
    return np.array(owner, np.int64), np.array(s0), np.array(s1), out


def test_corner_cuts_are_the_numpy_ones():
    rng = np.random.default_rng(23)
    cut = 0
    for _ in range(200):
        counts = rng.integers(1, 30, int(rng.integers(1, 6)))
        # steps along the axes and diagonals (turns of 0, 45, 90, 135, 180 degrees; repeats)
        step = rng.integers(-1, 2, (counts.sum(), 2)) * 1.0
        pts = np.cumsum(step, axis=0)
        S = _strokes(pts, counts)
        L = S.lengths
        Q = int(rng.integers(0, 8))
        p_line = rng.integers(0, len(counts), Q)
        a, b = rng.random(Q) * L[p_line], rng.random(Q) * L[p_line]
        p_s0, p_s1 = np.minimum(a, b), np.maximum(a, b)
        M = int(rng.integers(0, 40))
        smp = rng.integers(-1, Q, M) if Q else np.full(M, -1, np.int64)
        d_s = np.where(smp >= 0, p_s0[np.maximum(smp, 0)] + rng.random(M) * (p_s1 - p_s0)[np.maximum(smp, 0)], 0.0) \
            if Q else np.zeros(M)
        for cos_min in (-0.5, 0.0, np.cos(np.radians(70.0))):
            got = K.corner_cuts(S.points, S.offsets, S.arc_length, cos_min, p_line, p_s0, p_s1, smp, d_s)
            ref = _corner_cuts_numpy(S, p_line, p_s0, p_s1, smp, d_s, cos_min)
            for x, y in zip(ref, got):
                assert np.array_equal(x, y)
            cut += len(got[0]) - Q
    assert cut > 100  # (the inputs do cut pieces)


def test_a_line_is_covered_only_by_a_drawn_one():
    """Three shingles side by side, 1.5 px apart, ranked left to right: the middle one is covered
    by the left one (drawn), the right one, 3 px from the left, is not covered by the middle one
    (which is not drawn): it is drawn, so every line stays within the cover's 2 px of a drawn
    line. Brought within 2 px of the left one, it is covered by it."""
    def fan(gap):
        ys = np.arange(0.0, 20.0, 1.0)
        xs = [0.0, 1.5, 1.5 + gap]
        p = np.concatenate([np.c_[np.full(len(ys), x), ys] for x in xs])
        n = len(p)
        return Samples(p=p, X=np.zeros((n, 3)), u=np.zeros(n), t=np.tile([0.0, 1.0], (n, 1)), ids=np.zeros(n, np.int64),
                       stroke=np.repeat(np.arange(3), len(ys)), s=np.tile(ys, 3), w=np.ones(n))

    kind = np.zeros(3, np.int64)  # silhouettes
    for gap, right in ((1.5, "drawn"), (0.4, "covered by the left")):
        D = fan(gap)
        run = D.stroke.copy()
        for tree in (query_tree(D.p), SampleGrid(D.p, 3.0)):
            out = covering_samples(D, kind, run, np.arange(3), 2.0, tree)
            mid, rgt = out[run == 1], out[run == 2]
            assert (run[mid] == 0).all()
            if right == "drawn":
                assert (rgt == -1).all()
            else:
                assert (rgt >= 0).all() and (run[rgt] == 0).all()
