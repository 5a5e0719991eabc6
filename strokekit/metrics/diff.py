"""Golden diffs: compare the stroke geometry of two SVG drawings (or two folders of them) within a
pixel tolerance, kind by kind.

Two drawings are equal at tolerance `tol` (px, in SVG user units = viewBox units) when, for every
line kind (SVG layer), every point of A's strokes lies within `tol` of B's strokes of the same kind
and every point of B's strokes lies within `tol` of A's (a symmetric, Hausdorff-style test). Stroke
ids, stroke order, stroke direction and where strokes are split do not matter: only the drawn
geometry does. Ids that changed on otherwise identical strokes are reported as information.

How the test is made: each polyline is resampled at most `tol / 2` px apart (plus its vertices);
each sample's exact distance to the other drawing's polylines is found with a k-d tree over short
pieces of those polylines (candidates within `tol + piece/2` of the sample, then exact
point-to-segment distances). Between two samples the true distance can exceed the sampled ones by
at most `tol / 4`. Identical geometry (the usual case for golden files) is detected exactly and
costs no sampling. The drawings are read by `strokekit.metrics.svg_reader`.
"""

from __future__ import annotations

import io
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from strokekit.errors import InputError, UsageError
from strokekit.fileio import atomic_write_bytes
from strokekit.metrics.svg_reader import STYLE_KEYS, Polylines, SvgDrawing, read_svg
from strokekit.sampling import segment_samples

#: Colours of the difference image (RGB): strokes only in A, only in B, and common to both.
A_ONLY_COLOR = (220, 20, 20)
B_ONLY_COLOR = (20, 60, 220)
COMMON_COLOR = (160, 160, 160)
#: Faint frames drawn around the differing regions so that small differences can be found.
A_REGION_COLOR = (255, 205, 205)
B_REGION_COLOR = (205, 215, 255)
BACKGROUND_COLOR = (255, 255, 255)

#: Refuse to sample more than this many points for one kind and one side (memory ~ 100 bytes each).
MAX_SAMPLES = 5_000_000
#: Float slack added to `tol` so that a shift of exactly `tol` written in decimal text still passes.
_EPS = 1e-6

# ----------------------------------------------------------------------------------------------
# Sampling and distances
# ----------------------------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class _Samples:
    """Points along polylines at most `step` px apart, in order along each polyline. pos (M, 2),
    stroke (M,) polyline index, weight (M,) px of arc length each sample stands for (half of the
    intervals on either side, so weights sum to the total length)."""

    pos: np.ndarray
    stroke: np.ndarray
    weight: np.ndarray
    step: float


def _count_samples(pl: Polylines, step: float) -> int:
    seg = pl.segment_lengths
    last = np.zeros(len(pl.points), bool)
    last[pl.offsets[1:] - 1] = True
    return int(np.maximum(1, np.ceil(seg / step))[~last[:-1]].sum() + len(pl)) if len(pl.points) > 1 else len(pl)


def _resample(pl: Polylines, step: float) -> _Samples:
    """The samples of `segment_samples`, each weighing half the gaps to its neighbours."""
    pos, stroke, _ = segment_samples(pl.points, pl.offsets, step)
    gap = np.zeros(len(pos) + 1)
    if len(pos) > 1:
        same = stroke[1:] == stroke[:-1]
        gap[1:-1] = np.where(same, np.linalg.norm(np.diff(pos, axis=0), axis=1), 0.0)
    weight = 0.5 * (gap[:-1] + gap[1:])
    return _Samples(pos, stroke, weight, step)


class _NearestStroke:
    """Exact distance from query points to a set of polylines.

    The polylines are cut into pieces at most `piece` px long; a k-d tree holds the piece
    midpoints. A point within `tol` of a piece has that piece's midpoint within `tol + piece/2`,
    so a bounded k-nearest query (asking again with more slots, then a ball query, when the k
    slots are full) finds every candidate and the exact point-to-segment minimum is the distance.
    For points farther than `tol`
    the distance comes from the k nearest midpoints (exact in practice, never off by more than
    piece/2)."""

    K = 8

    def __init__(self, pl: Polylines, piece: float):
        s = _resample(pl, piece)
        same = s.stroke[1:] == s.stroke[:-1]
        a, b, st = s.pos[:-1][same], s.pos[1:][same], s.stroke[:-1][same]
        # polylines of a single point are pieces of length 0
        single = np.flatnonzero(np.diff(pl.offsets) == 1)
        if len(single):
            p1 = pl.points[pl.offsets[single]]
            a, b, st = np.vstack([a, p1]), np.vstack([b, p1]), np.r_[st, single]
        self.a, self.b, self.stroke = a, b, st
        self.piece = piece
        self.tree = cKDTree(0.5 * (a + b))

    def _exact(self, q: np.ndarray, idx: np.ndarray) -> np.ndarray:
        """(M, K) distances from q (M, 2) to pieces idx (M, K); inf where idx is out of range."""
        ok = idx < len(self.a)
        j = np.where(ok, idx, 0)
        a, ab = self.a[j], self.b[j] - self.a[j]
        den = np.maximum((ab * ab).sum(-1), 1e-300)
        t = np.clip(((q[:, None, :] - a) * ab).sum(-1) / den, 0.0, 1.0)
        dist = np.linalg.norm(q[:, None, :] - (a + t[..., None] * ab), axis=-1)
        return np.where(ok, dist, np.inf)

    def _best(self, q, idx):
        dist = self._exact(q, idx)
        arg = np.argmin(dist, axis=1)
        rows = np.arange(len(q))
        best = np.minimum(idx[rows, arg], len(self.a) - 1)
        return dist[rows, arg], self.stroke[best]

    def query(self, q: np.ndarray, tol: float, chunk: int = 32_768) -> tuple[np.ndarray, np.ndarray]:
        """(M,) distance in px from each point of q (M, 2) to the nearest polyline, and (M,) that
        polyline's index."""
        dist = np.empty(len(q))
        near = np.empty(len(q), np.int64)
        k = min(self.K, len(self.a))
        r = tol + 0.5 * self.piece + _EPS
        for s0 in range(0, len(q), chunk):
            qc = q[s0:s0 + chunk]
            dm, idx = self.tree.query(qc, k=k, distance_upper_bound=r)
            dm, idx = dm.reshape(len(qc), k), idx.reshape(len(qc), k)
            d, st = self._best(qc, idx)
            # all k slots full: the nearest piece may be among the others within reach. Ask again
            # with more slots, then one ball query per point that is still full (rare: only where
            # many strokes crowd within tol + piece/2, as at junctions)
            full = np.flatnonzero(np.isfinite(dm[:, -1]))
            if len(full) and len(self.a) > k:
                k2 = min(8 * k, len(self.a))
                dm2, idx2 = self.tree.query(qc[full], k=k2, distance_upper_bound=r)
                dm2, idx2 = dm2.reshape(len(full), k2), idx2.reshape(len(full), k2)
                d[full], st[full] = self._best(qc[full], idx2)
                for i in full[np.isfinite(dm2[:, -1])] if k2 < len(self.a) else ():
                    cand = np.array(self.tree.query_ball_point(qc[i], r), np.int64)
                    dd = self._exact(qc[i:i + 1], cand[None, :])[0]
                    j = int(np.argmin(dd))
                    d[i], st[i] = dd[j], self.stroke[cand[j]]
            far = np.flatnonzero(d > tol + _EPS)
            if len(far):
                _, idx2 = self.tree.query(qc[far], k=k)
                d2, st2 = self._best(qc[far], idx2.reshape(len(far), k))
                better = d2 < d[far]
                d[far[better]], st[far[better]] = d2[better], st2[better]
            dist[s0:s0 + len(qc)], near[s0:s0 + len(qc)] = d, st
        return dist, near


# ----------------------------------------------------------------------------------------------
# Results
# ----------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Region:
    """A connected place where one drawing has strokes the other lacks (within tol).
    side 'a' (only in A) or 'b' (only in B); bbox (x0, y0, x1, y1) px; length px of the strokes
    there; max_deviation px from the other drawing (None: the other has no stroke of this kind);
    stroke_ids: ids of the strokes involved on that side."""

    kind: str
    side: str
    bbox: tuple[float, float, float, float]
    length: float
    max_deviation: float | None
    stroke_ids: tuple

    def to_dict(self) -> dict:
        return {"kind": self.kind, "side": self.side, "bbox": [round(v, 3) for v in self.bbox],
                "length_px": round(self.length, 4),
                "max_deviation_px": None if self.max_deviation is None else round(self.max_deviation, 4),
                "stroke_ids": list(self.stroke_ids)}


@dataclass(eq=False)
class KindDiff:
    """Figures of one kind. Lengths in px. a_only_length: length of A's strokes farther than tol
    from B's strokes of the same kind (b_only_length likewise). max_deviation: the largest distance
    found from a point of either side to the other (0 for identical geometry, None when one side
    has no stroke of this kind and the other has). renamed: (id in A, id in B) of strokes with the
    same geometry on both sides but different ids (information, not a difference)."""

    kind: str
    strokes_a: int
    strokes_b: int
    length_a: float
    length_b: float
    a_only_length: float = 0.0
    b_only_length: float = 0.0
    max_deviation: float | None = 0.0
    equal: bool = True
    identical: bool = False
    regions: list[Region] = field(default_factory=list)
    renamed: list[tuple] = field(default_factory=list)
    # for the difference image: polylines of both sides, unmatched samples and their run numbers
    _draw: dict | None = field(default=None, repr=False)

    def to_dict(self) -> dict:
        return {"kind": self.kind, "equal": self.equal, "identical": self.identical,
                "strokes_a": self.strokes_a, "strokes_b": self.strokes_b,
                "length_a_px": round(self.length_a, 4), "length_b_px": round(self.length_b, 4),
                "a_only_length_px": round(self.a_only_length, 4), "b_only_length_px": round(self.b_only_length, 4),
                "max_deviation_px": None if self.max_deviation is None else round(self.max_deviation, 4),
                "regions": [r.to_dict() for r in self.regions],
                "renamed_ids": [list(p) for p in self.renamed]}


def _fmt_ids(ids, limit=6) -> str:
    ids = [i for i in ids if i is not None]
    s = ", ".join(str(i) for i in ids[:limit])
    return s + (f", +{len(ids) - limit} more" if len(ids) > limit else "")


def _fmt_dev(v: float | None) -> str:
    return "n/a (kind missing on one side)" if v is None else f"{v:.3g} px"


@dataclass(eq=False)
class DiffResult:
    """Comparison of two SVG drawings at tolerance `tol` px. `equal` is true when every kind is
    equal within tol. `kinds` maps each kind found in either file to its KindDiff."""

    a: str
    b: str
    tol: float
    kinds: dict[str, KindDiff]
    viewbox_a: tuple | None = None
    viewbox_b: tuple | None = None
    styles_a: dict = field(default_factory=dict)  # SvgDrawing.styles of A and B
    styles_b: dict = field(default_factory=dict)

    @property
    def same_canvas(self) -> bool:
        """Both viewBoxes within tol of each other (a file without one is not compared): the same
        strokes on another canvas (another --size, a shifted viewBox) are another picture."""
        a, b = self.viewbox_a, self.viewbox_b
        return a is None or b is None or all(abs(x - y) <= self.tol for x, y in zip(a, b))

    @property
    def equal(self) -> bool:
        return self.same_canvas and all(k.equal for k in self.kinds.values())

    @property
    def regions(self) -> list[Region]:
        """All differing regions, largest first."""
        return sorted((r for k in self.kinds.values() for r in k.regions), key=lambda r: -r.length)

    @property
    def renamed(self) -> list[tuple[str, str, str]]:
        """(kind, id in A, id in B) of strokes whose geometry is the same but whose id changed."""
        return [(k.kind, ia, ib) for k in self.kinds.values() for ia, ib in k.renamed]

    @property
    def look_notes(self) -> list[str]:
        """What changed in the drawing's look but is no difference: a viewBox within tol, styles."""
        out = []
        if self.viewbox_a != self.viewbox_b and self.same_canvas:
            out.append(f"viewBox differs within {self.tol:g} px: A {self.viewbox_a}, B {self.viewbox_b}")
        for kind in self.kinds:
            a, b = self.styles_a.get(kind), self.styles_b.get(kind)
            if a and b and a != b:
                out.append(f"{kind}: style differs (geometry is what is compared): A {_fmt_styles(a)}, "
                           f"B {_fmt_styles(b)}")
        return out

    @property
    def notes(self) -> list[str]:
        """Information that does not make the drawings different: look_notes, new stroke ids."""
        out = self.look_notes
        for k in self.kinds.values():
            if k.renamed:
                ex = ", ".join(f"{ia}->{ib}" for ia, ib in k.renamed[:5])
                more = f", +{len(k.renamed) - 5} more" if len(k.renamed) > 5 else ""
                out.append(f"{k.kind}: {len(k.renamed)} stroke(s) with the same geometry have new ids ({ex}{more})")
        return out

    def to_dict(self) -> dict:
        return {"a": self.a, "b": self.b, "tol_px": self.tol, "equal": self.equal,
                "viewbox_a": list(self.viewbox_a) if self.viewbox_a else None,
                "viewbox_b": list(self.viewbox_b) if self.viewbox_b else None, "same_canvas": self.same_canvas,
                "kinds": {k: v.to_dict() for k, v in self.kinds.items()}, "notes": self.notes}

    def summary(self, max_regions: int = 8) -> str:
        """A compact human summary: verdict, then per kind what changed and where."""
        lines = []
        if self.equal:
            dev = max((k.max_deviation or 0.0) for k in self.kinds.values()) if self.kinds else 0.0
            identical = all(k.identical for k in self.kinds.values())
            how = "identical geometry" if identical else f"max deviation {dev:.3g} px"
            lines.append(f"equal within {self.tol:g} px: {self.a} vs {self.b} ({how})")
        else:
            lines.append(f"DIFFERENT at {self.tol:g} px: {self.a} (A) vs {self.b} (B)")
            if not self.same_canvas:
                lines.append(f"  canvas: viewBox A {_fmt_box(self.viewbox_a)}, B {_fmt_box(self.viewbox_b)}")
            for k in self.kinds.values():
                if k.equal:
                    continue
                lines.append(f"  {k.kind}: {k.a_only_length:.1f} px only in A, {k.b_only_length:.1f} px only in B, "
                             f"max deviation {_fmt_dev(k.max_deviation)} "
                             f"[A {k.length_a:.1f} px in {k.strokes_a} strokes, "
                             f"B {k.length_b:.1f} px in {k.strokes_b}]")
                for r in k.regions[:max_regions]:
                    x0, y0, x1, y1 = r.bbox
                    where = f"x {x0:.1f}..{x1:.1f}, y {y0:.1f}..{y1:.1f}"
                    ids = f" (strokes {_fmt_ids(r.stroke_ids)})" if any(i is not None for i in r.stroke_ids) else ""
                    dev = "" if r.max_deviation is None else f", {r.max_deviation:.3g} px away"
                    if r.length < 0.05 and x1 - x0 < 0.05 and y1 - y0 < 0.05:  # a stroke end or a dot, not a stretch
                        where = f"a point near ({(x0 + x1) / 2:.2f}, {(y0 + y1) / 2:.2f})"
                        lines.append(f"    only in {r.side.upper()}: {where}{dev}{ids}")
                    else:
                        lines.append(f"    only in {r.side.upper()}: {r.length:.1f} px at {where}{dev}{ids}")
                if len(k.regions) > max_regions:
                    lines.append(f"    ... {len(k.regions) - max_regions} more regions (see --json)")
            same = [k.kind for k in self.kinds.values() if k.equal and (k.strokes_a or k.strokes_b)]
            if same:
                lines.append(f"  equal: {', '.join(same)}")
        lines += [f"  note: {n}" for n in self.notes]
        return "\n".join(lines)


def _fmt_styles(styles: frozenset) -> str:
    shown = sorted(styles)[:3]
    text = "; ".join(" ".join(f"{k} {v}" for k, v in zip(STYLE_KEYS, st)) for st in shown)
    return text + (f" (+{len(styles) - 3} more)" if len(styles) > 3 else "")


def _fmt_box(box: tuple) -> str:
    return " ".join(f"{v:g}" for v in box)


@dataclass(eq=False)
class DirDiffResult:
    """Comparison of two folders of SVG files paired by relative path. missing: files in A (the
    reference) that B lacks; extra: files in B that A lacks. `equal` needs both empty and every
    pair equal."""

    a: str
    b: str
    tol: float
    files: dict[str, DiffResult]
    missing: list[str]
    extra: list[str]
    pngs: list[str] = field(default_factory=list)

    @property
    def equal(self) -> bool:
        return not self.missing and not self.extra and all(r.equal for r in self.files.values())

    @property
    def different(self) -> list[str]:
        return [n for n, r in self.files.items() if not r.equal]

    def to_dict(self) -> dict:
        return {"a": self.a, "b": self.b, "tol_px": self.tol, "equal": self.equal,
                "compared": len(self.files), "different": self.different,
                "missing": self.missing, "extra": self.extra, "pngs": self.pngs,
                "files": {n: r.to_dict() for n, r in self.files.items()}}

    def summary(self, max_files: int = 20) -> str:
        diff = self.different
        head = "equal" if self.equal else "DIFFERENT"
        lines = [f"{head} at {self.tol:g} px: {self.a} (A) vs {self.b} (B): {len(self.files)} files compared, "
                 f"{len(self.files) - len(diff)} equal, {len(diff)} different, {len(self.missing)} missing in B, "
                 f"{len(self.extra)} extra in B"]
        if self.missing:
            lines.append(f"  missing in B: {_fmt_ids(self.missing, 10)}")
        if self.extra:
            lines.append(f"  extra in B: {_fmt_ids(self.extra, 10)}")
        for n in diff[:max_files]:
            lines.append("  " + self.files[n].summary().replace("\n", "\n  "))
        if len(diff) > max_files:
            lines.append(f"  ... {len(diff) - max_files} more different files (see --json)")
        # The look notes of equal files (a different file's summary has its own), each said once
        # with the files it holds for: a changed stroke width is the same note in every frame.
        looks: dict[str, list[str]] = {}
        for n, r in self.files.items():
            for note in r.look_notes if r.equal else ():
                looks.setdefault(note, []).append(n)
        for note, names in looks.items():
            lines.append(f"  note: {note} [{_fmt_ids(names, 3)}]")
        renamed = sum(len(r.renamed) for r in self.files.values())
        if renamed:
            lines.append(f"  note: {renamed} stroke(s) in {sum(1 for r in self.files.values() if r.renamed)} "
                         f"file(s) have new ids with the same geometry")
        return "\n".join(lines)


# ----------------------------------------------------------------------------------------------
# Comparing
# ----------------------------------------------------------------------------------------------

def _check_tol(tol) -> float:
    try:
        tol = float(tol)
    except (TypeError, ValueError):
        raise UsageError(f"tolerance must be a number of px, got {tol!r}") from None
    if not (math.isfinite(tol) and tol > 0):
        raise UsageError(f"tolerance must be a positive number of px, got {tol!r}")
    return tol


def _canonical_keys(pl: Polylines) -> list[bytes]:
    """One key per polyline, the same whichever way the polyline runs."""
    keys = []
    for s in range(len(pl)):
        p = pl.points[pl.offsets[s]:pl.offsets[s + 1]]
        keys.append(min(p.tobytes(), np.ascontiguousarray(p[::-1]).tobytes()))
    return keys


def _majority_partner(src: np.ndarray, dst: np.ndarray, n_src: int, n_dst: int) -> np.ndarray:
    """(n_src,) for each source polyline the destination polyline most of its samples are
    nearest to (-1 when it has none)."""
    partner = np.full(n_src, -1, np.int64)
    if len(src) == 0:
        return partner
    key, cnt = np.unique(src.astype(np.int64) * n_dst + dst, return_counts=True)
    s, d = key // n_dst, key % n_dst
    order = np.lexsort((-cnt, s))
    s, d = s[order], d[order]
    first = np.r_[True, s[1:] != s[:-1]]
    partner[s[first]] = d[first]
    return partner


def _regions(kind: str, side: str, smp: _Samples, dist: np.ndarray, unmatched: np.ndarray, ids: tuple,
             gap: float) -> tuple[list[Region], np.ndarray, np.ndarray]:
    """Group the unmatched samples into regions: runs of consecutive unmatched samples of a
    polyline, joined when they come within `gap` px of each other. Returns the regions (largest
    first), the unmatched sample positions (U, 2) and their run numbers (U,) for drawing."""
    u = np.flatnonzero(unmatched)
    if len(u) == 0:
        return [], np.zeros((0, 2)), np.zeros(0, np.int64)
    st = smp.stroke[u]
    start = np.r_[True, (np.diff(u) != 1) | (st[1:] != st[:-1])]
    run = np.cumsum(start) - 1
    run_first = np.flatnonzero(start)
    in_run = np.arange(len(u)) - run_first[run]
    end = np.r_[start[1:], True]
    # keep samples about gap/2 apart along each run: enough to join runs that come within gap
    every = max(1, int(0.5 * gap / smp.step))
    keep = np.flatnonzero((in_run % every == 0) | end)
    sub = smp.pos[u[keep]]
    pairs = cKDTree(sub).query_pairs(gap, output_type="ndarray")
    # consecutive kept samples of a run are joined too (they are at most gap/2 apart along the arc)
    same_run = np.flatnonzero(run[keep][1:] == run[keep][:-1])
    i = np.r_[pairs[:, 0], same_run]
    j = np.r_[pairs[:, 1], same_run + 1]
    graph = coo_matrix((np.ones(len(i)), (i, j)), shape=(len(sub), len(sub)))
    _, comp_sub = connected_components(graph, directed=False)
    kept_run_first = np.searchsorted(keep, run_first)  # the first sample of every run is kept
    comp = comp_sub[kept_run_first][run]
    order = np.argsort(comp, kind="stable")
    cs = comp[order]
    bounds = np.flatnonzero(np.r_[True, cs[1:] != cs[:-1]])
    pos = smp.pos[u][order]
    w = smp.weight[u][order]
    dd = dist[u][order]
    sto = st[order]
    regions = []
    x0 = np.minimum.reduceat(pos[:, 0], bounds)
    y0 = np.minimum.reduceat(pos[:, 1], bounds)
    x1 = np.maximum.reduceat(pos[:, 0], bounds)
    y1 = np.maximum.reduceat(pos[:, 1], bounds)
    length = np.add.reduceat(w, bounds)
    dev = np.maximum.reduceat(dd, bounds)
    ends = np.r_[bounds[1:], len(cs)]
    for r, (b0, b1) in enumerate(zip(bounds, ends)):
        strokes = np.unique(sto[b0:b1])
        rid = tuple(dict.fromkeys(ids[s] for s in strokes))
        regions.append(Region(kind, side, (float(x0[r]), float(y0[r]), float(x1[r]), float(y1[r])),
                              float(length[r]), float(dev[r]) if np.isfinite(dev[r]) else None, rid))
    regions.sort(key=lambda g: -g.length)
    return regions, smp.pos[u], run


def diff_polylines(kind: str, pa: Polylines, pb: Polylines, tol: float) -> KindDiff:
    """Compare the strokes of one kind. tol in px. See the module docstring for the test."""
    tol = _check_tol(tol)
    la, lb = pa.length, pb.length
    kd = KindDiff(kind, len(pa), len(pb), la, lb)
    kd._draw = {"a": pa, "b": pb, "a_only": (np.zeros((0, 2)), np.zeros(0, np.int64)),
                "b_only": (np.zeros((0, 2)), np.zeros(0, np.int64))}
    if len(pa) == 0 and len(pb) == 0:
        kd.identical = True
        return kd
    # Identical geometry (whatever the order, direction and ids): no sampling needed.
    ka, kb = _canonical_keys(pa), _canonical_keys(pb)
    if sorted(ka) == sorted(kb):
        kd.identical = True
        oa = sorted(range(len(pa)), key=lambda s: (ka[s], str(pa.ids[s])))
        ob = sorted(range(len(pb)), key=lambda s: (kb[s], str(pb.ids[s])))
        kd.renamed = [(pa.ids[i], pb.ids[j]) for i, j in zip(oa, ob)
                      if pa.ids[i] != pb.ids[j] and pa.ids[i] is not None and pb.ids[j] is not None]
        return kd

    step = 0.5 * tol
    for side, pl in (("A", pa), ("B", pb)):
        n = _count_samples(pl, step)
        if n > MAX_SAMPLES:
            need = 2.2 * pl.length / MAX_SAMPLES
            raise UsageError(f"tolerance {tol:g} px is too fine for the {pl.length:.0f} px of {kind} strokes in {side} "
                             f"({n} samples); use a tolerance of at least {need:.2g} px")
    sa = _resample(pa, step) if len(pa) else None
    sb = _resample(pb, step) if len(pb) else None
    piece = max(0.5, tol)
    if sa is not None and sb is not None:
        da, na = _NearestStroke(pb, piece).query(sa.pos, tol)
        db, nb = _NearestStroke(pa, piece).query(sb.pos, tol)
    else:
        da = np.full(len(sa.pos), np.inf) if sa is not None else None
        db = np.full(len(sb.pos), np.inf) if sb is not None else None
    gap = max(2.0, 4.0 * tol)
    devs = []
    for side, smp, dist, pl in (("a", sa, da, pa), ("b", sb, db, pb)):
        if smp is None:
            continue
        unmatched = dist > tol + _EPS
        regions, upos, urun = _regions(kind, side, smp, dist, unmatched, pl.ids, gap)
        kd.regions += regions
        kd._draw[f"{side}_only"] = (upos, urun)
        setattr(kd, f"{side}_only_length", float(smp.weight[unmatched].sum()))
        devs.append(float(dist.max()) if len(dist) else 0.0)
        if unmatched.any():
            kd.equal = False
    kd.max_deviation = max(devs) if devs and all(math.isfinite(d) for d in devs) else None
    kd.regions.sort(key=lambda g: -g.length)
    if sa is not None and sb is not None:
        # ids on strokes that match one to one (all of each within tol of the other, mutual partners)
        ma, mb = da <= tol + _EPS, db <= tol + _EPS
        pa_of = _majority_partner(sa.stroke[ma], na[ma], len(pa), len(pb))
        pb_of = _majority_partner(sb.stroke[mb], nb[mb], len(pb), len(pa))
        full_a = np.bincount(sa.stroke[~ma], minlength=len(pa)) == 0
        full_b = np.bincount(sb.stroke[~mb], minlength=len(pb)) == 0
        for i in np.flatnonzero(full_a & (pa_of >= 0)):
            j = pa_of[i]
            if full_b[j] and pb_of[j] == i and pa.ids[i] != pb.ids[j] and None not in (pa.ids[i], pb.ids[j]):
                kd.renamed.append((pa.ids[i], pb.ids[j]))
    return kd


def diff_drawings(a: SvgDrawing, b: SvgDrawing, tol: float = 0.05) -> DiffResult:
    """Compare two read drawings kind by kind (kinds in A's order, then B's new ones)."""
    tol = _check_tol(tol)
    empty = Polylines.from_list([], [])
    kinds = list(dict.fromkeys([*a.layers, *b.layers]))
    out = {k: diff_polylines(k, a.layers.get(k, empty), b.layers.get(k, empty), tol) for k in kinds}
    return DiffResult(a.path, b.path, tol, out, a.viewbox, b.viewbox, a.styles, b.styles)


def diff_svgs(path_a: str | Path, path_b: str | Path, tol: float = 0.05, *, png: str | Path | None = None,
              png_scale: float = 1.0) -> DiffResult:
    """Compare the stroke geometry of two SVG files within tol px. With `png`, also draw the
    difference there (see write_diff_png)."""
    tol = _check_tol(tol)
    res = diff_drawings(read_svg(path_a), read_svg(path_b), tol)
    if png is not None:
        write_diff_png(res, png, scale=png_scale)
    return res


def _svg_files(root: Path) -> dict[str, Path]:
    return {f.relative_to(root).as_posix(): f for f in sorted(root.rglob("*.svg")) if f.is_file()}


def diff_dirs(dir_a: str | Path, dir_b: str | Path, tol: float = 0.05, *, png_dir: str | Path | None = None,
              png_scale: float = 1.0) -> DirDiffResult:
    """Compare two folders of SVG files (searched recursively) paired by relative path. A is the
    reference: files only in A are `missing`, files only in B `extra`. With `png_dir`, a difference
    image `<name>.png` is written there for every pair that differs."""
    tol = _check_tol(tol)
    ra, rb = Path(dir_a), Path(dir_b)
    for r in (ra, rb):
        if not r.is_dir():
            # (a path that is not there is the command's fault, exit 2: told apart from a difference)
            raise (UsageError("no such folder", path=r) if not r.exists() else InputError("is not a folder", path=r))
    fa, fb = _svg_files(ra), _svg_files(rb)
    if not fa and not fb:
        raise UsageError(f"no SVG files in either folder ({ra} and {rb}): nothing to compare")
    files: dict[str, DiffResult] = {}
    pngs = []
    for name in sorted(fa.keys() & fb.keys()):
        res = diff_svgs(fa[name], fb[name], tol)
        if png_dir is not None and not res.equal:
            target = Path(png_dir) / (name[:-4] + ".png")
            write_diff_png(res, target, scale=png_scale)
            pngs.append(str(target))
        for k in res.kinds.values():  # the geometry is not needed any more: keep memory flat
            k._draw = None
        files[name] = res
    return DirDiffResult(str(ra), str(rb), tol, files, sorted(fa.keys() - fb.keys()), sorted(fb.keys() - fa.keys()),
                         pngs)


def diff_paths(a: str | Path, b: str | Path, tol: float = 0.05, *, png: str | Path | None = None,
               png_scale: float = 1.0) -> DiffResult | DirDiffResult:
    """diff_svgs for two files, diff_dirs for two folders (png is then a folder of images).
    UsageError when one is a file and the other a folder."""
    pa, pb = Path(a), Path(b)
    for p in (pa, pb):
        if not p.exists():  # (exit 2: a CI job tells a missing golden folder from a difference)
            raise UsageError("no such file or folder", path=p)
    if pa.is_dir() != pb.is_dir():
        d, f = (pa, pb) if pa.is_dir() else (pb, pa)
        raise UsageError(f"cannot compare a folder with a file: {d} is a folder, {f} is a file")
    if pa.is_dir():
        return diff_dirs(pa, pb, tol, png_dir=png, png_scale=png_scale)
    return diff_svgs(pa, pb, tol, png=png, png_scale=png_scale)


def assert_same_drawing(a: str | Path, b: str | Path, tol: float = 0.05, *,
                        png: str | Path | None = None) -> DiffResult | DirDiffResult:
    """For tests against golden files: raise AssertionError with the human summary when the two
    SVG files (or folders) differ within tol px; return the result otherwise."""
    res = diff_paths(a, b, tol, png=png)
    if not res.equal:
        raise AssertionError(res.summary())
    return res


# ----------------------------------------------------------------------------------------------
# Difference image
# ----------------------------------------------------------------------------------------------

#: Largest difference image side in px.
MAX_PNG_SIDE = 16384


def diff_image_frame(result: DiffResult) -> tuple[float, float, float, float]:
    """(x0, y0, w, h) px of the drawing area: the union of both viewBoxes, else the geometry's
    bounds with a margin."""
    boxes = [v for v in (result.viewbox_a, result.viewbox_b) if v]
    if boxes:
        x0 = min(v[0] for v in boxes)
        y0 = min(v[1] for v in boxes)
        return x0, y0, max(v[0] + v[2] for v in boxes) - x0, max(v[1] + v[3] for v in boxes) - y0
    pts = [k._draw[s].points for k in result.kinds.values() if k._draw for s in ("a", "b") if len(k._draw[s].points)]
    if not pts:
        return 0.0, 0.0, 1.0, 1.0
    allp = np.concatenate(pts)
    lo, hi = allp.min(0) - 10.0, allp.max(0) + 10.0
    return float(lo[0]), float(lo[1]), float(hi[0] - lo[0]), float(hi[1] - lo[1])


def write_diff_png(result: DiffResult, path: str | Path, *, scale: float = 1.0) -> Path:
    """Draw the difference of a DiffResult as a PNG (RGB): strokes common to both drawings in
    COMMON_COLOR, parts only in A in A_ONLY_COLOR, parts only in B in B_ONLY_COLOR, each differing
    region framed faintly. Image size = viewBox size x scale (px). Written atomically."""
    from PIL import Image, ImageDraw

    if any(k._draw is None for k in result.kinds.values()):
        raise UsageError("this diff result no longer holds its geometry (diff_dirs drops it); draw with diff_svgs")
    if not (math.isfinite(scale) and scale > 0):
        raise UsageError(f"PNG scale must be positive, got {scale!r}")
    x0, y0, w, h = diff_image_frame(result)
    W, H = max(1, math.ceil(w * scale)), max(1, math.ceil(h * scale))
    if max(W, H) > MAX_PNG_SIDE:
        raise UsageError(f"difference image would be {W} x {H} px; lower the PNG scale")
    img = Image.new("RGB", (W, H), BACKGROUND_COLOR)
    draw = ImageDraw.Draw(img)
    thin = max(1, round(scale))
    thick = max(2, round(2 * scale))

    def xy(p: np.ndarray) -> list[float]:
        return ((p - (x0, y0)) * scale).ravel().tolist()

    def polyline(p: np.ndarray, color, width):
        if len(p) == 1 or np.all(p == p[0]):
            cx, cy = xy(p[:1])
            r = width / 2
            draw.ellipse([cx - r, cy - r, cx + r, cy + r], fill=color)
        else:
            draw.line(xy(p), fill=color, width=width, joint="curve")

    pad = 3
    for k in result.kinds.values():
        for r in k.regions:
            bx0, by0, bx1, by1 = r.bbox
            draw.rectangle([(bx0 - x0) * scale - pad, (by0 - y0) * scale - pad,
                            (bx1 - x0) * scale + pad, (by1 - y0) * scale + pad],
                           outline=A_REGION_COLOR if r.side == "a" else B_REGION_COLOR)
    for k in result.kinds.values():
        for s in ("a", "b"):
            pl = k._draw[s]
            for i in range(len(pl)):
                polyline(pl.points[pl.offsets[i]:pl.offsets[i + 1]], COMMON_COLOR, thin)
    for key, color in (("a_only", A_ONLY_COLOR), ("b_only", B_ONLY_COLOR)):
        for k in result.kinds.values():
            pos, run = k._draw[key]
            if not len(pos):
                continue
            for part in np.split(pos, np.flatnonzero(np.diff(run)) + 1):
                polyline(part, color, thick)
    buf = io.BytesIO()
    img.save(buf, format="PNG")
    try:
        return atomic_write_bytes(path, buf.getvalue())
    except OSError as e:
        raise InputError(f"cannot write the difference image: {e.strerror or e}", path=path) from None
