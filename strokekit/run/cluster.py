"""A dask cluster's workers checked before any frame (`check_workers`): each must read the
run's scene and write into the caller's output folder at the paths the caller names, as on a
shared file system; a worker that cannot is said by name, instead of frames that fail one by one
or land on the worker's own disk."""

from __future__ import annotations

import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

from strokekit.errors import InputError
from strokekit.run.spec import RunSpec
from strokekit.run.workers import Workers

#: The workers need the caller's files at the same paths.
SHARED = "the workers need the caller's files at the same paths (a shared file system)"


@dataclass(frozen=True)
class WorkerCheck:
    """What a worker must see: the scene file (of the caller's size) and, in the output folder,
    the file `marker` the caller has just made there. Called on the worker: the problem, or None."""

    scene_path: str
    scene_size: int
    out_dir: str
    marker: str

    def __call__(self) -> str | None:
        try:
            with open(self.scene_path, "rb") as f:
                size = os.fstat(f.fileno()).st_size
                f.read(1)
        except OSError as e:
            return f"cannot read the scene {self.scene_path} ({e.strerror or e}): {SHARED}"
        if size != self.scene_size:
            return (f"reads another file at {self.scene_path} ({size} bytes; the caller's scene has "
                    f"{self.scene_size}): {SHARED}")
        if not os.path.exists(os.path.join(self.out_dir, self.marker)):
            return f"does not see the output folder {self.out_dir} of the caller: {SHARED}"
        try:
            fd, tmp = tempfile.mkstemp(prefix=".strokekit-check.", dir=self.out_dir)
            os.close(fd)
            os.unlink(tmp)
        except OSError as e:
            return f"cannot write in the output folder {self.out_dir} ({e.strerror or e})"
        return None


def check_workers(spec: RunSpec, workers: Workers) -> None:
    """InputError naming the first worker (and the path) that cannot read the scene or write the
    output folder; nothing to check without a cluster. The output folder is made for the check
    (removed again when the check fails and it was not there)."""
    if workers.on_each is None:
        return
    out = Path(spec.outputs.out_dir)
    existing = next(p for p in [out, *out.parents] if p.exists())
    out.mkdir(parents=True, exist_ok=True)
    fd, marker = tempfile.mkstemp(prefix=".strokekit-check.", dir=out)
    os.close(fd)
    try:
        answers = workers.on_each(WorkerCheck(spec.scene_path, os.path.getsize(spec.scene_path), str(out),
                                              os.path.basename(marker)))
    finally:
        os.unlink(marker)
    bad = sorted((name, why) for name, why in answers.items() if why is not None)
    if bad:
        if existing != out:  # the folders this check made, if still empty
            top = next(p for p in [out, *out.parents] if p.parent == existing)
            if not any(f for _, _, fs in os.walk(top) for f in fs):
                shutil.rmtree(top, ignore_errors=True)
        name, why = bad[0]
        more = f" (and {len(bad) - 1} other worker(s))" if len(bad) > 1 else ""
        raise InputError(f"dask worker {name}{more} {why}")
