"""Face lines of an OBJ that trimesh drops or fails on without saying where: a face line of fewer
than three vertices (what a file cut short mid-face ends with) is dropped in silence, and a face
referring past the vertices fails as a bare IndexError."""

from __future__ import annotations

import re

import numpy as np

_SPACE, _TAB, _NEWLINE, _F = 32, 9, 10, ord("f")


def _line_at(data: bytes, start: int) -> tuple[int, str]:
    """(1-based line number, text) of the line starting at byte `start`."""
    end = data.find(b"\n", start)
    text = data[start:end if end >= 0 else len(data)].decode("utf-8", "replace").strip()
    return data.count(b"\n", 0, start) + 1, text


def short_face_warnings(data: bytes) -> tuple[str, ...]:
    """A warning (without the file's name) for the face lines of OBJ text `data` with fewer than
    three vertices, naming the first by its line; said as a cut when it is the file's last line.
    A line with fewer than three separators after its `f` has fewer than three indices (the
    count is over whole arrays: a few percent of trimesh's own parse)."""
    a = np.frombuffer(data, np.uint8)
    newlines = np.flatnonzero(a == _NEWLINE)
    starts = np.concatenate(([0], newlines + 1))
    ends = np.concatenate((newlines, [len(a)]))
    keep = starts < len(a) - 1
    starts, ends = starts[keep], ends[keep]
    face = (a[starts] == _F) & ((a[starts + 1] == _SPACE) | (a[starts + 1] == _TAB))
    starts, ends = starts[face], ends[face]
    separators = np.flatnonzero((a == _SPACE) | (a == _TAB))
    indices = np.searchsorted(separators, ends) - np.searchsorted(separators, starts)
    short = np.flatnonzero(indices < 3)
    if not len(short):
        return ()
    first = int(starts[short[0]])
    line, text = _line_at(data, first)
    n = int(indices[short[0]])
    msg = f"line {line} {text!r} is a face of {n} vertex index{'es' if n != 1 else ''} (a face needs 3): dropped"
    if len(short) > 1:
        msg += f", with {len(short) - 1} more such line(s)"
    if not data[ends[short[0]]:].strip():
        msg += "; the file ends there: it looks cut short"
    return (msg,)


_FACE_LINE = re.compile(rb"^f[ \t]+(.*)$", re.M)
_VERTEX_LINE = re.compile(rb"^v[ \t]", re.M)


def face_past_vertices(data: bytes) -> str | None:
    """The first face line of OBJ text `data` referring to a vertex the file does not have (1-based,
    or negative: counted back from the vertices before the line), said with its line; None when
    every index is in range. (Read only once trimesh has failed: a pass over every index.)"""
    n_vertices = len(_VERTEX_LINE.findall(data))
    for m in _FACE_LINE.finditer(data):
        for token in m.group(1).split():
            try:
                i = int(token.split(b"/")[0])
            except ValueError:
                continue
            before = len(_VERTEX_LINE.findall(data, 0, m.start())) if i < 0 else n_vertices
            if abs(i) > before:
                line, text = _line_at(data, m.start())
                return (f"line {line} {text!r} refers to vertex {i}, but the file has {n_vertices} "
                        f"vertices{f' ({before} before that line)' if i < 0 else ''}")
    return None
