"""The run manifest (OUT/.strokekit-run.json): digests of the scene, of every option that
changes the output bytes and of each frame's camera, so `--skip-existing` resumes only frames
rendered by the same run."""

from __future__ import annotations

import hashlib
import json
from dataclasses import fields, is_dataclass
from pathlib import Path

from strokekit.fileio import atomic_write_bytes
from strokekit.ribbons.brushes import BUNDLED
from strokekit.run.spec import RunSpec
from strokekit.scene.load import Scene

# --- the run manifest ----------------------------------------------------------------------------------

#: The output folder's record of what its frame files were rendered from (a dotfile: not a frame file).
RUN_MANIFEST = ".strokekit-run.json"


def canonical(v):
    """`v` as plain JSON values, deterministically (dataclasses field by field, tuples as lists)."""
    if is_dataclass(v) and not isinstance(v, type):
        return {f.name: canonical(getattr(v, f.name)) for f in fields(v)}
    if isinstance(v, (list, tuple)):
        return [canonical(x) for x in v]
    if isinstance(v, dict):
        return {str(k): canonical(x) for k, x in v.items()}
    if isinstance(v, Path):
        return str(v)
    if v is None or isinstance(v, (bool, int, float, str)):
        return v
    if hasattr(v, "item"):  # a numpy scalar
        return v.item()
    raise TypeError(f"cannot digest a {type(v).__name__} in the run options")


def _digest(v) -> str:
    text = json.dumps(canonical(v), sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def run_manifest(spec: RunSpec, scene: Scene) -> dict:
    """What determines the bytes of the run's frame files: `scene` and `options` digests (the
    set of frames aside) and per frame a digest of its camera. When strokes carry over from
    frame to frame a frame's lines also depend on every frame before it in the run, so its
    digest chains theirs: a longer range of the same path (1-10, then 1-20) keeps the digests
    of the frames they share."""
    plan = spec.plan
    scene_d = _digest({"content_hash": scene.content_hash, "objects": len(scene.objects),
                       "materials": [m.base_color for m in scene.materials]})
    o = spec.outputs
    # An option at its default that a later option added is left out of the digest, so that the
    # digests of runs made before it stay: the dash paths, the SVG's outlines, the EXR codec.
    outputs = {f.name: getattr(o, f.name) for f in fields(o) if f.name != "out_dir"
               and not (f.name == "dash_paths" and not o.dash_paths)
               and not (f.name == "svg_lines" and o.svg_lines == "outline")}
    outputs["raster_options"] = plan.raster  # (the raster pass is digested with the outputs)
    if o.exr is not None and o.exr.codec == "zip":
        outputs["exr"] = {f.name: getattr(o.exr, f.name) for f in fields(o.exr) if f.name != "codec"}
    brush = o.gltf_options.brush if o.gltf_options is not None else None
    if o.gltf and brush is not None:
        if brush not in BUNDLED:  # a user's image: its bytes go into every GLB
            try:
                outputs["brush_sha256"] = hashlib.sha256(Path(brush).read_bytes()).hexdigest()
            except OSError:
                pass  # the run reports it
    opts = {"lines": plan.lines.to_json(), "outputs": outputs, "tracking": plan.tracking}
    if plan.style.is_default:  # the shortcuts' style: digested as the outputs' options it was before
        outputs["stroke_width_px"] = plan.style.width
        if plan.style.dashes is not None:
            outputs["hidden_dashes"] = plan.style.dashes
    else:
        opts["style"] = plan.style.to_json()
    if plan.paths is not None:  # (brush runs only: a lines run's digest has no paths)
        opts["paths"] = plan.paths
    options_d = _digest(opts)
    frames, chain = {}, ""
    for f, cam in spec.cameras:
        d = _digest(cam.to_json())
        if plan.carried:
            d = chain = _digest([chain, f, d])
        frames[f] = d
    return {"strokekit_run": 1, "run": _digest([scene_d, options_d]), "scene": scene_d, "options": options_d,
            "frames": frames}


def read_run_manifest(out_dir: Path) -> dict | None:
    """The manifest in `out_dir`, frames keyed by int; None when missing or unreadable."""
    try:
        d = json.loads((Path(out_dir) / RUN_MANIFEST).read_text())
        d["frames"] = {int(k): str(v) for k, v in d["frames"].items()}
        if d.get("strokekit_run") != 1 or not all(isinstance(d.get(k), str) for k in ("run", "scene", "options")):
            return None
        return d
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return None


def write_run_manifest(out_dir: Path, manifest: dict, frames: dict[int, str]) -> Path:
    d = {k: manifest[k] for k in ("strokekit_run", "run", "scene", "options")}
    d["frames"] = {str(f): frames[f] for f in sorted(frames)}
    return atomic_write_bytes(Path(out_dir) / RUN_MANIFEST, (json.dumps(d, indent=1) + "\n").encode())


def _frame_ranges(frames) -> str:
    """[1, 2, 3, 7] -> '1-3, 7'."""
    out: list[list[int]] = []
    for f in sorted(frames):
        if out and f == out[-1][1] + 1:
            out[-1][1] = f
        else:
            out.append([f, f])
    return ", ".join(str(a) if a == b else f"{a}-{b}" for a, b in out)


def not_a_resume(out_dir: Path, old: dict | None, new: dict, present: set[int]) -> str:
    """The one line saying why --skip-existing cannot skip the frames `present` in `out_dir`."""
    where = f"{out_dir}/"
    fix = "remove them or render without --skip-existing"
    if old is None:
        return (f"--skip-existing: {where} holds frames but no readable {RUN_MANIFEST} to tell what they were "
                f"rendered from; {fix}")
    parts = [p for p in ("scene", "options") if old[p] != new[p]]
    cams = [f for f in present if f in old["frames"] and old["frames"][f] != new["frames"][f]]
    if cams:
        parts.append(f"cameras of frames {_frame_ranges(cams)}")
    what = " or ".join(x for x, p in (("another scene", "scene"), ("other options", "options")) if p in parts)
    what = what or "another run"  # a run digest that its parts do not explain: an edited file
    return (f"--skip-existing: {where} holds frames of {what} ({RUN_MANIFEST} differs: {', '.join(parts)}); {fix}")
