"""Temporal coherence metrics of BRIEF section 3, between the strokes of consecutive frames.

Every stroke is resampled at 1 px of arc length. A sample carries its stroke id, position p (px),
parameter u (texture periods), surface point X (world) and screen tangent t. Correspondence
between frames f-1 and f: X of frame f-1 is projected with frame f's camera and matched to the
nearest frame-f sample within `radius_px` (6) whose tangent agrees (|t.t'| >= `min_tangent_dot`,
0.65); the same is run from f to f-1. Silhouettes slide over the surface, so matching is done on
the screen position of the projected point, never on identical surface points.

- M1 id persistence: matched length whose id is the same in both frames / matched length.
- M2 popping: length without a match in the other frame (both directions) / both frames' length.
- M4 sliding: |u' - u| wrapped into (-1/2, 1/2], times the period P, in px (median, p95, max).
- M5 flatness: lambda = 1 / (P du/ds); length-weighted mean |log2 lambda| over a frame; a
  stretch counts for at most MAX_STRETCH_OCTAVES (10), which a frozen texture (constant u) gets.
  `flatness_raw` is that number on u as written. `flatness` is the same measure on the texture
  as drawn with the self-similar levels of Benard 2010 (Strokes.level, level_weight, convention
  of strokekit.tracking.ufit): octave k samples u * 2^-k, so its lambda is 2^k / (P du/ds); the
  blend of octaves level and level+1 is read at its continuous level
  c = level + 1 - level_weight. `flatness_blend` counts the two octaves apart with their
  weights instead (an upper bound: 1/3 octave on average even for a perfect level choice).
- M7 end growth: per id present in both frames, |L' - L| in px.
- M8 wholeness, one frame against the same frame drawn afresh (`--no-coherence`): path ends per
  1000 px drawn, 2 per open stroke, none for a loop (a stroke whose ends lie within LOOP_PX);
  over a sequence the tracked value, the fresh one and their ratio, each the median over the
  second half of the frames (where a tracker that only ever splits has crumbled).
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from strokekit.errors import InputError
from strokekit.fileio import check_pattern
from strokekit.model import Strokes, carry_points
from strokekit.sampling import MATCH_RADIUS_PX, MIN_TANGENT_DOT, Samples, match_samples, resample_strokes
from strokekit.writers.strokes_json import read_strokes_json


def _wrap(du: np.ndarray) -> np.ndarray:
    """Wrap a parameter difference into (-1/2, 1/2] (periodic texture)."""
    return -((-du + 0.5) % 1.0 - 0.5)


#: M5: the stretch counted for a texture stretched further, or frozen (constant u), in octaves.
MAX_STRETCH_OCTAVES = 10.0


def _flatness(strokes: Strokes, smp: Samples, mode: str) -> float:
    """Length-weighted mean |log2 lambda| of one frame (see module doc). mode "raw": u as
    written; "level": the self-similar texture at its continuous level c = level + 1 -
    level_weight (octave blend read as one texture of scale 2^c, as Benard 2010 designs it);
    "blend": the two blended octaves counted separately with their weights (an upper bound)."""
    if len(smp) < 2:
        return 0.0
    same = smp.stroke[1:] == smp.stroke[:-1]
    ds = 0.5 * (smp.w[1:] + smp.w[:-1])
    ok = same & (ds > 0)
    if not ok.any():
        return 0.0
    P = strokes.period_px
    ds = ds[ok]
    # A texture stretched beyond MAX_STRETCH_OCTAVES (constant u: frozen, lambda infinite)
    # counts as stretched by that much: left out, a stroke with constant u would score 0.
    du = np.maximum(np.abs(smp.u[1:] - smp.u[:-1])[ok], ds / (P * 2.0 ** MAX_STRETCH_OCTAVES))
    log_lam = -np.log2(P * du / ds)  # lambda = 1 / (P du/ds)
    w = ds
    if mode == "raw":
        return float(np.sum(w * np.abs(log_lam)) / np.sum(w))
    st = smp.stroke[1:][ok]
    lev = strokes.level[st]
    wt = np.clip(strokes.level_weight[st], 0.0, 1.0)
    # Octave k samples u 2^-k: lambda_k = 2^k lambda. Octave `level` has weight `level_weight`,
    # octave level + 1 the rest.
    if mode == "level":
        e = np.abs(log_lam + lev + 1 - wt)
    else:
        e = wt * np.abs(log_lam + lev) + (1 - wt) * np.abs(log_lam + lev + 1)
    return float(np.sum(w * e) / np.sum(w))


@dataclass
class PairMetrics:
    """Metrics of one frame pair (f-1, f). Lengths in px."""

    frame: int
    matched_px: float
    same_id_px: float
    unmatched_px: float
    total_px: float
    sliding_px: np.ndarray = field(repr=False)  # |wrapped du| * P of every matched sample
    growth_px: np.ndarray = field(repr=False)  # |L' - L| per persisting id
    flatness: float = 0.0  # of frame f, with self-similar levels
    flatness_raw: float = 0.0  # of frame f, u as written
    flatness_blend: float = 0.0  # of frame f, blended octaves counted apart
    prev_frame: int = -1  # the frame compared with (frame - 1 unless frames are missing)

    @property
    def m1(self) -> float:
        return self.same_id_px / self.matched_px if self.matched_px > 0 else 1.0

    @property
    def m2(self) -> float:
        return self.unmatched_px / self.total_px if self.total_px > 0 else 0.0

    def summary(self) -> dict:
        return {"frame": self.frame, "M1": self.m1, "M2": self.m2, **_stats("M4", self.sliding_px),
                "M5": self.flatness, "M5_raw": self.flatness_raw,
                "M5_blend": self.flatness_blend, **_stats("M7", self.growth_px),
                "matched_px": self.matched_px, "total_px": self.total_px}


def _stats(name: str, v: np.ndarray) -> dict:
    if len(v) == 0:
        return {f"{name}_median": 0.0, f"{name}_p95": 0.0, f"{name}_max": 0.0}
    return {f"{name}_median": float(np.median(v)), f"{name}_p95": float(np.percentile(v, 95)),
            f"{name}_max": float(np.max(v))}


def pair_metrics(prev: Strokes, cur: Strokes, *, radius_px: float = MATCH_RADIUS_PX,
                 min_tangent_dot: float = MIN_TANGENT_DOT, prev_samples: Samples | None = None,
                 cur_samples: Samples | None = None) -> PairMetrics:
    """BRIEF 3 metrics between the strokes of frame f-1 (`prev`) and frame f (`cur`). Both need
    their camera. The sliding uses cur.period_px. In a moving scene (the strokes' pose) each
    frame's surface points move with their objects to where they are in the other frame before
    they are projected with its camera (so the samples given are not used)."""
    if prev.camera is None or cur.camera is None:
        raise InputError("coherence metrics need the camera of both frames")
    if prev.pose is not None or cur.pose is not None:
        a = resample_strokes(prev, 1.0, surface=carry_points(prev.surface, prev.face, prev.pose, cur.pose))
        b = resample_strokes(cur, 1.0, surface=carry_points(cur.surface, cur.face, cur.pose, prev.pose))
    else:
        a = prev_samples if prev_samples is not None else resample_strokes(prev, 1.0)
        b = cur_samples if cur_samples is not None else resample_strokes(cur, 1.0)
    P = cur.period_px
    ta = cKDTree(a.p) if len(a) else None
    tb = cKDTree(b.p) if len(b) else None
    ab = match_samples(a, cur.camera, b, tb, radius_px=radius_px, min_tangent_dot=min_tangent_dot, exact=True)
    ba = match_samples(b, prev.camera, a, ta, radius_px=radius_px, min_tangent_dot=min_tangent_dot, exact=True)
    ma, mb = ab >= 0, ba >= 0
    matched = a.w[ma].sum() + b.w[mb].sum()
    same = a.w[ma][a.ids[ma] == b.ids[ab[ma]]].sum() + b.w[mb][b.ids[mb] == a.ids[ba[mb]]].sum()
    unmatched = a.w[~ma].sum() + b.w[~mb].sum()
    total = a.w.sum() + b.w.sum()
    slide = np.concatenate([np.abs(_wrap(b.u[ab[ma]] - a.u[ma])), np.abs(_wrap(b.u[mb] - a.u[ba[mb]]))]) * P
    common, ia, ib = np.intersect1d(prev.ids, cur.ids, return_indices=True)
    # Ids are unique per frame when tracked; with repeated ids compare the first occurrences.
    growth = np.abs(cur.lengths[ib] - prev.lengths[ia])
    return PairMetrics(frame=int(cur.frame), prev_frame=int(prev.frame), matched_px=float(matched), same_id_px=float(same),
                       unmatched_px=float(unmatched), total_px=float(total), sliding_px=slide, growth_px=growth,
                       flatness=_flatness(cur, b, "level"), flatness_raw=_flatness(cur, b, "raw"),
                       flatness_blend=_flatness(cur, b, "blend"))


def sequence_metrics(frames: list[Strokes], **kw) -> tuple[list[PairMetrics], dict]:
    """Metrics of every consecutive pair of `frames` (in order) and the overall summary:
    M1 over all matched length; M2 median and mean of the per-pair values; M4 and M7 median, p95
    and max over all pairs' samples; M5 mean and max over frames 2..n (with levels and raw)."""
    pairs = []
    prev_s = None
    for k in range(1, len(frames)):
        a = prev_s if prev_s is not None else resample_strokes(frames[k - 1], 1.0)
        b = resample_strokes(frames[k], 1.0)
        pairs.append(pair_metrics(frames[k - 1], frames[k], prev_samples=a, cur_samples=b, **kw))
        prev_s = b
    return pairs, overall(pairs)


def overall(pairs: list[PairMetrics]) -> dict:
    """Summary of a list of pair metrics (see sequence_metrics)."""
    if not pairs:
        return {"pairs": 0}
    matched = sum(p.matched_px for p in pairs)
    same = sum(p.same_id_px for p in pairs)
    m2 = np.array([p.m2 for p in pairs])
    fl = np.array([p.flatness for p in pairs])
    flr = np.array([p.flatness_raw for p in pairs])
    # (Nothing matched, e.g. no strokes at all: M1 is undefined, not perfect.)
    return {"pairs": len(pairs), "M1": same / matched if matched > 0 else float("nan"),
            "matched_px": float(matched), "total_px": float(sum(p.total_px for p in pairs)),
            "M2_median": float(np.median(m2)), "M2_mean": float(np.mean(m2)), "M2_max": float(np.max(m2)),
            **_stats("M4", np.concatenate([p.sliding_px for p in pairs])),
            "M5": float(np.mean(fl)), "M5_max": float(np.max(fl)),
            "M5_raw": float(np.mean(flr)), "M5_raw_max": float(np.max(flr)),
            "M5_blend": float(np.mean([p.flatness_blend for p in pairs])),
            **_stats("M7", np.concatenate([p.growth_px for p in pairs]))}


def frame_files(out_dir, pattern: str = "frame_{frame:04d}", at_least: int = 2) -> list[Path]:
    """The frame JSON files of a folder named by `pattern` (render --pattern), sorted by name; fewer
    than `at_least` is an InputError."""

    check_pattern(pattern)
    d = Path(out_dir)
    if not d.exists():
        raise InputError("folder not found", d)
    if not d.is_dir():
        raise InputError("not a folder", d)
    glob = re.sub(r"\{frame[^}]*\}", "*", pattern) + ".json"
    # Exactly the names the pattern gives: {frame} is a number that formats back to the name
    # (shot_{frame:04d} must not take shot_0001_draft.json, nor a report frame_report.json).
    literal = re.split(r"\{frame[^}]*\}", pattern)
    exact = re.compile("(.+?)".join(re.escape(s) for s in literal) + r"\.json")

    def named_by_pattern(name: str) -> bool:
        m = exact.fullmatch(name)
        if m is None or len(set(m.groups())) != 1:
            return False
        # Some whole number must format back to the name, in any integer format ({frame:x},
        # {frame:<4}, {frame:,}); a longer name of another render (_draft) has none.
        text = m.group(1)
        digits = re.sub(r"[^0-9a-fA-F]", "", text)
        tries = set()
        for base in (10, 16, 8, 2):
            for s in (text.strip().replace(",", "").replace("_", ""), digits):
                try:
                    tries.add(int(s, base))
                except ValueError:
                    pass
        tries |= {-x for x in tries}  # ("{frame:=+5}" and fill characters: the sign stands apart)
        if len(text) == 1:
            tries.add(ord(text))  # {frame:c}
        for n in tries:
            try:
                if pattern.format(frame=n) + ".json" == name:
                    return True
            except (ValueError, OverflowError):
                continue
        return False

    files = sorted(p for p in d.glob(glob) if named_by_pattern(p.name))  # (not render's .strokekit-run.json)
    if len(files) < at_least:
        hint = " (its frames have no JSON: render without --no-json)" if not files and any(d.glob(glob[:-5] + ".svg")) else ""
        need = f"needs at least {at_least} {glob} files to compare" if at_least > 1 else f"needs {glob} files"
        raise InputError(f"{need}, found {len(files)}{hint}", d)
    return files


def holds_brush_paths(out_dir, pattern: str = "frame_{frame:04d}") -> bool | None:
    """Whether the frames of a folder are brush paths (their JSON strokes list the lines they
    cover) rather than lines; None where no frame holds a stroke to tell."""
    for f in frame_files(out_dir, pattern, at_least=0):
        try:
            strokes = json.loads(f.read_text()).get("strokes") or []
        except (OSError, ValueError, AttributeError):
            continue  # (read_frames says what is wrong with it)
        if strokes and isinstance(strokes[0], dict):
            return "covers" in strokes[0]
    return None


def read_frames(out_dir, pattern: str = "frame_{frame:04d}", occlusion: tuple[int, int] | None = None,
                at_least: int = 2) -> list[Strokes]:
    """The strokes of every frame JSON of `out_dir` named by `pattern` (strokekit.writers.strokes_json
    format), in frame order. `occlusion` (lo, hi): only the strokes of those occlusion levels
    (hidden-line runs: 1-15 measures the hidden lines). `at_least`: see frame_files."""

    frames = []
    for f in frame_files(out_dir, pattern, at_least):
        try:
            st = read_strokes_json(f)
        except (KeyError, ValueError, TypeError) as e:
            raise InputError(f"not a strokekit frame JSON ({type(e).__name__}: {e})", f) from None
        if st.camera is None:
            raise InputError("frame JSON has no camera: cannot project surface points", f)
        if occlusion is not None:
            st = st.select((st.occlusion >= occlusion[0]) & (st.occlusion <= occlusion[1]))
        frames.append(st)
    frames.sort(key=lambda s: s.frame)
    return frames


def posed_frames(frames: list[Strokes], scene, animation: str | None = None, where=None) -> list[Strokes]:
    """Frames read back from their JSON (read_frames) with the poses of the scene they were drawn
    from, at each frame's time (its JSON's "time"): a deforming object's points then move with its
    mesh too (the JSON alone moves the rigid objects'). InputError for a frame without a time, or
    whose strokes do not lie on the scene so posed (another scene)."""
    m = scene.motion
    if m is None or not m.moves(m.animation(animation)):
        raise InputError("is not a moving scene: the frames' points need no scene to move", scene.source or None)
    ai = m.animation(animation)
    out = []
    for st in frames:
        if st.pose is None or getattr(st.pose, "time", None) is None:
            raise InputError(f"frame {st.frame} has no time: not a frame of a moving scene", where)
        posed = scene.at(st.pose.time, ai)
        if len(st.face) and (st.face.max() >= len(posed.faces)):
            raise InputError(f"frame {st.frame}'s strokes lie on faces the scene does not have: another scene",
                             where)
        out.append(st.replace(pose=posed.pose))
    return out


def folder_metrics(out_dir, pattern: str = "frame_{frame:04d}", occlusion: tuple[int, int] | None = None,
                   **kw) -> tuple[list[PairMetrics], dict]:
    """Read every frame JSON of `out_dir` named by `pattern` (read_frames) and return (per pair
    metrics, overall summary)."""
    return sequence_metrics(read_frames(out_dir, pattern, occlusion), **kw)


# --- M8 wholeness -----------------------------------------------------------------------------

#: M8: a stroke whose two ends lie within this many px of each other is a loop: it has no ends.
LOOP_PX = 0.5


def stroke_ends(strokes: Strokes) -> np.ndarray:
    """(S,) the ends of each stroke (BRIEF 3, M8): 2 for an open stroke, 0 for a loop (its first
    and last points within LOOP_PX; a stroke with no length is one too: it draws nothing)."""
    if len(strokes) == 0:
        return np.zeros(0, np.int64)
    off = strokes.offsets
    first, last = strokes.points[off[:-1]], strokes.points[np.maximum(off[1:] - 1, off[:-1])]
    gap = np.hypot(*(last - first).T)
    return np.where((off[1:] > off[:-1]) & (gap > LOOP_PX), 2, 0).astype(np.int64)


def ends_per_kpx(strokes: Strokes) -> float:
    """Path ends per 1000 px drawn of one frame (nan when nothing is drawn)."""
    L = float(strokes.lengths.sum()) if len(strokes) else 0.0
    return 1000.0 * float(stroke_ends(strokes).sum()) / L if L > 0 else float("nan")


def ends_ratio(tracked: float, fresh: float) -> float:
    """tracked / fresh ends per 1000 px: 1 where neither frame has an end (both loops only), inf
    where only the tracked one has ends, nan where either draws nothing."""
    if not (np.isfinite(tracked) and np.isfinite(fresh)):
        return float("nan")
    if fresh == 0:
        return 1.0 if tracked == 0 else float("inf")
    return tracked / fresh


@dataclass(frozen=True)
class FrameWholeness:
    """M8 of one frame: its ends, length drawn (px) and ends per 1000 px; with the same frame
    drawn afresh, that frame's ends per 1000 px and the ratio (nan without one)."""

    frame: int
    ends: int
    length_px: float
    ends_per_kpx: float
    fresh_ends_per_kpx: float = float("nan")
    ratio: float = float("nan")


def _same_view(a, b) -> bool:
    """Whether two cameras (read back from frame JSON, rounded there) show the same view."""
    return (a.projection == b.projection and a.width == b.width and a.height == b.height
            and np.allclose(a.eye, b.eye, rtol=1e-6, atol=1e-9) and np.allclose(a.target, b.target, rtol=1e-6, atol=1e-9)
            and np.isclose(a.fov_y, b.fov_y, rtol=1e-6) and np.isclose(a.ortho_height, b.ortho_height, rtol=1e-6))


def wholeness(frames: list[Strokes], fresh: list[Strokes] | None = None) -> tuple[list[FrameWholeness], dict]:
    """M8 of every frame of a sequence (in order) and its summary over the second half of the
    frames (frames[len // 2:], the late half): M8 (ends per 1000 px), M8_fresh and M8_ratio,
    each the median over the late frames that have them, and M8_frames, how many late frames the
    ratio was taken over. `fresh`: the same frames drawn afresh, matched by frame number (a frame
    missing there has no ratio); a fresh frame seen through another camera is an InputError."""
    by_frame = {int(f.frame): f for f in fresh} if fresh is not None else {}
    rows = []
    for st in frames:
        e = int(stroke_ends(st).sum())
        L = float(st.lengths.sum()) if len(st) else 0.0
        row = FrameWholeness(frame=int(st.frame), ends=e, length_px=L, ends_per_kpx=ends_per_kpx(st))
        other = by_frame.get(int(st.frame))
        if other is not None:
            if st.camera is not None and other.camera is not None and not _same_view(st.camera, other.camera):
                raise InputError(f"frame {st.frame} is seen through another camera than in the sequence "
                                 "measured: not the same frames drawn afresh")
            f8 = ends_per_kpx(other)
            row = replace(row, fresh_ends_per_kpx=f8, ratio=ends_ratio(row.ends_per_kpx, f8))
        rows.append(row)
    late = rows[len(rows) // 2:]

    def med(v):
        v = np.asarray([x for x in v if not np.isnan(x)], float)
        return float(np.median(v)) if len(v) else float("nan")

    ratios = [r.ratio for r in late]
    return rows, {"M8": med([r.ends_per_kpx for r in late]), "M8_fresh": med([r.fresh_ends_per_kpx for r in late]),
                  "M8_ratio": med(ratios), "M8_frames": int(sum(not np.isnan(x) for x in ratios)),
                  "M8_late_first": late[0].frame if late else -1}
