"""The stroke JSON of BRIEF 1.3, and its reader (used by the coherence metrics and diffs)."""

from __future__ import annotations

import numpy as np
import orjson

from ..camera import Camera
from ..model import KIND_INDEX, KINDS, Strokes


def round_list(x: np.ndarray, ndigits: int) -> list[float]:
    """[round(v, ndigits) for v in x.tolist()] without a Python call per value. Python rounds the
    exact binary value to decimal (half to even) and reads the decimal back; numpy's
    rint(x 10^n) / 10^n gives the same double wherever x 10^n is not within float64 rounding of
    a half (its error is below 1e-6 for |x 10^n| < 1e9). Values near a half, huge or not finite
    go through round()."""
    x = np.asarray(x, float)
    scale = 10.0 ** ndigits
    with np.errstate(invalid="ignore", over="ignore"):
        t = x * scale
        out = (np.rint(t) / scale).tolist()
        risky = ~((np.abs(np.abs(t - np.floor(t)) - 0.5) > 1e-6) & (np.abs(t) < 1e9))
    if risky.any():
        for i in np.flatnonzero(risky).tolist():
            out[i] = round(float(x[i]), ndigits)
    return out


def strokes_json(strokes: Strokes, width: int, height: int, frame: int, *, extra: dict | None = None) -> bytes:
    """JSON bytes: frame, size, camera and every stroke with points (px, 4 decimals), u, surface
    (world), face, length_px, self-similar level and weight. Deterministic."""
    pts = np.round(strokes.points, 4) + 0.0
    u = np.round(strokes.u, 5) + 0.0
    surface, face = strokes.surface, strokes.face
    off = strokes.offsets.tolist()
    lengths = round_list(strokes.lengths, 4)
    level, weight = round_list(strokes.level, 6), round_list(strokes.level_weight, 6)
    out = [{
        "id": i, "kind": KINDS[k],
        "points": pts[a:b], "u": u[a:b], "surface": surface[a:b], "face": face[a:b],
        "length_px": ln, "level": lv, "level_weight": w,
    } for i, k, a, b, ln, lv, w in zip(strokes.ids.tolist(), strokes.kind.tolist(), off[:-1], off[1:],
                                       lengths, level, weight)]
    doc = {"frame": int(frame), "width": int(width), "height": int(height),
           "camera": strokes.camera.to_json() if strokes.camera is not None else None,
           "period_px": strokes.period_px}
    if extra:
        doc.update(extra)
    doc["strokes"] = out
    return orjson.dumps(doc, option=orjson.OPT_SERIALIZE_NUMPY) + b"\n"


def read_strokes_json(path) -> Strokes:
    """Read a frame JSON back into Strokes (camera included)."""
    d = orjson.loads(open(path, "rb").read())
    ss = d["strokes"]
    counts = [len(s["points"]) for s in ss]
    offsets = np.r_[0, np.cumsum(counts)].astype(np.int64)

    def cat(key, dim):
        arrs = [np.asarray(s[key], float).reshape(-1, dim) if dim > 1 else np.asarray(s[key], float) for s in ss]
        if not arrs:
            return np.zeros((0, dim)) if dim > 1 else np.zeros(0)
        return np.concatenate(arrs)

    cam = None
    if d.get("camera"):
        c = dict(d["camera"])
        cam = Camera(**{k: (tuple(v) if isinstance(v, list) else v) for k, v in c.items()})
    st = Strokes(points=cat("points", 2), surface=cat("surface", 3),
                 face=np.asarray(cat("face", 1) if ss and "face" in ss[0] else np.full(offsets[-1], -1), np.int64),
                 offsets=offsets, kind=np.array([KIND_INDEX[s["kind"]] for s in ss], np.int8),
                 ids=np.array([s["id"] for s in ss], np.int64), u=cat("u", 1),
                 level=np.array([s.get("level", 0.0) for s in ss], float),
                 level_weight=np.array([s.get("level_weight", 1.0) for s in ss], float),
                 camera=cam, frame=int(d["frame"]), period_px=float(d.get("period_px", 30.0)))
    return st
