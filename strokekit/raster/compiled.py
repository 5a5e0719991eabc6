"""The raster pass's own compiled loops (numba), beside the z-buffer (`zbuffer.py`): what would
otherwise be several full-image numpy passes with temporaries. Imports numpy and numba only;
loaded on first use (`raster.hits.compiled()`: lines-only runs never import numba).

* `label_samples`: band label and key (label, material, object) of every sample, from the
  per-face tables of `bands.FaceShading` (smooth n.l interpolated only where a face spans bands).
* `thin_face_pixels`: the pixels a triangle thinner than the sample spacing crosses where it may
  show another key than the samples there (`bands._thin_face_pixels` says why).
* `label_counts`: per mixed pixel, the samples of each label.
* `mixed_sums`: per mixed pixel, the samples of each label and the sum of its covered samples'
  linear colours.
* `view_normals`: the EXR's view-space normal of every pixel's representative sample.
* `crypto_rank0`: Cryptomatte's rank 0 (id, coverage 1) of every pixel's representative sample.
* `crypto_ranks`: Cryptomatte's ranks of the mixed pixels from their samples.
* `table_planes`: the EXR's shade colours, a table's columns gathered by key into planes.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from strokekit.numba_cache import kernel


@njit(cache=True, error_model="numpy")
def _quantize(x, bands, thresholds):
    """bands.quantize_bands of one finite n.l: 1 + floor(max(0, x) N) clipped to N, or 1 + the
    number of thresholds <= x."""
    if thresholds.shape[0] > 0:
        n = 0
        for t in thresholds:
            if t <= x:
                n += 1
        return n + 1
    v = math.floor(x * bands)
    if v < 0.0:
        v = 0.0
    if v > bands - 1:
        v = bands - 1
    return int(v) + 1


@kernel("(i4[::1], f4[:, ::1], u1[::1], f8[:, ::1], i8, f8[::1], i4[::1], u1[::1], i4[::1])", error_model="numpy")
def label_samples(face, bary, label, coef, bands, thresholds, region, out_label, out_key):
    """Labels and keys of M samples (flat arrays): face (M,) int32 (-1: background), bary (M, 2)
    float32; label (F + 1,) uint8 the per-face label or 255 (interpolate), label[F] = 0; coef
    (F, 7) float64 the smooth-shading scalars (corner n.l a, b, c, their normals' dot products
    ab, bc, ca, the two-sided sign; (0, 7) for flat shading); thresholds (T,) float64; region
    (F,) int32 ((0,): one region, key = label). out_label (M,) uint8, out_key (M,) int32."""
    step = bands + 1
    one = region.shape[0] == 0
    for i in range(face.shape[0]):
        f = face[i]
        if f < 0:
            out_label[i] = 0
            out_key[i] = 0
            continue
        lab = label[f]
        if lab == 255:
            wb = np.float64(bary[i, 0])
            wc = np.float64(bary[i, 1])
            wa = 1.0 - wb - wc
            norm2 = wa * wa + wb * wb + wc * wc + 2 * (wa * wb * coef[f, 3] + wb * wc * coef[f, 4]
                                                       + wc * wa * coef[f, 5])
            if norm2 < 1e-24:
                norm2 = 1e-24
            x = coef[f, 6] * (wa * coef[f, 0] + wb * coef[f, 1] + wc * coef[f, 2]) / math.sqrt(norm2)
            lab = _quantize(x, bands, thresholds)
        out_label[i] = lab
        out_key[i] = lab if one else lab + step * region[f]


#: Largest pixel box (with its ring) `_behind_box` reads; a longer sliver gets the per-pixel test.
_BOX_PIXELS = 256


@njit(cache=True, error_model="numpy")
def _behind_box(xmin, xmax, ymin, ymax, zmin, W, H, K, depth, slack):
    """Whether a triangle with pixel box [xmin, xmax] x [ymin, ymax] and nearest corner depth
    zmin is behind every sample of its box widened by two pixels (its edge pixels' 3 x 3
    neighbourhoods, with a pixel more for the rounding of its edge crossings): then the
    per-pixel depth test of `thin_face_pixels` rejects each of its pixels (a depth on an edge is
    at least the nearer end's, up to rounding, which the 1e-9 margin covers). False for a box
    of more than _BOX_PIXELS pixels."""
    c0 = int(max(math.floor(xmin) - 2.0, 0.0))
    c1 = int(min(math.floor(xmax) + 2.0, W - 1.0))
    r0 = int(max(math.floor(ymin) - 2.0, 0.0))
    r1 = int(min(math.floor(ymax) + 2.0, H - 1.0))
    if c0 > c1 or r0 > r1:
        return True  # no pixel of the image
    if (c1 - c0 + 1) * (r1 - r0 + 1) > _BOX_PIXELS:
        return False
    zmax = -np.inf
    for r in range(r0 * K, (r1 + 1) * K):
        for q in range(c0 * K, (c1 + 1) * K):
            if depth[r, q] > zmax:
                zmax = depth[r, q]
    return zmin * (1.0 - 1e-9) > np.float64(zmax) * (1 + slack)


@kernel(("(f8[:, ::1], f8[::1], i4[:, ::1], f8, i8, i8, i8, u1[::1], u1[::1], b1[::1], i4[::1], i8[:, ::1], "
        "i8, f4[:, ::1], i4[:, ::1], b1, f8, b1[:, ::1])"), error_model="numpy")
def thin_face_pixels(xy, z, faces, near, W, H, K, lo, hi, back, region, nb, step, depth, keys, ortho, slack, out):
    """Mark in out (H, W) bool the pixels where a thin triangle may show a key its pixel's K x K
    samples do not have (see bands._thin_face_pixels): xy (V, 2), z (V,) the vertices' pixel
    coordinates and view depths; faces (F, 3) int32; lo, hi (F,) uint8 the labels a face can
    have; back (F,) bool; region (F,) int32 (all 0 for one region); nb (F, 3) int64 the faces
    across its edges (-1: border or non-manifold); step = N + 1; depth (HK, WK) float32, keys
    (HK, WK) int32 the sample grid; slack the relative depth slack. Returns the pixels marked
    (with repeats)."""
    thr = math.sqrt(0.5) / K
    HK, WK = depth.shape
    marked = 0
    for fi in range(faces.shape[0]):
        ia, ib, ic = faces[fi, 0], faces[fi, 1], faces[fi, 2]
        za, zb, zc = z[ia], z[ib], z[ic]
        if not (min(za, zb, zc) > near):
            continue
        xa, ya, xb, yb, xc, yc = xy[ia, 0], xy[ia, 1], xy[ib, 0], xy[ib, 1], xy[ic, 0], xy[ic, 1]
        if not (max(xa, xb, xc) >= 0 and min(xa, xb, xc) < W and max(ya, yb, yc) >= 0 and min(ya, yb, yc) < H):
            continue
        twice_area = abs((xb - xa) * (yc - ya) - (yb - ya) * (xc - xa))
        # inradius = 2 area / perimeter < thr; the perimeter is at most the edges' |dx| + |dy|
        # (a test without square roots first: most faces are not thin)
        if not (twice_area < thr * (abs(xb - xa) + abs(yb - ya) + abs(xc - xb) + abs(yc - yb) + abs(xa - xc)
                                    + abs(ya - yc))):
            continue
        perim = math.hypot(xb - xa, yb - ya) + math.hypot(xc - xb, yc - yb) + math.hypot(xa - xc, ya - yc)
        if not (twice_area < perim * thr):
            continue
        l0 = lo[fi]
        r0 = region[fi]
        if hi[fi] == l0:
            plain = True
            for k in range(3):
                n = nb[fi, k]
                if n < 0 or lo[n] != l0 or hi[n] != l0 or region[n] != r0 or back[n] != back[fi]:
                    plain = False
                    break
            if plain:
                continue
        if _behind_box(min(xa, xb, xc), max(xa, xb, xc), min(ya, yb, yc), max(ya, yb, yc), min(za, zb, zc), W, H,
                       K, depth, slack):
            continue
        klo = np.int64(l0) + step * r0
        khi = np.int64(hi[fi]) + step * r0
        for e in range(3):
            if e == 0:
                ax, ay, az, bx, by, bz = xa, ya, za, xb, yb, zb
            elif e == 1:
                ax, ay, az, bx, by, bz = xb, yb, zb, xc, yc, zc
            else:
                ax, ay, az, bx, by, bz = xc, yc, zc, xa, ya, za
            dx, dy = bx - ax, by - ay
            # The pixel of the start corner, then both pixels at every crossing of a pixel column
            # line x = g (c = 0) and row line y = g (c = 1) inside the image.
            for c in range(3):
                if c == 2:
                    g0, g1 = 0, 0
                else:
                    p0, dd, lim = (ax, dx, W) if c == 0 else (ay, dy, H)
                    lo_c, hi_c = min(p0, p0 + dd), max(p0, p0 + dd)
                    g0 = int(min(max(math.floor(lo_c), -1.0), lim)) + 1
                    g1 = int(min(max(math.floor(hi_c), -1.0), lim))
                for g in range(g0, g1 + 1):
                    if c == 2:
                        t = 0.0
                        px0, py0 = ax, ay
                        sides = 1
                    else:
                        t = (g - (ax if c == 0 else ay)) / (dx if c == 0 else dy)
                        t = min(max(t, 0.0), 1.0)
                        px0, py0 = ax + t * dx, ay + t * dy
                        if c == 0:
                            px0 = g + 0.5
                        else:
                            py0 = g + 0.5
                        sides = 2
                    if ortho:
                        zt = az + t * (bz - az)
                    else:
                        zt = 1.0 / ((1 - t) / az + t / bz)
                    for s in range(sides):
                        qx, qy = px0, py0
                        if s == 1:
                            if c == 0:
                                qx = g - 0.5
                            else:
                                qy = g - 0.5
                        ix = int(math.floor(qx))
                        iy = int(math.floor(qy))
                        if ix < 0 or ix >= W or iy < 0 or iy >= H:
                            continue
                        if out[iy, ix]:
                            continue
                        # Cannot change it: the pixel's samples all carry the face's one key.
                        if klo == khi and keys[iy * K, ix * K] == klo:
                            same = True
                            for r in range(iy * K, iy * K + K):
                                for q in range(ix * K, ix * K + K):
                                    if keys[r, q] != klo:
                                        same = False
                            if same:
                                continue
                        # Hidden there: behind every sample of the 3 x 3 pixels around.
                        zmax = -np.inf
                        for r in range(max(iy * K - K, 0), min(iy * K + 2 * K, HK)):
                            for q in range(max(ix * K - K, 0), min(ix * K + 2 * K, WK)):
                                if depth[r, q] > zmax:
                                    zmax = depth[r, q]
                        if not (zt <= np.float64(zmax) * (1 + slack)):
                            continue
                        out[iy, ix] = True
                        marked += 1
    return marked


@kernel("(u1[:, ::1], i8[:, ::1])", error_model="numpy")
def label_counts(labels, counts):
    """counts (P, n) int64: per mixed pixel (rows of labels (P, S), every label < n), its samples
    of each label."""
    for p in range(labels.shape[0]):
        for c in range(counts.shape[1]):
            counts[p, c] = 0
        for s in range(labels.shape[1]):
            counts[p, labels[p, s]] += 1


@kernel("(u1[:, ::1], i4[:, ::1], f8[:, ::1], i8, i4[:, ::1], f8[:, ::1])", error_model="numpy")
def mixed_sums(labels, keys, colours, n_labels, counts, rgb):
    """Per mixed pixel (rows of labels, keys (P, S)): counts (P, n_labels) int32 its samples of
    each label; rgb (P, 3) float64 the sum of the linear colours (colours (keys, 3), by key) of
    its covered samples (label > 0)."""
    for p in range(labels.shape[0]):
        for c in range(n_labels):
            counts[p, c] = 0
        r = g = b = 0.0
        for s in range(labels.shape[1]):
            lab = labels[p, s]
            if lab < n_labels:
                counts[p, lab] += 1
            if lab > 0:
                k = keys[p, s]
                r += colours[k, 0]
                g += colours[k, 1]
                b += colours[k, 2]
        rgb[p, 0] = r
        rgb[p, 1] = g
        rgb[p, 2] = b


@kernel(("(i4[:, ::1], f4[:, :, ::1], i8, i8[:, ::1], f8[:, ::1], f8[:, ::1], f8[::1], f8[::1], f8[::1], "
        "f8[::1], f8[::1], f8[::1], f4[:, ::1])"), error_model="numpy")
def view_normals(face, bary, K, corner, normals, face_normals, right, up, fwd, ray_x, ray_y, ortho_dir, out):
    """View-space unit normals (x right, y up, z toward the camera) of each output pixel's sample
    nearest its centre: face (H K, W K) int32 (-1 background), bary (H K, W K, 2) float32; corner
    (F, 3) int64 rows of normals (Nn, 3) float64 interpolated at the barycentrics (smooth
    shading), or (0, 3) for the face normal (flat); face_normals (F, 3) float64; right, up, fwd
    (3,) the camera basis; ray_x (W K,), ray_y (H K,) the perspective rays' offsets along right
    and up; ortho_dir (3,) the ray direction of a parallel projection, or (0,) for perspective.
    Normals face the camera (two-sided, as the bands are lit). out (3, H W) float32, 0 on
    background."""
    H = face.shape[0] // K
    W = face.shape[1] // K
    c = K // 2
    smooth = corner.shape[0] > 0
    ortho = ortho_dir.shape[0] == 3
    for r in range(H):
        for col in range(W):
            i = r * W + col
            f = face[r * K + c, col * K + c]
            if f < 0:
                out[0, i] = 0.0
                out[1, i] = 0.0
                out[2, i] = 0.0
                continue
            if smooth:
                u = np.float64(bary[r * K + c, col * K + c, 0])
                v = np.float64(bary[r * K + c, col * K + c, 1])
                a = 1.0 - u - v
                ia, ib, ic = corner[f, 0], corner[f, 1], corner[f, 2]
                nx = a * normals[ia, 0] + u * normals[ib, 0] + v * normals[ic, 0]
                ny = a * normals[ia, 1] + u * normals[ib, 1] + v * normals[ic, 1]
                nz = a * normals[ia, 2] + u * normals[ib, 2] + v * normals[ic, 2]
                ln = math.sqrt(nx * nx + ny * ny + nz * nz)
                if ln < 1e-12:
                    ln = 1e-12
                nx /= ln
                ny /= ln
                nz /= ln
            else:
                nx, ny, nz = face_normals[f, 0], face_normals[f, 1], face_normals[f, 2]
            if ortho:
                dx, dy, dz = ortho_dir[0], ortho_dir[1], ortho_dir[2]
            else:
                sx = ray_x[col * K + c]
                sy = ray_y[r * K + c]
                dx = fwd[0] + sx * right[0] + sy * up[0]
                dy = fwd[1] + sx * right[1] + sy * up[1]
                dz = fwd[2] + sx * right[2] + sy * up[2]
            # The geometric side decides which way the normal faces.
            if face_normals[f, 0] * dx + face_normals[f, 1] * dy + face_normals[f, 2] * dz > 0:
                nx, ny, nz = -nx, -ny, -nz
            out[0, i] = nx * right[0] + ny * right[1] + nz * right[2]
            out[1, i] = nx * up[0] + ny * up[1] + nz * up[2]
            out[2, i] = -(nx * fwd[0] + ny * fwd[1] + nz * fwd[2])


@kernel("(i4[::1], i4[::1], f4[::1], f4[::1], f4[::1])")
def crypto_rank0(face, table, bits, ids, cov):
    """Cryptomatte's rank 0 of the uniform pixels: at each pixel of face (M,) (its representative
    sample's face, -1: background), ids gets bits[table[face]] (the id, as float32 bits, of the
    face's object or material) and cov 1; background pixels are left as they are (0)."""
    for i in range(face.shape[0]):
        f = face[i]
        if f >= 0:
            ids[i] = bits[table[f]]
            cov[i] = 1.0


@kernel("(i4[::1], f4[:, ::1], f4[:, ::1])")
def table_planes(key, table, out):
    """out[c, i] = table[c, key[i]] for every channel c: a (C, M) gather in one pass over key."""
    for i in range(key.shape[0]):
        k = key[i]
        for c in range(table.shape[0]):
            out[c, i] = table[c, k]


@kernel("(i4[:, ::1], f4[::1], f4[:, ::1], f4[:, ::1])")
def crypto_ranks(slots, bits, ids, cov):
    """Cryptomatte's ranks of P mixed pixels from their S samples: slots (P, S) the slot of each
    sample's id in the ascending table of distinct ids (-1: background), bits (U,) those ids as
    float32. ids, cov (R, P), zero on entry, get each pixel's R most-seen ids, by count (then
    ascending id), at coverage count / S (background counts in S): cryptomatte.rank_samples'
    ranks with every sample weighing 1."""
    P, S = slots.shape
    R = ids.shape[0]
    s = np.empty(S, np.int32)
    cand = np.empty(S, np.int32)
    count = np.empty(S, np.int64)
    for p in range(P):
        n = 0
        for j in range(S):  # the pixel's ids, sorted (insertion: S is small)
            v = slots[p, j]
            if v < 0:
                continue
            i = n
            while i > 0 and s[i - 1] > v:
                s[i] = s[i - 1]
                i -= 1
            s[i] = v
            n += 1
        m = 0
        for j in range(n):  # runs of one id: candidates in ascending id order
            if m > 0 and cand[m - 1] == s[j]:
                count[m - 1] += 1
            else:
                cand[m] = s[j]
                count[m] = 1
                m += 1
        for r in range(min(R, m)):  # the most-seen left, the lowest id among equals
            best = -1
            for j in range(m):
                if count[j] > 0 and (best < 0 or count[j] > count[best]):
                    best = j
            ids[r, p] = bits[cand[best]]
            cov[r, p] = count[best] / S
            count[best] = 0
