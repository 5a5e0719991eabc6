"""`strokekit info SCENE`: what is in a scene and what lines it can have."""

from __future__ import annotations

import click

from strokekit.options import LineOptions

from ..common import echo_json, say_warnings
from ..flags import field_option


@click.command("info", short_help="What a scene holds and which lines it can have.")
@click.argument("scene", type=click.Path())
@click.option("--json", "as_json", is_flag=True, help="Print JSON instead of text.")
@field_option(LineOptions, "crease_angle_deg")
def command(scene: str, as_json: bool, crease_angle: float | None):
    """Meshes, faces, materials, bounds, borders and non-manifold edges, and the line kinds present."""
    from strokekit.camera.gltf import gltf_camera_count
    from strokekit.scene.load import load_scene

    # (render's check and default: a crease angle in (0, 180) degrees)
    lines = LineOptions() if crease_angle is None else LineOptions(crease_angle_deg=crease_angle)
    crease_angle = lines.crease_angle_deg
    s = load_scene(scene)
    say_warnings(s)
    d = s.summary()
    d["line_kinds"] = s.available_kinds(crease_angle)
    d["crease_edges"] = int(s.crease_mask(crease_angle).sum())
    d.pop("crease_edges_60deg", None)  # the count at --crease-angle replaces it
    if str(scene).lower().endswith((".glb", ".gltf")):
        d["cameras"] = gltf_camera_count(scene)
    if as_json:
        echo_json(d)
        return
    rows = [
        ("file", d["source"]),
        ("objects", f"{d['objects']} ({', '.join(d['object_names'][:6])}{', ...' if d['objects'] > 6 else ''})"),
        ("materials", f"{len(d['materials'])} ({', '.join(d['materials'][:6])})"),
        ("faces", f"{d['faces']} (dropped: {d['dropped_degenerate_faces']} degenerate, "
                  f"{d['dropped_duplicate_faces']} duplicate)"),
        ("vertices", f"{d['vertices_welded']} welded by position ({d['vertices_in_file']} in file)"),
        ("bounds", f"min {fmt(d['bounds_min'])}  max {fmt(d['bounds_max'])}  "
                   f"size {fmt([b - a for a, b in zip(d['bounds_min'], d['bounds_max'])])}"),
        ("edges", f"{d['edges']}: {d['border_edges']} border, {d['nonmanifold_edges']} non-manifold, "
                  f"{d['crease_edges']} crease (> {crease_angle:g} deg), {d['material_boundary_edges']} material boundary"),
        ("line kinds", ", ".join(d["line_kinds"]) or "none"),
    ]
    if d.get("cameras"):
        rows.append(("cameras", f"{d['cameras']} (render with --camera {scene})"))
    if d.get("animations"):
        rows.append(("animations", "; ".join(
            f"{a['index']}{' (' + a['name'] + ')' if a['name'] else ''}: {a['seconds']:.4g} s"
            f"{'' if a['moves'] else ', moves no object'}" for a in d["animations"])))
    w = max(len(k) for k, _ in rows)
    for k, v in rows:
        click.echo(f"{k:<{w}}  {v}")


def fmt(v) -> str:
    # 7 digits: a unit box 1e6 away from the origin reads (1000000, ...) to (1000001, ...), not
    # 1e+06 at both ends.
    return "(" + ", ".join(f"{x:.7g}" for x in v) + ")"
