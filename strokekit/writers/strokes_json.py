"""The stroke JSON of BRIEF 1.3, and its reader (used by the coherence metrics and diffs)."""

from __future__ import annotations

from itertools import chain

import numpy as np
import orjson

from strokekit.camera.view import Camera
from strokekit.model import KIND_INDEX, KINDS, N_KINDS, BrushPaths, RecordedPose, Strokes
from strokekit.style.widths import StyledStrokes, apply_style


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


_STROKE = (b'{"id":%d,"kind":"%s","lineset":"%s","points":[%s],"width":[%s],"u":[%s],"surface":[%s],"face":[%s],'
           b'"length_px":%s,"level":%s,"level_weight":%s}')
_STROKE_OCCLUSION = _STROKE.replace(b'"kind":"%s",', b'"kind":"%s","occlusion":%d,')
#: With an along modifier, whether each end is joined to the next piece of its line (no head or
#: tail there: strokekit.style.joins), after the widths.
_JOINED = b'"width":[%s],"joined":[%d,%d],'
#: The lines a brush-path frame keeps beside its strokes are not drawn: no line set, no width.
_LINE = _STROKE.replace(b'"lineset":"%s",', b"").replace(b'"width":[%s],', b"")
_LINE_OCCLUSION = _STROKE_OCCLUSION.replace(b'"lineset":"%s",', b"").replace(b'"width":[%s],', b"")
#: A moving scene's strokes: each point's object and its point in the object's own frame too.
_POSED = (b'"face":[%s],', b'"face":[%s],"object":[%s],"local":[%s],')
_KIND_BYTES = [k.encode() for k in KINDS]
_KIND_BYTES_ARRAY = np.array(_KIND_BYTES, dtype=object)
_NP = orjson.OPT_SERIALIZE_NUMPY


def strokes_json(strokes: Strokes, width: int, height: int, frame: int, *, extra: dict | None = None,
                 paths: BrushPaths | None = None, styled: StyledStrokes | None = None,
                 layers: tuple[str, ...] = ()) -> bytes:
    """JSON bytes: frame, size, camera, the line sets drawn ("linesets": name, selection,
    colour, width, modifiers; "depth_range" when a depth modifier took the frame's) and every
    stroke drawn with its line set, points (px, 4 decimals), width (px at each point, 4
    decimals; with an along modifier, "joined": [start, end], 1 where the end meets the next
    piece of its line: no head or tail there), u, surface (world), face, length_px, self-similar
    level and weight.
    The default style (no line sets: Style.is_default) draws every stroke at one width in its
    kind's colour: its JSON has no "linesets", and its strokes no line set and no widths.
    Deterministic. A moving scene's strokes (strokes.pose) also give each point's object and its
    point in the object's own frame ("object", "local"; scene.motion.ScenePose.object_points).
    Hidden-line runs (`extra` holds "occlusion", the range of levels drawn; or a stroke is hidden)
    give each stroke its "occlusion" level after its kind (0: visible; "level" is the texture
    octave).

    styled: the strokes in their style (strokekit.style.apply_style: `strokes` is then not used);
    None: the default style (one set per layer of `layers`, and of any other kind drawn).

    `paths` (the frame's brush paths; `strokes` is then paths.strokes): every stroke also lists
    the line pieces it covers, `"covers": [[line id, s0, s1, drawn], ...]` (arc lengths along the
    line in px, 4 decimals; drawn 1 where the path draws the piece, 0 where the piece runs beside
    it), and the exact lines follow the strokes as `"lines"`, in the strokes' format.

    The bytes of orjson.dumps of the document (see _strokes_json_nested), built without a numpy
    view and an orjson array call per stroke and field (the costly part): orjson writes each
    per-point array of the frame once, the text is cut at the stroke starts and the strokes are
    assembled by one bytes %-operation."""
    if styled is None:
        styled = apply_style(strokes, layers)
    strokes = styled.strokes
    doc = {"frame": int(frame), "width": int(width), "height": int(height),
           "camera": strokes.camera.to_json() if strokes.camera is not None else None,
           "period_px": strokes.period_px}
    if extra:
        if {"strokes", "linesets"} & extra.keys() or (paths is not None and "lines" in extra):
            # the key would sit where extra puts it
            return _strokes_json_nested(styled, width, height, frame, extra=extra, paths=paths)
        doc.update(extra)
    doc.update(_sets_json(styled))
    doc["strokes"] = []
    head = orjson.dumps(doc, option=_NP)
    covers = _cover_texts(paths, styled.kept) if paths is not None else None
    body = _strokes_body(strokes, covers, _with_occlusion(strokes, extra), _said(styled))
    if body is None:  # unusual arrays (empty strokes, shapes that do not match): the plain way
        return _strokes_json_nested(styled, width, height, frame, extra=extra, paths=paths)
    if paths is None:
        return b"".join((head[:-2], body, b"]}\n")) if len(strokes) else head + b"\n"
    lines = _strokes_body(paths.lines, None, _with_occlusion(paths.lines, extra))
    if lines is None:
        return _strokes_json_nested(styled, width, height, frame, extra=extra, paths=paths)
    return b"".join((head[:-2], body, b'],"lines":[', lines, b"]}\n"))


def _said(styled: StyledStrokes) -> StyledStrokes | None:
    """The style the JSON writes out: None for the default one (module doc of strokes_json)."""
    return None if styled.style.is_default else styled


def _sets_json(styled: StyledStrokes) -> dict:
    """{"linesets": [...]} (the style's sets, with their colour: null where each kind is drawn in
    its own), and "depth_range" when a depth modifier took the frame's; {} for the default style."""
    if _said(styled) is None:
        return {}
    sets = [dict(s.to_json(styled.style), color=s.color) for s in styled.sets]
    out: dict = {"linesets": sets}
    if styled.depth_range is not None:
        out["depth_range"] = list(styled.depth_range)
    return out


def _with_occlusion(strokes: Strokes, extra: dict | None) -> bool:
    """Whether the strokes get their "occlusion" level: a hidden-line run, or hidden strokes."""
    return bool(extra and "occlusion" in extra) or bool(len(strokes.kind) and strokes.kind.max() >= N_KINDS)


def _strokes_body(strokes: Strokes, covers: list[bytes] | None = None, occlusion: bool = False,
                  styled: StyledStrokes | None = None) -> bytes | None:
    """The text between the brackets of the strokes array (b"" for no stroke); None where the fast
    way does not apply (see _stroke_cuts). `occlusion`: each stroke gets its level; `styled`:
    the strokes' style (their line set and widths; None: lines not drawn, without either)."""
    n = len(strokes)
    if n == 0:
        return b""
    cuts = _stroke_cuts(strokes, styled.width if styled is not None else None)
    if cuts is None:
        return None
    codes = strokes.kind.astype(np.int64)  # (a hidden drawing has thousands: no Python loop over them)
    cols = [strokes.ids.tolist(), _KIND_BYTES_ARRAY.take(codes % N_KINDS).tolist()]
    if styled is None:
        template = _LINE_OCCLUSION if occlusion else _LINE
    else:
        template = _STROKE_OCCLUSION if occlusion else _STROKE
        if styled.free is not None:
            template = template.replace(b'"width":[%s],', _JOINED)
    if occlusion:
        cols.append((codes // N_KINDS).tolist())
    if styled is not None:
        names = np.array([s.name.encode() for s in styled.sets], dtype=object)
        cols.append(names.take(styled.lineset).tolist())
    if styled is not None and styled.free is not None:
        joined = (~styled.free).astype(int)
        cuts = [*cuts[:2], joined[:, 0].tolist(), joined[:, 1].tolist(), *cuts[2:]]
    if strokes.pose is not None:
        template = template.replace(*_POSED)
    cols += [*cuts, _number_texts(strokes.lengths, 4, n), _number_texts(strokes.level, 6, n),
             _number_texts(strokes.level_weight, 6, n)]
    if covers is not None:
        cols.append(covers)
        template = template[:-1] + b',"covers":[%s]}'
    return b",".join([template] * n) % tuple(chain.from_iterable(zip(*cols)))


def _covers_lists(paths: BrushPaths, kept: np.ndarray | None = None) -> list[list]:
    """Per path (those `kept`, (S,) bool, None: all), its covers as [[line id, s0, s1, drawn], ...]
    (s0, s1 rounded to 4 decimals)."""
    line_ids = paths.lines.ids[paths.cover_line].tolist() if len(paths.cover_line) else []
    s0, s1 = round_list(paths.cover_s0, 4), round_list(paths.cover_s1, 4)
    drawn = paths.cover_drawn.astype(int).tolist()
    rows = [[i, a, b, d] for i, a, b, d in zip(line_ids, s0, s1, drawn)]
    off = paths.cover_offsets.tolist()
    out = [rows[a:b] for a, b in zip(off[:-1], off[1:])]
    return out if kept is None else [c for c, k in zip(out, kept.tolist()) if k]


def _cover_texts(paths: BrushPaths, kept: np.ndarray | None = None) -> list[bytes]:
    """Per path, the JSON text between the brackets of its covers (orjson's, as the nested document has)."""
    return [orjson.dumps(c)[1:-1] for c in _covers_lists(paths, kept)]


def _number_texts(x: np.ndarray, ndigits: int, n: int) -> list[bytes]:
    """orjson's text of each of round_list(x, ndigits) (n values); one text n times when x is
    constant, bit for bit (the level and weight of untracked strokes; -0.0 is not 0.0)."""
    if n > 1 and x.dtype == np.float64 and x.shape == (n,) and (x.view(np.int64) == x.view(np.int64)[0]).all():
        return [orjson.dumps(round_list(x[:1], ndigits)[0])] * n
    return orjson.dumps(round_list(x, ndigits))[1:-1].split(b",")


def _stroke_cuts(strokes: Strokes, width: np.ndarray | None = None) -> list[list[bytes]] | None:
    """Each stroke's points, width (when given), u, surface and face (and for a moving scene its
    objects and object points) as the JSON text between the brackets of its arrays: orjson's text
    of the frame's whole array, cut at the stroke starts. None when a stroke is empty, the arrays
    are not the (N, 2), (N,), (N, 3), (N,) of the offsets or the ids are not integers (%d would
    write them differently)."""
    off = strokes.offsets
    n = len(strokes.points)
    counts = np.diff(off)
    if (off[0] != 0 or off[-1] != n or not (counts > 0).all() or strokes.ids.dtype.kind not in "iu"
            or strokes.points.ndim != 2
            or strokes.surface.ndim != 2 or strokes.u.ndim != 1 or strokes.face.ndim != 1
            or not len(strokes.surface) == len(strokes.u) == len(strokes.face) == n):
        return None
    if width is not None and width.shape != (n,):
        return None
    out = []
    arrays = [np.round(strokes.points, 4) + 0.0, np.round(strokes.u, 5) + 0.0, strokes.surface, strokes.face]
    if width is not None:
        arrays.insert(1, np.round(width, 4) + 0.0)
    if strokes.pose is not None:
        arrays += list(strokes.pose.object_points(strokes.surface, strokes.face))
    for arr in arrays:
        text = orjson.dumps(np.ascontiguousarray(arr), option=_NP)  # orjson refuses strided arrays
        b = np.frombuffer(text, np.uint8)
        # [[x,y],[x,y]]: rows start at '['; [a,b,c]: elements after the commas. The comma before
        # each stroke's first row or element becomes NUL (never in orjson's text of numbers) and
        # the text between the outer brackets splits there.
        seps = np.flatnonzero(b == 91)[2:] - 1 if arr.ndim == 2 else np.flatnonzero(b == 44)
        if len(seps) != n - 1:
            return None
        b = b.copy()
        b[seps.take(off[1:-1] - 1)] = 0
        out.append(b[1:-1].tobytes().split(b"\0"))
    return out


def _stroke_dicts(strokes: Strokes, occlusion: bool = False, styled: StyledStrokes | None = None) -> list[dict]:
    pts = np.round(strokes.points, 4) + 0.0
    u = np.round(strokes.u, 5) + 0.0
    surface, face = strokes.surface, strokes.face
    off = strokes.offsets.tolist()
    lengths = round_list(strokes.lengths, 4)
    level, weight = round_list(strokes.level, 6), round_list(strokes.level_weight, 6)
    wd = np.round(styled.width, 4) + 0.0 if styled is not None else None
    names = [styled.sets[k].name for k in styled.lineset.tolist()] if styled is not None else [None] * len(strokes)
    joined = (~styled.free).astype(int).tolist() if styled is not None and styled.free is not None else \
        [None] * len(strokes)
    obj = local = None
    if strokes.pose is not None:
        obj, local = strokes.pose.object_points(surface, face)
    return [{
        "id": i, "kind": KINDS[k % N_KINDS], **({"occlusion": k // N_KINDS} if occlusion else {}),
        **({"lineset": name} if styled is not None else {}), "points": pts[a:b],
        **({"width": wd[a:b]} if styled is not None else {}), **({"joined": j} if j is not None else {}),
        "u": u[a:b], "surface": surface[a:b], "face": face[a:b],
        **({"object": obj[a:b], "local": local[a:b]} if obj is not None else {}),
        "length_px": ln, "level": lv, "level_weight": w,
    } for i, k, name, j, a, b, ln, lv, w in zip(strokes.ids.tolist(), strokes.kind.tolist(), names, joined,
                                                off[:-1], off[1:], lengths, level, weight)]


def _strokes_json_nested(styled: StyledStrokes, width: int, height: int, frame: int, *,
                         extra: dict | None = None, paths: BrushPaths | None = None) -> bytes:
    """strokes_json by orjson.dumps of the nested document (a numpy view per stroke and field)."""
    strokes = styled.strokes
    out = _stroke_dicts(strokes, _with_occlusion(strokes, extra), _said(styled))
    if paths is not None:
        for d, c in zip(out, _covers_lists(paths, styled.kept)):
            d["covers"] = c
    doc = {"frame": int(frame), "width": int(width), "height": int(height),
           "camera": strokes.camera.to_json() if strokes.camera is not None else None,
           "period_px": strokes.period_px}
    if extra:
        doc.update(extra)
    doc.update(_sets_json(styled))
    doc["strokes"] = out
    if paths is not None:
        doc["lines"] = _stroke_dicts(paths.lines, _with_occlusion(paths.lines, extra))
    return orjson.dumps(doc, option=orjson.OPT_SERIALIZE_NUMPY) + b"\n"


def read_strokes_json(path, which: str = "strokes") -> Strokes:
    """Read a frame JSON back into Strokes (camera included): its `strokes` (what the SVG draws),
    or with which="lines" the exact lines a brush-path frame keeps beside them (its strokes
    when the file has no "lines": the strokes are the lines then)."""
    d = orjson.loads(open(path, "rb").read())
    ss = d.get(which, d["strokes"]) if which == "lines" else d[which]
    counts = [len(s["points"]) for s in ss]
    offsets = np.r_[0, np.cumsum(counts)].astype(np.int64)

    def cat(key, dim):
        arrs = [np.asarray(s[key], float).reshape(-1, dim) if dim > 1 else np.asarray(s[key], float) for s in ss]
        if not arrs:
            return np.zeros((0, dim)) if dim > 1 else np.zeros(0)
        return np.concatenate(arrs)

    cam = None
    if d.get("camera"):
        cam = Camera.from_json(dict(d["camera"]))
    pose = None
    if "objects" in d and ss and "object" in ss[0]:  # a moving scene's frame
        pose = RecordedPose.from_json(d, np.asarray(cat("object", 1), np.int64), cat("local", 3))
    st = Strokes(points=cat("points", 2), surface=cat("surface", 3),
                 face=np.asarray(cat("face", 1) if ss and "face" in ss[0] else np.full(offsets[-1], -1), np.int64),
                 offsets=offsets,
                 kind=np.array([KIND_INDEX[s["kind"]] + N_KINDS * s.get("occlusion", 0) for s in ss], np.int8),
                 ids=np.array([s["id"] for s in ss], np.int64), u=cat("u", 1),
                 level=np.array([s.get("level", 0.0) for s in ss], float),
                 level_weight=np.array([s.get("level_weight", 1.0) for s in ss], float),
                 camera=cam, frame=int(d["frame"]), period_px=float(d.get("period_px", 30.0)), pose=pose)
    return st
