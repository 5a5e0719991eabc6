"""The JSON run report (`run_report`): versions, input hashes, every option, per-frame status,
camera, outputs and timings: enough to render any frame again."""

from __future__ import annotations

import hashlib
import platform
from dataclasses import fields
from pathlib import Path

from strokekit.run.manifest import canonical
from strokekit.run.spec import RunResult, RunSpec


def installed_versions() -> dict:
    """The versions of Python and of the distributions that shape the outputs (None: not installed)."""
    from importlib.metadata import PackageNotFoundError, version

    out = {"python": platform.python_version()}
    for dist in ("strokekit", "numpy", "scipy", "trimesh", "open3d", "embreex", "shapely",
                 "pygltflib", "click", "pillow", "numba"):
        out[dist] = None
        # (open3d is installed as open3d-cpu where that build is published)
        for name in (dist, "open3d-cpu") if dist == "open3d" else (dist,):
            try:
                out[dist] = out[dist] or version(name)
            except PackageNotFoundError:
                pass
    return out


def run_report(spec: RunSpec, res: RunResult) -> dict:
    """The JSON run report: versions, input hashes, per-frame status, outputs, timings, stages."""
    plan = spec.plan
    with open(spec.scene_path, "rb") as fh:
        file_hash = hashlib.sha256(fh.read()).hexdigest()
    cameras = {"source": spec.camera_source or None, "frames": len(spec.cameras),
               "sizes": sorted({(c.width, c.height) for _, c in spec.cameras})}
    if spec.camera_source and Path(spec.camera_source).is_file():
        try:
            cameras["sha256"] = hashlib.sha256(Path(spec.camera_source).read_bytes()).hexdigest()
        except OSError:
            pass
    # Each frame's camera as the run used it (with the scene and options above, enough to
    # render any frame again).
    cams = {f: canonical(c.to_json()) for f, c in spec.cameras}
    o = spec.outputs
    outputs = canonical({**{f.name: getattr(o, f.name) for f in fields(o)}, "raster_options": spec.raster})
    frames = {}
    for f, _ in spec.cameras:
        if f in res.failures:
            frames[str(f)] = {"status": "failed", "error": res.failures[f]}
        elif f in res.frames_skipped and f not in res.frames_ok:
            frames[str(f)] = {"status": "skipped (exists)"}
        elif f in res.frames_ok:
            frames[str(f)] = {"status": "ok", "seconds": round(res.frame_seconds.get(f, 0.0), 6)}
        else:
            frames[str(f)] = {"status": "not run"}
        frames[str(f)]["camera"] = cams[f]
    return {
        "status": res.status,
        "versions": installed_versions(),
        "platform": platform.platform(),
        "scene": {"path": spec.scene_path, "sha256": file_hash, "content_hash": res.scene_hash, **res.scene_summary},
        "cameras": cameras,
        "options": {"lines": spec.lines.to_json(), "workers": spec.workers, "worker_kind": spec.worker_kind,
                    "scheduler": spec.scheduler, "strokes": "brush" if plan.paths is not None else "lines",
                    "tracking": plan.tracking.method if plan.tracking is not None else "none",
                    "tracking_options": canonical(plan.tracking) if plan.tracking is not None else None,
                    "paths_options": canonical(plan.paths) if plan.paths is not None else None,
                    "contours": spec.lines.contours, "outputs": outputs,
                    "animation": spec.request.animation, "time_offset": spec.request.time_offset, "fps": spec.fps,
                    "style": None if plan.style.is_default else plan.style.to_json()},
        "ray_tracer": ", ".join(sorted(res.ray_tracers)) or None,
        "stages": [{"stage": s.name, "ran": s.ran, "why": s.why, "seconds": round(s.seconds, 6)} for s in res.stages],
        "frames": frames,
        "failures": {str(k): v for k, v in sorted(res.failures.items())},
        "write_error": res.write_error,
        "outputs": res.outputs,
        "passes": {"png": [f"{p}/{spec.outputs.pattern}.png" for p in spec.pass_folders()],
                   "exr": list(spec.outputs.exr.passes) if spec.outputs.exr is not None else []},
        "wall_seconds": round(res.wall_seconds, 4),
        "exit_code": res.exit_code,
    }
