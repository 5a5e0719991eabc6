"""The data passed between stages: small frozen dataclasses of numpy arrays.

scene -> FeatureEdges (per frame) -> VisibleRuns -> Strokes -> (tracked) Strokes -> writers.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np

from strokekit.kinds import KIND_INDEX, KINDS, MAX_OCCLUSION, N_KINDS, layer_name  # noqa: F401 (the model's names)

if TYPE_CHECKING:  # the model holds a frame's Camera; the camera stage imports the model's KINDS nowhere
    from strokekit.camera.view import Camera
    from strokekit.scene.motion import ScenePose



def kind_of(code) -> np.ndarray:
    """The line kind (index into KINDS) of kind codes (see MAX_OCCLUSION)."""
    return np.asarray(code) % N_KINDS


def occlusion_of(code) -> np.ndarray:
    """The occlusion level of kind codes: 0 visible, n hidden by n surfaces."""
    return np.asarray(code) // N_KINDS


try:  # the clip ufunc itself: np.clip(a, lo, hi) with both bounds given is this call, behind ~1 us
    from numpy._core.umath import clip as uclip  # of Python-level wrapping (numpy >= 2)
except ImportError:  # pragma: no cover
    from numpy.core.umath import clip as uclip


def bracket(G: np.ndarray, r: np.ndarray, first: np.ndarray, last: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(i, j) point indices of the segment i -> j holding each global arc position (see
    Strokes.global_arc), given r = G.searchsorted(position, side="right") and the first and last
    point index of the position's stroke; clamped to the stroke's segments (a one-point stroke
    has none: there j is first + 1, within the arrays, and callers that can meet one handle it)."""
    j = uclip(r, first + 1, np.maximum(last, first + 1))
    j = np.minimum(j, len(G) - 1)
    return np.maximum(j - 1, first), j


def row_norm(x: np.ndarray) -> np.ndarray:
    """np.linalg.norm(x, axis=1) of an (N, 2) or (N, 3) float64 array, the same bits
    (sqrt((x0 x0 + x1 x1) + x2 x2), the order of numpy's reduction) without the generic
    reduction machinery (its overhead dominates on short rows)."""
    x = np.asarray(x)
    if x.ndim == 2 and x.dtype == np.float64 and x.shape[1] in (2, 3):
        s = x[:, 0] * x[:, 0] + x[:, 1] * x[:, 1]
        if x.shape[1] == 3:
            s += x[:, 2] * x[:, 2]
        return np.sqrt(s)
    return np.linalg.norm(x, axis=1)


@dataclass(frozen=True, eq=False)
class FeatureEdges:
    """Candidate feature segments of one frame, in world space.

    a, b (N, 3) float64 endpoints; kind (N,) int8 into KINDS; va, vb (N,) int64 mesh vertex ids of
    a and b (-1 where the endpoint is not a mesh vertex, e.g. inside a face); face (N,) int64 the
    face the segment lies on (for surface lookups). va/vb are chaining keys: two segments chain
    where they share a key, so points on a mesh edge (not a vertex) should use V + edge index.
    lift (N, 3) or None: a world-space offset added to the occlusion ray origin of every sample of
    the segment (for lines inside faces, whose rays would graze the surface); zero when None."""

    a: np.ndarray
    b: np.ndarray
    kind: np.ndarray
    va: np.ndarray
    vb: np.ndarray
    face: np.ndarray
    lift: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.a)

    @staticmethod
    def empty() -> "FeatureEdges":
        z3 = np.zeros((0, 3))
        zi = np.zeros(0, np.int64)
        return FeatureEdges(z3, z3, np.zeros(0, np.int8), zi, zi, zi)

    @staticmethod
    def concat(parts: list["FeatureEdges"]) -> "FeatureEdges":
        parts = [p for p in parts if len(p)]
        if not parts:
            return FeatureEdges.empty()
        lift = None
        if any(p.lift is not None for p in parts):
            lift = np.concatenate([p.lift if p.lift is not None else np.zeros((len(p), 3)) for p in parts])
        return FeatureEdges(*(np.concatenate([getattr(p, n) for p in parts])
                              for n in ("a", "b", "kind", "va", "vb", "face")), lift=lift)


@dataclass(frozen=True, eq=False)
class VisibleRuns:
    """Visible pieces of feature segments. For run r: segment index `edge[r]` into the frame's
    FeatureEdges, world endpoints X0, X1 (R, 3), pixel endpoints p0, p1 (R, 2), and chaining keys
    key0, key1 (R,): the mesh vertex id where the run ends on a mesh vertex, else a unique
    negative number (so the chain cannot continue there)."""

    edge: np.ndarray
    X0: np.ndarray
    X1: np.ndarray
    p0: np.ndarray
    p1: np.ndarray
    key0: np.ndarray
    key1: np.ndarray
    kind: np.ndarray
    face: np.ndarray

    def __len__(self) -> int:
        return len(self.edge)

    @property
    def length_px(self) -> np.ndarray:
        return row_norm(self.p1 - self.p0)


@dataclass(frozen=True, eq=False)
class Strokes:
    """The strokes of one frame as flat arrays.

    points (N, 2) pixels; surface (N, 3) world points the 2D points came from; face (N,) the mesh
    face under each point (-1 unknown); u (N,) parametrization in texture periods; offsets (S+1,)
    so that stroke s is points[offsets[s]:offsets[s+1]]; kind (S,) int8 into KINDS; ids (S,)
    persistent stroke ids; level, level_weight (S,) self-similar texture octave and blend weight.
    pose: where the scene's objects were in this frame (None: a still scene), so that a surface
    point can be carried with its object (carry_points)."""

    points: np.ndarray
    surface: np.ndarray
    face: np.ndarray
    offsets: np.ndarray
    kind: np.ndarray
    ids: np.ndarray
    u: np.ndarray
    level: np.ndarray
    level_weight: np.ndarray
    camera: Camera | None = None
    frame: int = 0
    period_px: float = 30.0
    pose: ScenePose | RecordedPose | None = None

    def __len__(self) -> int:
        return len(self.offsets) - 1

    @cached_property
    def segment_lengths(self) -> np.ndarray:
        """(N,) length in px of the segment ending at each point (0 at each stroke's first point)."""
        d = np.zeros(len(self.points))
        if len(self.points) > 1:
            P = np.asarray(self.points)
            d[1:] = row_norm(P[1:] - P[:-1])  # (np.diff's values, without its wrapping)
        d[self.offsets[:-1]] = 0.0
        return d

    @cached_property
    def arc_length(self) -> np.ndarray:
        """(N,) cumulative arc length in px from each stroke's start."""
        c = self.segment_lengths.cumsum()
        o = self.offsets
        return c - c[o[:-1]].repeat(o[1:] - o[:-1])

    @cached_property
    def lengths(self) -> np.ndarray:
        """(S,) stroke lengths in px."""
        if len(self) == 0:
            return np.zeros(0)
        return self.arc_length[self.offsets[1:] - 1]

    @cached_property
    def global_arc(self) -> tuple[np.ndarray, np.ndarray]:
        """(base (S,), G (N,)): one strictly increasing arc coordinate over all strokes, stroke s
        starting at base[s] with a 1 px gap between strokes (a search for a position on one
        stroke never lands on another); G is each point's arc_length + its stroke's base."""
        L, o = self.lengths, self.offsets
        base = np.concatenate(((0.0,), (L[:-1] + 1.0).cumsum()))
        return base, self.arc_length + base.repeat(o[1:] - o[:-1])

    @cached_property
    def stroke_of_point(self) -> np.ndarray:
        o = self.offsets
        return np.arange(len(self)).repeat(o[1:] - o[:-1])

    def stroke(self, s: int) -> slice:
        return slice(int(self.offsets[s]), int(self.offsets[s + 1]))

    @property
    def occlusion(self) -> np.ndarray:
        """(S,) occlusion level of each stroke: 0 visible, n hidden by n surfaces (from its kind
        code, see MAX_OCCLUSION)."""
        return occlusion_of(self.kind).astype(np.int64)

    def replace(self, **changes) -> "Strokes":
        """dataclasses.replace that keeps the cached arc lengths (and stroke_of_point) when the new
        strokes share this one's points (and offsets) arrays: they would be recomputed identically,
        and tracking replaces strokes a dozen times a frame. The fields are copied into a new
        instance directly (Strokes has no __post_init__), which is what replace's call of __init__
        amounts to, at a quarter of its cost."""
        if not changes.keys() <= _STROKES_FIELD_SET:
            return replace(self, **changes)  # (its error)
        old = self.__dict__
        out = object.__new__(Strokes)
        new = out.__dict__
        for k in _STROKES_FIELDS:
            new[k] = changes[k] if k in changes else old[k]
        if new["offsets"] is old["offsets"]:
            if "stroke_of_point" in old:
                new["stroke_of_point"] = old["stroke_of_point"]
            if new["points"] is old["points"]:
                for k in _GEOMETRY_CACHE:
                    if k in old:
                        new[k] = old[k]
        return out

    def select(self, mask: np.ndarray) -> "Strokes":
        """The strokes where mask (S,) is true, in order."""
        mask = np.asarray(mask, bool)
        n = np.diff(self.offsets)
        counts = n[mask]
        # take(axis=0) of the points kept: a boolean mask over (N, 2) rows is ~4x slower (same values)
        pm = np.flatnonzero(np.repeat(mask, n))
        return replace(self, points=self.points.take(pm, axis=0), surface=self.surface.take(pm, axis=0),
                       face=self.face.take(pm), u=self.u.take(pm),
                       offsets=np.concatenate(((0,), np.cumsum(counts))).astype(np.int64), kind=self.kind[mask],
                       ids=self.ids[mask], level=self.level[mask], level_weight=self.level_weight[mask])

    @staticmethod
    def build(points, surface, face, offsets, kind, *, ids=None, u=None, camera=None, frame=0,
              period_px=30.0) -> "Strokes":
        """Strokes with default ids (0..S-1), u = arc length / period and level 0."""
        offsets = np.asarray(offsets, np.int64)
        n_s = len(offsets) - 1
        s = Strokes(points=np.asarray(points, float).reshape(-1, 2), surface=np.asarray(surface, float).reshape(-1, 3),
                    face=np.asarray(face, np.int64), offsets=offsets, kind=np.asarray(kind, np.int8),
                    ids=np.arange(n_s, dtype=np.int64) if ids is None else np.asarray(ids, np.int64),
                    u=np.zeros(len(points)) if u is None else np.asarray(u, float),
                    level=np.zeros(n_s), level_weight=np.ones(n_s), camera=camera, frame=frame,
                    period_px=period_px)
        if u is None:
            s = replace(s, u=s.arc_length / period_px)
        return s

    @staticmethod
    def empty(camera=None, frame=0, period_px=30.0) -> "Strokes":
        return Strokes.build(np.zeros((0, 2)), np.zeros((0, 3)), np.zeros(0), [0], np.zeros(0),
                             camera=camera, frame=frame, period_px=period_px)

    @staticmethod
    def concat(parts: list["Strokes"]) -> "Strokes":
        """Join the strokes of several parts of one frame (ids are kept as they are)."""
        parts = [p for p in parts if len(p)] or parts[:1]
        counts = np.concatenate([np.diff(p.offsets) for p in parts])
        first = parts[0]
        return replace(first, points=np.concatenate([p.points for p in parts]),
                       surface=np.concatenate([p.surface for p in parts]),
                       face=np.concatenate([p.face for p in parts]), u=np.concatenate([p.u for p in parts]),
                       offsets=np.r_[0, np.cumsum(counts)].astype(np.int64),
                       kind=np.concatenate([p.kind for p in parts]), ids=np.concatenate([p.ids for p in parts]),
                       level=np.concatenate([p.level for p in parts]),
                       level_weight=np.concatenate([p.level_weight for p in parts]))


@dataclass(frozen=True, eq=False)
class BrushPaths:
    """The brush paths of one frame (strokekit.paths) beside the frame's exact lines.

    strokes: the paths, drawn instead of the lines with `--strokes brush` (persistent ids, u,
    level, surface points, as tracked lines have). lines: the frame's exact lines, as the line pass
    made them. Covers: what each path stands for, as intervals of the lines: path s covers
    cover_line[k] from arc length cover_s0[k] to cover_s1[k] (px) for k in
    cover_offsets[s]:cover_offsets[s + 1]; cover_drawn[k] is True where the path draws that
    piece itself, False where the piece runs beside the path within the cover radius (a
    shingle of the mesh contour the path stands for). held: new paths held back this frame (not
    drawn, no covers; see PathOptions.hold_px), carried to the next frame beside `strokes`."""

    strokes: Strokes
    lines: Strokes
    cover_offsets: np.ndarray
    cover_line: np.ndarray
    cover_s0: np.ndarray
    cover_s1: np.ndarray
    cover_drawn: np.ndarray
    held: Strokes | None = None

    def __len__(self) -> int:
        return len(self.strokes)

    def covers(self, s: int) -> list[tuple[int, float, float, bool]]:
        """(line, s0, s1, drawn) of every line piece path s covers."""
        k = slice(int(self.cover_offsets[s]), int(self.cover_offsets[s + 1]))
        return list(zip(self.cover_line[k].tolist(), self.cover_s0[k].tolist(), self.cover_s1[k].tolist(),
                        self.cover_drawn[k].tolist()))


#: Cached properties that depend only on points and offsets (see Strokes.replace).
_GEOMETRY_CACHE = ("segment_lengths", "arc_length", "lengths", "global_arc")
_STROKES_FIELDS = tuple(f.name for f in fields(Strokes))  # (in order: the same __dict__ as __init__ makes)
_STROKES_FIELD_SET = frozenset(_STROKES_FIELDS)


@dataclass(frozen=True)
class BandRegion:
    """One band of one material as polygons: rings (K, 2) px (closed: the last point repeats the
    first), outer boundaries and holes alike (even-odd fill); colour (3,) its ramp colour, linear."""

    material: int
    band: int
    rings: list
    colour: np.ndarray


@dataclass(frozen=True, eq=False)
class CryptoLayer:
    """One Cryptomatte type of a frame (e.g. "CryptoObject"): per pixel the ids (H, W, R) float32
    and coverages (H, W, R) float32 of its R ranks, highest coverage first, and every name the
    scene has of that type (the manifest)."""

    type_name: str
    ids: np.ndarray
    coverage: np.ndarray
    names: tuple[str, ...]


@dataclass(frozen=True, eq=False)
class RasterPasses:
    """A frame's compositing passes at output resolution H x W, each None when not asked for.

    depth (H, W) float32 view depth in scene units (BACKGROUND_DEPTH where nothing is hit);
    normal (H, W, 3) float32 view-space unit normal (x right, y up, z toward the camera; 0 on
    background); shade (H, W, 4) float32 linear colour premultiplied by its alpha (coverage);
    bands (H, W) float32 band label (0 background); crypto: the Cryptomatte layers; lines:
    {kind: (H, W) float32 coverage of that kind's strokes}, in layer order."""

    width: int
    height: int
    depth: np.ndarray | None = None
    normal: np.ndarray | None = None
    shade: np.ndarray | None = None
    bands: np.ndarray | None = None
    crypto: tuple[CryptoLayer, ...] = ()
    lines: dict | None = None


#: View depth of background pixels in depth passes: what Blender's Cycles and Eevee write there.
BACKGROUND_DEPTH = 1e10


@dataclass(frozen=True, eq=False)
class RecordedPose:
    """A frame's pose as its JSON recorded it (read back: writers.strokes_json; a posed scene's
    own is strokekit.scene.motion.ScenePose, and carry_points takes either): each object's
    world matrix (O, 4, 4) and whether it deforms, and the frame's own stroke points' objects
    (N,) and object points (N, 3). It moves rigid objects' points only: a deforming object's
    points need the scene (their world point is kept)."""

    matrix: np.ndarray
    deforms: np.ndarray
    obj: np.ndarray
    local: np.ndarray
    time: float | None = None

    @staticmethod
    def from_json(head: dict, obj: np.ndarray, local: np.ndarray) -> "RecordedPose":
        objects = head.get("objects") or []
        m = np.array([o["matrix"] for o in objects], float).reshape(-1, 4, 4)
        return RecordedPose(m, np.array([bool(o.get("deforms")) for o in objects], bool), obj, local,
                            head.get("time"))

    def input_faces(self, face: np.ndarray) -> np.ndarray:
        return np.asarray(face, np.int64)

    def object_points(self, X: np.ndarray, face: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The recorded objects and object points of the frame's own points X."""
        if len(X) != len(self.obj):
            raise ValueError("a recorded pose knows the object points of its own frame's points only")
        return self.obj, self.local

    def world_points(self, obj: np.ndarray, local: np.ndarray, input_face: np.ndarray) -> np.ndarray:
        """World points of object points; NaN where the object deforms or is unknown."""
        obj = np.asarray(obj, np.int64)
        out = np.full((len(obj), 3), np.nan)
        rigid = (obj >= 0) & (obj < len(self.matrix))
        rigid[rigid] = ~self.deforms[obj[rigid]]
        M = self.matrix[obj[rigid]]
        out[rigid] = np.einsum("nij,nj->ni", M[:, :3, :3], np.asarray(local, float)[rigid]) + M[:, :3, 3]
        return out


def carry_points(X: np.ndarray, face: np.ndarray, src, dst) -> np.ndarray:
    """World points X (N, 3) on scene faces `face` of the scene posed by `src` (a ScenePose or
    RecordedPose), moved with their objects to where they are in the scene posed by `dst`. A
    scene at rest (None) does not move: X as it is, as for a point whose move is not known."""
    if src is None or dst is None or src is dst:
        return X
    obj, local = src.object_points(X, face)
    out = dst.world_points(obj, local, src.input_faces(face))
    unknown = ~np.isfinite(out).all(axis=1)
    if unknown.any():
        out[unknown] = np.asarray(X, float)[unknown]
    return out
