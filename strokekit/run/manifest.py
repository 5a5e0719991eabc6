"""The run manifest (OUT/.strokekit-run.json): digests of the scene, of every option that
changes the output bytes and of each frame's camera, so `--skip-existing` resumes only frames
rendered by the same run."""

from __future__ import annotations

import hashlib
import json
from dataclasses import fields, is_dataclass
from pathlib import Path

from strokekit.fileio import atomic_write_bytes
from strokekit.options import LineOptions, flag_of
from strokekit.paths.options import PathOptions
from strokekit.raster.options import PassOptions, RasterOptions
from strokekit.ribbons.options import BUNDLED
from strokekit.run.spec import OutputOptions, RunSpec
from strokekit.scene.load import Scene
from strokekit.style.linesets import Style
from strokekit.tracking.options import TrackingOptions
from strokekit.writers.options import GltfOptions

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
    # digests of runs made before it stay: the dash paths, the SVG's outlines, the EXR codec and float
    # types.
    # The default style's shortcuts are digested among the outputs, where their options were.
    shortcuts = _style_shortcuts(plan.style)
    outputs = {}
    for f in fields(o):
        if f.name == "dash_paths":
            outputs.update({k: v for k, v in shortcuts.items() if k != "stroke_width_px"})
        if f.name != "out_dir" and not (f.name == "dash_paths" and not o.dash_paths) \
                and not (f.name == "svg_lines" and o.svg_lines == "outline"):
            outputs[f.name] = getattr(o, f.name)
        if f.name == "decimals" and "stroke_width_px" in shortcuts:
            outputs["stroke_width_px"] = shortcuts["stroke_width_px"]
    outputs["raster_options"] = plan.raster  # (the raster pass is digested with the outputs)
    if plan.raster is not None and plan.raster.shading == "flat":  # (the smooth angle shapes no flat bytes)
        outputs["raster_options"] = {k: v for k, v in canonical(plan.raster).items() if k != "smooth_angle_deg"}
    if o.exr is not None:
        outputs["exr"] = {f.name: getattr(o.exr, f.name) for f in fields(o.exr)
                          if not (f.name == "codec" and o.exr.codec == "zip")
                          and not (f.name == "precision" and o.exr.precision == "half")}
    brush = o.gltf_options.brush if o.gltf_options is not None else None
    if o.gltf and brush is not None:
        if brush not in BUNDLED:  # a user's image: its bytes go into every GLB
            try:
                outputs["brush_sha256"] = hashlib.sha256(Path(brush).read_bytes()).hexdigest()
            except OSError:
                pass  # the run reports it
    opts = {"lines": plan.lines.to_json(), "outputs": outputs, "tracking": plan.tracking}
    if not plan.style.is_default:
        opts["style"] = plan.style.to_json()
    if plan.paths is not None:  # (brush runs only: a lines run's digest has no paths)
        opts["paths"] = plan.paths
    options_d = _digest(opts)
    settings = _flat(canonical(opts))
    frames, chain = {}, ""
    motion = scene.motion
    moving = motion is not None and motion.moves(motion.animation(spec.request.animation))
    for f, cam in spec.cameras:
        # (a moving scene's frame is also its time in the animation: another fps or offset is
        # another frame)
        d = _digest(cam.to_json() if not moving else [cam.to_json(), spec.plan.clock.time(f), spec.request.animation])
        if plan.carried:
            d = chain = _digest([chain, f, d])
        frames[f] = d
    return {"strokekit_run": 1, "run": _digest([scene_d, options_d]), "scene": scene_d, "options": options_d,
            "settings": settings, "frames": frames}


#: The default style's shortcuts as the run options named them before line styles (outputs'
#: names), and their fields of Style.
_SHORTCUTS = {"stroke_width_px": "width", "hidden_dashes": "dashes"}


def _style_shortcuts(style: Style) -> dict:
    """{outputs' name: value} of the default style's shortcuts ({} for a style file's: it is
    digested whole); the dashes only where said."""
    if not style.is_default:
        return {}
    out = {"stroke_width_px": style.width}
    if style.dashes is not None:
        out["hidden_dashes"] = style.dashes
    return out


def _flat(v, prefix: str = "") -> dict:
    """{dotted name: value} of nested dicts ('outputs.raster_options.bands': 3)."""
    if not isinstance(v, dict):
        return {prefix: v}
    out = {}
    for k, x in v.items():
        out.update(_flat(x, f"{prefix}.{k}" if prefix else str(k)))
    return out


#: The options class of each part of the settings, whose fields name their flags.
_SETTINGS_CLASSES = {"lines": LineOptions, "outputs": OutputOptions, "outputs.raster_options": RasterOptions,
                     "outputs.exr": PassOptions, "outputs.gltf_options": GltfOptions, "tracking": TrackingOptions,
                     "paths": PathOptions}


def _setting_name(key: str) -> str:
    """A setting as the user gave it: its flag ('--stroke-width'), else its dotted name."""
    part, _, name = key.rpartition(".")
    cls = _SETTINGS_CLASSES.get(part)
    if part == "outputs" and name in _SHORTCUTS:
        cls, name = Style, _SHORTCUTS[name]
    field = next((f for f in fields(cls) if f.name == name), None) if cls is not None else None
    flag = flag_of(field) if field is not None else None
    return flag.name if flag is not None else key


def _setting_value(v) -> str:
    if isinstance(v, list):
        return ",".join(map(_setting_value, v))
    return v if isinstance(v, str) else "none" if v is None else json.dumps(v)


def _off_group(settings: dict, key: str) -> str | None:
    """The group of settings holding `key` that is none in `settings` ('outputs.gltf_options'
    of 'outputs.gltf_options.taper'), or None."""
    parts = key.split(".")
    return next((g for g in (".".join(parts[:i]) for i in range(1, len(parts))) if settings.get(g, 0) is None), None)


#: A group of settings that one run has off is said by its output's switch, else by its name;
#: the names of settings that no flag sets.
_GROUP_SWITCH = {"outputs.gltf_options": "outputs.gltf"}
_NAMES = {"outputs.raster_options": "a raster pass", "outputs.exr": "--exr",
          "outputs.raster_options.pngs": "the raster PNGs"}


def _group_value(settings: dict, key: str):
    """A setting's value; "on" for a group of settings that is not none."""
    return settings.get(key) if key in settings or not _is_on(settings, key) else "on"


# --- outputs turned off: a resume keeps the outputs still asked for -----------------------------------

#: The outputs a resume may turn off: {their switch: the settings that only they read (writers.svg
#: alone takes the decimals, the SVG line form and the dash paths; the ribbons' options and brush
#: go into the GLBs alone)}. The style and its shortcuts (--stroke-width, --dashes) are every
#: writer's, the pattern names every file: shared. The raster pass: `_raster_only`.
_OUTPUT_ONLY = {
    "outputs.svg": ("outputs.decimals", "outputs.svg_lines", "outputs.dash_paths"),
    "outputs.json": (),
    "outputs.gltf": ("outputs.gltf_sequence", "outputs.gltf_options", "outputs.brush_sha256"),
    "outputs.exr": (),
    "outputs.lines_png": (),
}
_RASTER = "outputs.raster_options"


def _is_on(settings: dict, switch: str) -> bool:
    """Whether the output of `switch` is asked for in `settings` (a switch, or a group of options)."""
    return settings.get(switch) is True or any(k.startswith(switch + ".") for k in settings)


def _within(key: str, groups) -> bool:
    return any(key == g or key.startswith(g + ".") for g in groups)


def _raster_only(a: dict, b: dict) -> bool:
    """Whether the raster pass of `a` (the old settings) is read by no output still asked for in
    `b`: none now, and neither the JSON (its "raster" part: the objects, materials and depth
    range) nor the SVG of band polygons is kept."""
    return (_is_on(a, _RASTER) and b.get(_RASTER, 0) is None and b.get("outputs.json") is False
            and (b.get("outputs.svg") is False or a.get(_RASTER + ".band_polygons") is False))


def _unflat(flat: dict) -> dict | None:
    """The nested settings that `_flat` made `flat` of (None: none make it)."""
    out: dict = {}
    try:
        for key, v in flat.items():
            *parents, name = key.split(".")
            d = out
            for p in parents:
                d = d.setdefault(p, {})
            if name in d:
                return None
            d[name] = v
    except (AttributeError, TypeError):  # (a part both a value and a group)
        return None
    return out


def outputs_turned_off(old: dict, new: dict) -> tuple[list[str], set[str]]:
    """(The switches of the outputs on in `old`'s settings and off in `new`'s, the settings that
    differ between them only because of it: the switches and the settings those outputs alone
    read.) Empty when either manifest has no settings."""
    a, b = old.get("settings"), new.get("settings")
    if not isinstance(a, dict) or not isinstance(b, dict):
        return [], set()
    off = [s for s in _OUTPUT_ONLY if _is_on(a, s) and not _is_on(b, s)]
    owned = [g for s in off for g in (s, *_OUTPUT_ONLY[s])]
    if _raster_only(a, b):
        off.append(_RASTER)
        owned.append(_RASTER)
    return off, {k for k in a.keys() | b.keys() if a.get(k) != b.get(k) and _within(k, owned)}


def resumes_from(old: dict | None, new: dict) -> bool:
    """Whether the frames that `old` (the folder's manifest) lists count as `new`'s run: the same
    run, or the same scene and options but for outputs turned off now (every setting that shapes
    the kept outputs' bytes is equal). The settings must be the options digested (an edited
    or older file's are not trusted: another run)."""
    if old is None:
        return False
    if old["run"] == new["run"]:
        return True
    if old["scene"] != new["scene"] or "settings" not in new:
        return False
    off, explained = outputs_turned_off(old, new)
    if not off:
        return False
    a, b = old["settings"], new["settings"]
    return all(a.get(k) == b.get(k) for k in a.keys() | b.keys() if k not in explained) \
        and all(_digests_to(_unflat(m["settings"]), m["options"]) for m in (old, new)) \
        and _digest([old["scene"], old["options"]]) == old["run"]


def _digests_to(options: dict | None, digest: str) -> bool:
    """Whether `options` (None: settings that unflatten to none) digest to `digest`."""
    return options is not None and _digest(options) == digest


def settings_changed(old: dict, new: dict, most: int = 3) -> str:
    """The settings that differ between two manifests' ('--stroke-width 1.5 there, 2 now'), the
    first `most` of them; "" when the old manifest has none (written before they were kept).
    Outputs turned off are not said beside other changes (those alone would resume)."""
    a, b = old.get("settings"), new.get("settings")
    if not isinstance(a, dict) or not isinstance(b, dict):
        return ""
    changed = [k for k in sorted(a.keys() | b.keys()) if a.get(k) != b.get(k)]
    explained = outputs_turned_off(old, new)[1]
    changed = [k for k in changed if k not in explained] or changed
    # The options of an output that one run has off (none there): said by its switch alone.
    keys: list[str] = []
    for k in changed:
        group = _off_group(a, k) or _off_group(b, k)
        k = _GROUP_SWITCH.get(group, group) if group is not None else k
        if k not in keys:
            keys.append(k)
    said = [f"{_NAMES.get(k) or _setting_name(k)} {_setting_value(_group_value(a, k))} there, "
            f"{_setting_value(_group_value(b, k))} now" for k in keys[:most]]
    changed = keys
    return "; ".join(said) + (f"; {len(changed) - most} more" if len(changed) > most else "")


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
    d = {k: manifest[k] for k in ("strokekit_run", "run", "scene", "options", "settings") if k in manifest}
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
    if "options" in parts and settings_changed(old, new):
        parts[parts.index("options")] = f"options ({settings_changed(old, new)})"
    cams = [f for f in present if f in old["frames"] and old["frames"][f] != new["frames"][f]]
    if cams:
        parts.append(f"cameras of frames {_frame_ranges(cams)}")
    what = " or ".join(x for x, p in (("another scene", "scene"), ("other options", "options"))
                       if old[p] != new[p])
    what = what or "another run"  # a run digest that its parts do not explain: an edited file
    return (f"--skip-existing: {where} holds frames of {what} ({RUN_MANIFEST} differs: {', '.join(parts) or 'run'}); {fix}")
