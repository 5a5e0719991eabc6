"""Atomic file writes: every output goes to a temporary name in the same folder and is renamed
into place, so an interrupted run never leaves a half-written file (BRIEF 1.3)."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from strokekit.errors import InputError, UsageError


def _read_umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


#: Read once at import: os.umask can only be read by setting it, which races with other threads.
_UMASK = _read_umask()


def atomic_write_bytes(path: str | Path, data: bytes) -> Path:
    """Write `data` to `path` through a temporary file in the same folder and a rename. The file
    gets the permissions any new file gets (0666 less the umask), not mkstemp's private 0600.
    An OSError names `path`, never the temporary file (which the user has never heard of)."""
    p = Path(path)
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=TEMP_SUFFIX, dir=p.parent)
    except OSError as e:
        raise OSError(e.errno, e.strerror, str(p)) from None
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            os.fchmod(f.fileno(), 0o666 & ~_UMASK)
        os.replace(tmp, p)
    except BaseException as e:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        if isinstance(e, OSError):
            raise OSError(e.errno, e.strerror, str(p)) from None
        raise
    return p


def atomic_write_text(path: str | Path, text: str) -> Path:
    return atomic_write_bytes(path, text.encode("utf-8"))


#: Temporary files of atomic_write_bytes are ".<final name>.<random>.part" beside the final file.
TEMP_SUFFIX = ".part"


def temp_file_target(tmp: str | Path) -> str | None:
    """The final file name a temporary file of atomic_write_bytes was for, or None when `tmp` is
    not one of ours."""
    name = Path(tmp).name
    if not (name.startswith(".") and name.endswith(TEMP_SUFFIX)):
        return None
    target, dot, _random = name[1:-len(TEMP_SUFFIX)].rpartition(".")
    return target if dot and target else None


def _nearest_existing(p: Path) -> Path:
    probe = p
    while not probe.exists():
        if probe.parent == probe:
            break
        probe = probe.parent
    return probe


def _try_create_in(folder: Path, make_folder: bool) -> str | None:
    """Create (and remove at once) a temporary file, or folder, in `folder`: the only sure test
    that it can be written (os.access says yes to root on a read-only mount or in /proc).
    Returns the reason it cannot, or None."""
    try:
        if make_folder:
            os.rmdir(tempfile.mkdtemp(prefix=".strokekit-check.", dir=folder))
        else:
            fd, tmp = tempfile.mkstemp(prefix=".strokekit-check.", suffix=TEMP_SUFFIX, dir=folder)
            os.close(fd)
            os.unlink(tmp)
    except OSError as e:
        return e.strerror or str(e)
    return None


def _folder_problem(p: Path) -> str | None:
    """Why files cannot be written in folder `p` (absolute; created later if missing), said of
    `p` without naming it, or None. Its nearest existing parent must be a folder where a file
    (or the missing folders) can really be created, which is tried."""
    probe = _nearest_existing(p)
    if not probe.is_dir():
        return "is a file, not a folder" if probe == p else f"cannot be created: {probe} is a file, not a folder"
    if not os.access(probe, os.W_OK | os.X_OK):
        return "cannot be written (no permission)" if probe == p else f"cannot be created: no permission in {probe}"
    why = _try_create_in(probe, make_folder=probe != p)
    if why is not None:
        return f"cannot be written ({why})" if probe == p else f"cannot be created in {probe} ({why})"
    return None


def check_output_folder(path: str | Path) -> None:
    """Raise InputError, naming `path`, unless files can be written in folder `path` (created
    later if missing). Leaves nothing behind, so a run refused for another reason leaves no
    empty folder. An empty name is a UsageError (it would mean the current folder)."""
    if not str(path).strip():
        raise UsageError("an output folder name is empty")
    why = _folder_problem(Path(path).absolute())
    if why is not None:
        raise InputError(why, path)


def check_output_file(path: str | Path) -> None:
    """Raise InputError, naming `path`, unless file `path` can be written (its folder, created
    later if missing, must allow it; a folder at `path` itself cannot be replaced)."""
    if not str(path).strip():
        raise UsageError("an output file name is empty")
    p = Path(path).absolute()
    if p.is_dir():
        raise InputError("cannot be written: it is a folder", path)
    why = _folder_problem(p.parent)
    if why is not None:
        raise InputError(f"cannot be written: its folder {p.parent} {why}", path)


def same_file(a: str | Path, b: str | Path) -> bool:
    """Whether `a` and `b` name one file: one path once links and '..' are resolved, or two names
    (hard links, bind mounts) of one existing file."""
    if os.path.realpath(a) == os.path.realpath(b):
        return True
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


def check_not_an_input(flag: str, output: str | Path | None, inputs) -> None:
    """UsageError when the file that `flag` writes (`output`) is one of `inputs` ((what, path)
    pairs: the scene, the camera file): writing it would destroy the input."""
    if not output or not str(output).strip():
        return
    for what, name in inputs:
        if name and Path(name).is_file() and same_file(output, name):
            raise UsageError(f"{flag} {output} is the {what}: it would be overwritten; name another file")


def check_pattern(pattern: str) -> None:
    """UsageError unless `pattern` (a frame's file name without extension, `{frame}` in str.format
    syntax) names frames apart, inside the output folder, not as dotfiles."""
    try:
        names = {pattern.format(frame=1), pattern.format(frame=2)}
    except (KeyError, IndexError, ValueError, AttributeError):
        raise UsageError(f"bad --pattern {pattern!r}: use {{frame}} e.g. frame_{{frame:04d}}") from None
    if len(names) < 2:
        raise UsageError(f"bad --pattern {pattern!r}: it must contain {{frame}}, or every frame gets the same name")
    if any(sep in pattern for sep in ("/", "\\")) or any(n.startswith(".") for n in names):
        raise UsageError(f"bad --pattern {pattern!r}: a file name inside --out, without folders")
