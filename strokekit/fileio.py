"""Atomic file writes: every output goes to a temporary name in the same folder and is renamed
into place, so an interrupted run never leaves a half-written file (BRIEF 1.3)."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from .errors import InputError


def _read_umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


#: Read once at import: os.umask can only be read by setting it, which races with other threads.
_UMASK = _read_umask()


def atomic_write_bytes(path: str | Path, data: bytes) -> Path:
    """Write `data` to `path` through a temporary file in the same folder and a rename. The file
    gets the permissions any new file gets (0666 less the umask), not mkstemp's private 0600."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".part", dir=p.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            os.fchmod(f.fileno(), 0o666 & ~_UMASK)
        os.replace(tmp, p)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise
    return p


def atomic_write_text(path: str | Path, text: str) -> Path:
    return atomic_write_bytes(path, text.encode("utf-8"))


def check_output_folder(path: str | Path) -> None:
    """Raise InputError unless files can be written in folder `path` (created later if missing):
    it, or its nearest existing parent, must be a writable folder. Creates nothing, so a run
    refused for another reason leaves no empty folder behind."""
    p = Path(path).absolute()
    probe = p
    while not probe.exists():
        if probe.parent == probe:
            break
        probe = probe.parent
    if not probe.is_dir():
        what = "is a file, not a folder" if probe == p else f"cannot be created: {probe} is not a folder"
        raise InputError(what, p)
    if not os.access(probe, os.W_OK | os.X_OK):
        raise InputError("cannot be written (no permission)" if probe == p else
                         f"cannot be created: no permission in {probe}", p)
