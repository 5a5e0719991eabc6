"""What the output folder holds around a run: the stock taken before it (`plan_resume`: frames
kept from an earlier run, what this run rewrites) and the clean-up after a stop (`clean_up`: a
frame is on disk whole or not at all)."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from strokekit.errors import UsageError
from strokekit.fileio import temp_file_target
from strokekit.run.manifest import RUN_MANIFEST, not_a_resume, read_run_manifest, resumes_from, run_manifest
from strokekit.run.spec import RunResult, RunSpec
from strokekit.scene.load import Scene


@dataclass
class ResumePlan:
    """What is on disk before the run and what this run will (re)write.

    before: {path: (inode, mtime_ns, size)} of the frame files there at the start (a file this run
    wrote is one missing from it or changed since; an atomic write replaces the inode: no clock
    compared). done_before: frames kept from an earlier run (--skip-existing). entries: the run
    manifest's frame entries to write now; enter_later: frames entered once written (files of
    them from something else are there until then)."""

    manifest: dict
    before: dict[str, tuple]
    done_before: set[int]
    entries: dict
    enter_later: set[int]


def plan_resume(spec: RunSpec, scene: Scene) -> ResumePlan:
    """Take stock of the output folder. Frames whose every file exists, rendered by this run's
    scene and options with this frame's camera (the manifest says so), are not written again
    with spec.skip_existing (when strokes carry over their lines are still computed: a frame's
    strokes depend on every earlier frame, so a resumed run gives the same bytes as an
    uninterrupted one). A run that only turns outputs off resumes too (manifest.resumes_from:
    the files of those outputs stay as they are, the manifest then describes this run).
    Frame files there with a manifest of another scene or options, or none, raise UsageError."""
    out = spec.outputs
    out.out_dir.mkdir(parents=True, exist_ok=True)
    # Temporary files of an interrupted earlier run are ours to remove (their final names never existed).
    for folder in _folders(spec):
        for stale in folder.glob(".*.part"):
            stale.unlink(missing_ok=True)
    frames = [f for f, _ in spec.cameras]
    manifest = run_manifest(spec, scene)
    old = read_run_manifest(out.out_dir)
    resumes = resumes_from(old, manifest)  # (the same run, or it with outputs turned off)
    before = _file_states(p for f in frames for p in spec.frame_files(f))
    on_disk = {f: [str(p) in before for p in spec.frame_files(f)] for f in frames}
    done_before = set()
    if spec.skip_existing:
        present = {f for f in frames if all(on_disk[f])}
        if present and not resumes:
            raise UsageError(not_a_resume(out.out_dir, old, manifest, present))
        done_before = {f for f in present if old["frames"].get(f) == manifest["frames"][f]}
    # The manifest is written before any frame file: the same run's entries are kept (merged; also
    # by a run that turned outputs off: the kept files are its own), another run's replaced. A
    # frame of this run is entered now unless files of it from something else are there (they
    # stay until rewritten): it is entered once written, so a run stopped before that never
    # leaves such a file looking like this run's.
    entries = dict(old["frames"]) if resumes else {}
    enter_later: set[int] = set()
    for f in frames:
        new = manifest["frames"][f]
        if entries.get(f) == new or not any(on_disk[f]):
            entries[f] = new
        else:
            entries.pop(f, None)
            enter_later.add(f)
    return ResumePlan(manifest, before, done_before, entries, enter_later)


def lines_needed(spec: RunSpec, resume: ResumePlan) -> list[int]:
    """The frames whose lines this run computes, in frame order: those it writes, and before
    the last of them the frames kept from an earlier run when tracking needs every earlier
    frame; every frame when sequence.glb holds them all. Empty when nothing is left to do
    (then no kernel is loaded or compiled either)."""
    frames = [f for f, _ in spec.cameras]
    done = resume.done_before
    if spec.outputs.gltf and spec.outputs.gltf_sequence:
        return frames
    if not spec.plan.carried:
        return [f for f in frames if f not in done]
    todo = [i for i, f in enumerate(frames) if f not in done]
    # (The tracker's state at a frame depends only on the frames before it.)
    return frames[:todo[-1] + 1] if todo else []


def run_files(spec: RunSpec) -> list[Path]:
    """Every file the run may write: each frame's files, sequence.glb, the run manifest."""
    out = spec.outputs
    files = [p for f, _ in spec.cameras for p in spec.frame_files(f)] + [out.out_dir / RUN_MANIFEST]
    if out.gltf and out.gltf_sequence:
        files.append(out.out_dir / "sequence.glb")
    return files


def clean_up(spec: RunSpec, res: RunResult, resume: ResumePlan | None, interrupted: bool = False) -> None:
    """After Ctrl-C (`interrupted`) or failed frames: a frame is on disk whole or not at all.
    After Ctrl-C the temporaries of writes in progress go, and frames whose files this run all
    wrote count as written though their results never came back."""
    before = resume.before if resume is not None else None
    if interrupted:
        remove_temp_files(spec)
        _frames_found_whole(spec, res, before)
    _remove_partial_frames(spec, res, before)


def _folders(spec: RunSpec) -> list[Path]:
    """The folders the run writes frame files into: the output folder and its PNG passes'."""
    out_dir = spec.outputs.out_dir
    return [out_dir, *(out_dir / p for p in spec.pass_folders())]


def _file_states(paths) -> dict[str, tuple]:
    """{path: (inode, mtime_ns, size)} of the files among `paths` that exist."""
    out = {}
    for p in paths:
        try:
            s = os.stat(p)
        except OSError:
            continue
        out[str(p)] = (s.st_ino, s.st_mtime_ns, s.st_size)
    return out


def _written_by_run(p: Path, before: dict[str, tuple] | None) -> bool:
    """Whether file `p` exists and was written by this run: it was not there at the start (see
    `before`), or has changed since. False when the run never took stock (nothing written yet)."""
    if before is None:
        return False
    now = _file_states([p])
    return str(p) in now and before.get(str(p)) != now[str(p)]


def _frames_found_whole(spec: RunSpec, res: RunResult, before: dict[str, tuple] | None) -> None:
    """After Ctrl-C: frames whose every file this run wrote count as written, though their results
    never came back (the interrupt fell between the last rename and the report of a worker, or
    of this process)."""
    known = set(res.frames_ok) | set(res.failures) | set(res.frames_skipped)
    listed = set(res.outputs)
    for f, _ in spec.cameras:
        if f in known:
            continue
        paths = spec.frame_files(f)
        if paths and all(_written_by_run(p, before) for p in paths):
            res.frames_ok.append(f)
            res.outputs += [str(p) for p in paths if str(p) not in listed]


def _remove_partial_frames(spec: RunSpec, res: RunResult, before: dict[str, tuple] | None) -> None:
    """Files this run wrote of frames it did not write whole: the raster images of a frame whose
    lines failed to be written, or that a stop (Ctrl-C, --fail-fast) left untracked. Removed with
    the rest of the frame's files (an earlier run's, which would make a frame of two runs), so that
    a frame is on disk whole or not at all. A frame this run did not touch stays as it was."""
    keep = set(res.frames_ok) | set(res.frames_skipped)
    gone = set()
    for f, _ in spec.cameras:
        if f in keep:
            continue
        paths = spec.frame_files(f)
        if not any(_written_by_run(p, before) for p in paths):
            continue  # untouched: an earlier run's frame stays as it was
        # Some of it is new: an earlier run's files of it would make a frame of two runs.
        for p in paths:
            try:
                p.unlink()
                gone.add(str(p))
            except OSError:
                continue
    if gone:
        res.outputs[:] = [o for o in res.outputs if o not in gone]


def remove_temp_files(spec: RunSpec) -> list[Path]:
    """Remove the temporary files (.<name>.<random>.part) that writes of this run's outputs left
    in its output folder (a worker stopped mid-write); returns them. Others' files are not touched."""
    out = spec.outputs
    names = {str(p) for p in run_files(spec)} | {str(out.out_dir / "sequence.glb")}
    removed = []
    try:
        temps = [t for folder in _folders(spec) for t in folder.glob(".*.part")]
    except OSError:
        return removed
    for tmp in temps:
        if str(tmp.parent / (temp_file_target(tmp) or "")) in names:
            tmp.unlink(missing_ok=True)
            removed.append(tmp)
    return removed
