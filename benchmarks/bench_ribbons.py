"""What glTF ribbons add per frame: ribbon geometry and the whole GLB (ribbons + document + bytes).

Bunny (or --model), orbit camera, 1024 x 1024, default line options; each frame's strokes are
computed once, then ribbons / GLB are timed `--repeat` times (median). Target: GLB <= 10 ms per
frame for the bunny.

    python benchmarks/bench_ribbons.py [--model PATH] [--frames 12] [--repeat 7] [--space world]
    python benchmarks/bench_ribbons.py --frames 4 --repeat 1 --blender /tmp/ribbons_blender

--blender DIR also writes frame_0001.glb and sequence.glb there and imports both in Blender
(`blender -b`, io_scene_gltf2), printing the objects, the camera and which frame node is visible
on each frame, and renders each frame (Cycles) to DIR/blender_*.png.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import time
from pathlib import Path

import numpy as np

from strokekit.camera.paths import orbit_path
from strokekit.lines.renderer import LineRenderer
from strokekit.options import LineOptions
from strokekit.ribbons.brushes import get_brush
from strokekit.ribbons.mesh import build_ribbons
from strokekit.scene.load import load_scene
from strokekit.writers.gltf import GltfOptions, glb_for_frame, glb_for_sequence

ROOT = Path(__file__).resolve().parents[1]


def timed(fn, repeat: int) -> tuple[float, object]:
    ts, out = [], None
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        ts.append(time.perf_counter() - t)
    return statistics.median(ts), out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default=str(ROOT.parent / "shared" / "models" / "stanford-bunny.obj"))
    ap.add_argument("--frames", type=int, default=12)
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--space", default="world", choices=["world", "image"])
    ap.add_argument("--brush", default="ink")
    ap.add_argument("--blender", metavar="DIR", help="also check that Blender imports the GLBs (writes DIR)")
    a = ap.parse_args()

    scene = load_scene(a.model)
    path = orbit_path(scene.center, scene.radius, a.frames, width=1024, height=1024)
    lr = LineRenderer(scene, LineOptions())
    opts = GltfOptions(space=a.space, brush=a.brush)
    ropts = opts.ribbon_options(get_brush(opts.brush))
    glb_for_frame(lr.render(path.cameras[0], 1), None, opts)  # warm-up: brush PNG, imports

    print(f"model {Path(a.model).name}: {len(scene.faces)} faces, {a.frames} frames, 1024 x 1024, "
          f"space {a.space}, brush {a.brush}, median of {a.repeat} runs per frame")
    print(f"{'frame':>5} {'strokes':>7} {'points':>7} {'length px':>9} {'verts':>7} {'tris':>7} "
          f"{'ribbons ms':>10} {'GLB ms':>7} {'GLB KB':>7}")
    rib_ms, glb_ms, all_strokes = [], [], []
    for i, cam in enumerate(path.cameras):
        s = lr.render(cam, i + 1)
        all_strokes.append(s)
        tr, mesh = timed(lambda s=s, cam=cam: build_ribbons(s, cam, ropts), a.repeat)
        tg, data = timed(lambda s=s, cam=cam: glb_for_frame(s, cam, opts), a.repeat)
        rib_ms.append(tr * 1e3)
        glb_ms.append(tg * 1e3)
        print(f"{i + 1:>5} {len(s):>7} {len(s.points):>7} {s.lengths.sum():>9.0f} {len(mesh.positions):>7} "
              f"{len(mesh.indices):>7} {tr * 1e3:>10.2f} {tg * 1e3:>7.2f} {len(data) / 1024:>7.1f}")
    print(f"median ribbons {np.median(rib_ms):.2f} ms, median GLB (ribbons + writing) {np.median(glb_ms):.2f} ms "
          f"per frame (target <= 10 ms)")
    ts, data = timed(lambda: glb_for_sequence(all_strokes, opts), max(1, a.repeat // 2))
    print(f"sequence GLB of {a.frames} frames: {ts * 1e3:.1f} ms ({ts * 1e3 / a.frames:.2f} ms per frame), "
          f"{len(data) / 1024:.0f} KB")
    if a.blender:
        blender_check(Path(a.blender), all_strokes, opts, data)


_BLENDER_SCRIPT = r"""
import math, sys
import numpy  # Debian's blender needs python3-numpy for its glTF importer (apt-get install python3-numpy)
if not hasattr(numpy, "bool"):  # Debian's Blender 3.4.1 importer still uses np.bool (gone in numpy 1.24)
    numpy.bool = bool
import bpy
out, glb, frames = sys.argv[-3], sys.argv[-2], [int(x) for x in sys.argv[-1].split(",")]
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.import_scene.gltf(filepath=glb)
sc = bpy.context.scene
cam = [o for o in sc.objects if o.type == "CAMERA"][0]
meshes = [o for o in sc.objects if o.type == "MESH"]
print("BLENDER objects", [(o.name, o.type) for o in sc.objects])
print("BLENDER camera", cam.data.type, "fov_y %.3f" % math.degrees(cam.data.angle_y),
      tuple(round(x, 4) for x in cam.location))
for m in meshes:
    print("BLENDER mesh", m.name, len(m.data.vertices), "verts", len(m.data.polygons), "tris",
          [s.material.name for s in m.material_slots], [u.name for u in m.data.uv_layers])
sc.camera = cam
sc.render.resolution_x = sc.render.resolution_y = 1024
sc.render.engine = "CYCLES"; sc.cycles.samples = 8; sc.cycles.use_denoising = False
w = bpy.data.worlds.new("white"); sc.world = w; w.use_nodes = True
w.node_tree.nodes["Background"].inputs[0].default_value = (1, 1, 1, 1)
sc.view_settings.view_transform = "Standard"
for f in frames:
    sc.frame_set(f)
    print("BLENDER frame", f, "visible", [m.name for m in meshes if m.matrix_world.to_scale()[0] > 0.5],
          "camera", tuple(round(x, 4) for x in cam.matrix_world.translation))
    sc.render.filepath = out + "_%d.png" % f
    bpy.ops.render.render(write_still=True)
"""


def blender_env() -> dict:
    """The environment to start Blender in: Debian's Blender finds its Python home from PATH, so
    pyenv / virtualenv interpreters are kept out of it."""
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYENV", "VIRTUAL_ENV", "PYTHONHOME"))}
    env["PATH"] = os.pathsep.join(p for p in env.get("PATH", "").split(os.pathsep)
                                  if ".pyenv" not in p and "venv" not in p)
    return env


def blender_check(out: Path, frames: list, opts: GltfOptions, seq: bytes) -> None:
    exe = shutil.which("blender")
    if exe is None:
        print("blender not found: skipping the import check")
        return
    out.mkdir(parents=True, exist_ok=True)
    (out / "frame_0001.glb").write_bytes(glb_for_frame(frames[0], frames[0].camera, opts))
    (out / "sequence.glb").write_bytes(seq)
    script = out / "import_check.py"
    script.write_text(_BLENDER_SCRIPT)
    nums = ",".join(str(int(f.frame)) for f in frames)
    env = blender_env()
    for name, fr in (("frame_0001.glb", str(int(frames[0].frame))), ("sequence.glb", nums)):
        r = subprocess.run([exe, "-b", "--python-exit-code", "1", "--python", str(script), "--", str(out / f"blender_{Path(name).stem}"),
                            str(out / name), fr], capture_output=True, text=True, timeout=600, env=env)
        # Our lines, and whatever the importer warns or fails about.
        lines = [ln for ln in (r.stdout + r.stderr).splitlines()
                 if ln.startswith(("BLENDER", "Saved")) or any(w in ln for w in ("Warning", "WARNING", "Error", "ERROR"))]
        print(f"--- Blender import of {name} (exit {r.returncode})")
        print("\n".join(lines) if lines else r.stdout[-2000:] + r.stderr[-2000:])


if __name__ == "__main__":
    main()
