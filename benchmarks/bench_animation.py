"""Scenes that move: the bars of glTF node animation, skins and morph targets, measured.

- turntable: spot on a turntable before a still camera (an animated GLB made here: a node
  rotation, --frames frames at 24 fps, 3 degrees a frame) against the still spot seen from the
  cameras of the same relative motion: the lines of every frame within 0.05 px (P and R >=
  0.999, strokekit.metrics.accuracy), and M1 and M8 (tracked ends per 1000 px and the ratio to
  the fresh paths, BRIEF 3) of the default brush paths within 0.005 of the orbit's;
- noise: the same orbit's M1 and M8 with its eyes moved by 1e-12 of their distance (how much
  of the turntable's difference rounding alone makes);
- exact: every frame of the CesiumMilkTruck's animation (its wheels, 31 frames, cameras of a
  31-frame orbit) and of a skinned tube (tests/animated.py) against the static scene of that
  frame's posed vertices: the same SVG bytes, and P and R >= 0.999 at 1 px against the exact
  preset every 5th frame;
- wheels: the truck's own animation before a still camera (its side), default brush paths: M1
  of the strokes on the wheels (each stroke's object: that of most of its points) >= 0.97;
- cost: a frame's lines (LineRenderer.at + render, process CPU) of the turntable against the
  still spot from the relative orbit, of the moving truck against the truck at rest, and of a
  box turning beside a still sphere (and the sphere turning) against the scene at rest, in
  turns (one frame of each, alternating), medians over the frames, best of --repeat; a deforming
  mesh's frame (the tube, and a finer tube of about 50 k faces): posing, its BVH and its lines.

    python benchmarks/bench_animation.py [--frames 120] [--repeat 3] [--only turntable,noise,exact,wheels,cost]
        [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from animated import (  # noqa: E402
    Doc,
    skinned_tube_glb,
    sphere_and_box_glb,
    tube,
    tube_weights,
    turntable_glb,
    yaw_matrix,
)

from strokekit.camera.paths import orbit_path  # noqa: E402
from strokekit.camera.view import Camera  # noqa: E402
from strokekit.lines.renderer import LineRenderer  # noqa: E402
from strokekit.metrics.accuracy import frame_accuracy  # noqa: E402
from strokekit.metrics.coherence import sequence_metrics, wholeness  # noqa: E402
from strokekit.options import LineOptions  # noqa: E402
from strokekit.run.request import RenderRequest  # noqa: E402
from strokekit.run.sequence import render_sequence  # noqa: E402
from strokekit.scene.load import build_scene, load_scene  # noqa: E402
from strokekit.writers.svg import svg_document  # noqa: E402

MODELS = Path(__file__).resolve().parents[2] / "shared" / "models"


def relative_orbit(cam: Camera, frames: int, deg: float = 3.0) -> list[Camera]:
    """The cameras that see the still object as `cam` sees it turned by `deg` a frame about +Y."""
    out = []
    for k in range(frames):
        R = yaw_matrix(deg * k).T
        out.append(Camera(eye=tuple(R @ np.asarray(cam.eye)), target=tuple(R @ np.asarray(cam.target)),
                          up=tuple(R @ np.asarray(cam.up)), fov_y=cam.fov_y, width=cam.width, height=cam.height))
    return out


def spot_files(folder: Path, frames: int) -> tuple[Path, Path]:
    spot = load_scene(MODELS / "spot.obj")
    V = spot.vertices - spot.center
    return (turntable_glb(folder / "turntable.glb", V, spot.faces, frames=frames),
            turntable_glb(folder / "still.glb", V, spot.faces, frames=frames, animated=False))


def brush_metrics(scene, cams) -> dict:
    tracked = [f.strokes for f in render_sequence(scene, cams)]
    fresh = [f.strokes for f in render_sequence(scene, cams, RenderRequest(strokes="brush", coherence="none"))]
    _, m = sequence_metrics(tracked)
    _, m8 = wholeness(tracked, fresh)
    return {"M1": m["M1"], "M8": m8["M8"], "M8_fresh": m8["M8_fresh"], "M8_ratio": m8["M8_ratio"]}


def turntable(folder: Path, frames: int) -> dict:
    turn, still = spot_files(folder, frames)
    s = load_scene(turn)
    cam = orbit_path(*s.framing()[:2], 1, elevation=20.0).cameras[0]
    cams_t, cams_o = [cam] * frames, relative_orbit(cam, frames)
    lines = RenderRequest(strokes="lines", coherence="none")
    a = [f.lines for f in render_sequence(turn, cams_t, lines)]
    b = [f.lines for f in render_sequence(still, cams_o, lines)]
    acc = [frame_accuracy(x, y, tols=(0.05,)) for x, y in zip(a, b)]
    P = min(x.precision[0.05] for x in acc)
    R = min(x.recall[0.05] for x in acc)
    mt, mo = brush_metrics(turn, cams_t), brush_metrics(still, cams_o)
    d = {k: abs(mt[k] - mo[k]) for k in mt}
    ok = P >= 0.999 and R >= 0.999 and d["M1"] <= 0.005 and d["M8"] <= 0.005 and d["M8_ratio"] <= 0.005
    return {"frames": frames, "min_P@0.05": P, "min_R@0.05": R, "turntable": mt, "orbit": mo, "diff": d, "pass": ok}


def orbit_noise(folder: Path, frames: int, runs: int = 3) -> dict:
    """How far the relative orbit's own brush-path M1 and M8 move when its eyes move by j * 1e-12
    of their distance (j = 1..runs): the rounding the turntable's cameras differ by."""
    _, still = spot_files(folder, frames)
    cam = orbit_path(*load_scene(still).framing()[:2], 1, elevation=20.0).cameras[0]
    base = brush_metrics(still, relative_orbit(cam, frames))
    out = []
    for j in range(1, runs + 1):
        cams = [replace(c, eye=tuple(np.asarray(c.eye) * (1 + 1e-12 * j))) for c in relative_orbit(cam, frames)]
        m = brush_metrics(still, cams)
        out.append({k: abs(m[k] - base[k]) for k in m})
    return {"frames": frames, "orbit": base, "moved_by": out}


def static_of(scene, t: float):
    m = scene.motion
    return build_scene(m.file_vertices_at(0, t), m.file_faces, m.file_face_object, m.file_face_material,
                       objects=scene.objects, materials=scene.materials, source=scene.source)


def exact_frames(scene, cams: list[Camera], frames: int) -> dict:
    opts, exact = LineOptions(), LineOptions.preset("exact")
    base = LineRenderer(scene, opts)
    same, worst_p, worst_r = 0, 1.0, 1.0
    for k in range(frames):
        t, cam = k / 24, cams[k % len(cams)]
        drawn = base.at(t).render(cam, k + 1)
        ref = static_of(scene, t)
        same += svg_document(drawn, cam.width, cam.height, opts.layers) == svg_document(
            LineRenderer(ref, opts).render(cam, k + 1), cam.width, cam.height, opts.layers)
        if k % 5 == 0:
            a = frame_accuracy(drawn, LineRenderer(ref, exact).render(cam, k + 1), tols=(1.0,))
            worst_p, worst_r = min(worst_p, a.precision[1.0]), min(worst_r, a.recall[1.0])
    return {"frames": frames, "same_svg": same, "min_P@1": worst_p, "min_R@1": worst_r,
            "pass": same == frames and worst_p >= 0.999 and worst_r >= 0.999}


def exact(folder: Path) -> dict:
    truck = load_scene(MODELS / "CesiumMilkTruck.glb")
    tube_s = load_scene(skinned_tube_glb(folder / "tube.glb"))
    return {"truck": exact_frames(truck, orbit_path(*truck.framing()[:2], 31).cameras, 31),
            "tube": exact_frames(tube_s, orbit_path(*tube_s.framing()[:2], 25).cameras, 25)}


def stroke_objects(st) -> np.ndarray:
    """(S,) each stroke's object: the object of most of its points."""
    obj, _ = st.pose.object_points(st.surface, st.face)
    out = np.full(len(st), -1)
    for s in range(len(st)):
        o = obj[st.stroke(s)]
        o = o[o >= 0]
        if len(o):
            out[s] = np.bincount(o).argmax()
    return out


def wheels() -> dict:
    truck = load_scene(MODELS / "CesiumMilkTruck.glb")
    cam = orbit_path(*truck.framing()[:2], 1).cameras[0]  # (azimuth 0: the truck's side)
    frames = [f.strokes for f in render_sequence(truck, [cam] * 31)]
    wheel = [k for k, n in enumerate(truck.objects) if n == "Wheels"]
    sel = [f.select(np.isin(stroke_objects(f), wheel)) for f in frames]
    _, m = sequence_metrics(sel)
    _, all_m = sequence_metrics(frames)
    return {"frames": 31, "wheel_M1": m["M1"], "wheel_matched_px": m["matched_px"], "all_M1": all_m["M1"],
            "pass": m["M1"] >= 0.97}


def cpu_frame(renderer: LineRenderer, t: float | None, cam: Camera) -> float:
    t0 = time.process_time()
    (renderer.at(t) if t is not None else renderer).render(cam)
    return time.process_time() - t0


def in_turns(a: LineRenderer, b: LineRenderer, frames: list[tuple], repeat: int) -> tuple[float, float]:
    """Medians over the frames of a's and b's CPU seconds a frame (best of `repeat` each),
    one frame of each in turn. frames: (time or None, camera of a, camera of b). Each repeat
    of a moving frame is at a time of its own (t + 1e-4 s each), so that it poses its scene
    again (a pose the same as the last one's is not posed again)."""
    ta, tb = [], []
    for t, ca, cb in frames:
        ta.append(min(cpu_frame(a, None if t is None else t + 1e-4 * r, ca) for r in range(repeat)))
        tb.append(min(cpu_frame(b, None, cb) for _ in range(repeat)))
    return float(np.median(ta)), float(np.median(tb))


def fine_tube(folder: Path) -> Path:
    """A skinned tube of about 50 k faces (160 rings of 160 sides), bent as the small one."""
    V, F = tube(rings=160, sides=160)
    d = Doc()
    joints = np.zeros((len(V), 4), np.uint16)
    joints[:, 1] = 1
    w = np.zeros((len(V), 4))
    w[:, :2] = tube_weights(V)
    import pygltflib

    ja, wa = d.accessor(joints, "VEC4", component=5123), d.accessor(w, "VEC4")
    m = d.mesh(V, F, JOINTS_0=ja, WEIGHTS_0=wa)
    root = d.node(name="root")
    mid = d.node(parent=root, name="middle", translation=[0.0, 2.0, 0.0])
    ibm = np.stack([np.eye(4), np.eye(4)])
    ibm[1, 1, 3] = -2.0
    d.g.skins.append(pygltflib.Skin(joints=[root, mid], inverseBindMatrices=d.accessor(
        ibm.transpose(0, 2, 1).reshape(2, 16), "MAT4")))
    d.node(mesh=m, skin=0, name="tube")
    k = np.arange(25)
    from animated import bend_quat

    d.animate([(mid, "rotation", k / 24, [bend_quat(60.0 * i / 24) for i in k])])
    return d.save(folder / "fine_tube.glb")


def cost(folder: Path, frames: int, repeat: int) -> dict:
    out = {}
    turn, still = spot_files(folder, frames)
    ts, ss = load_scene(turn), load_scene(still)
    cam = orbit_path(*ts.framing()[:2], 1, elevation=20.0).cameras[0]
    rt, rs = LineRenderer(ts, LineOptions()), LineRenderer(ss, LineOptions())
    orbit = relative_orbit(cam, frames)
    ks = range(0, frames, max(1, frames // 24))
    a, b = in_turns(rt, rs, [(k / 24, cam, orbit[k]) for k in ks], repeat)
    out["turntable spot"] = {"moving_ms": 1e3 * a, "still_ms": 1e3 * b, "added": a / b - 1}
    truck = load_scene(MODELS / "CesiumMilkTruck.glb")
    rest = build_scene(truck.motion.file_vertices, truck.motion.file_faces, truck.motion.file_face_object,
                       truck.motion.file_face_material, objects=truck.objects, materials=truck.materials)
    cams = orbit_path(*truck.framing()[:2], 8).cameras
    a, b = in_turns(LineRenderer(truck, LineOptions()), LineRenderer(rest, LineOptions()),
                    [(k / 24, cams[k % 8], cams[k % 8]) for k in range(1, 31)], repeat)
    out["truck wheels"] = {"moving_ms": 1e3 * a, "still_ms": 1e3 * b, "added": a / b - 1}
    for moving in ("box", "sphere"):  # a small object turning beside a still one of 5120 faces, and the other way
        s = load_scene(sphere_and_box_glb(folder / f"{moving}.glb", moving))
        cams = orbit_path(*s.framing()[:2], 8, elevation=20.0).cameras
        a, b = in_turns(LineRenderer(s, LineOptions()), LineRenderer(static_of(s, 0.0), LineOptions()),
                        [(k / 48, cams[k % 8], cams[k % 8]) for k in range(1, 24)], repeat)
        out[f"{moving} turning"] = {"moving_ms": 1e3 * a, "still_ms": 1e3 * b, "added": a / b - 1}
    for name, path in (("skinned tube", skinned_tube_glb(folder / "tube.glb")), ("fine skinned tube", fine_tube(folder))):
        s = load_scene(path)
        r = LineRenderer(s, LineOptions())
        cam = orbit_path(*s.framing()[:2], 1).cameras[0]
        pose, lines = [], []
        for k in range(1, 25):
            t0 = time.process_time()
            posed = r.at(k / 24 + 1e-3 * repeat)
            t1 = time.process_time()
            posed.render(cam)
            t2 = time.process_time()
            pose.append(t1 - t0)
            lines.append(t2 - t1)
        still = LineRenderer(static_of(s, 0.5), LineOptions())
        sl = [min(cpu_frame(still, None, cam) for _ in range(repeat)) for _ in range(5)]
        out[name] = {"faces": int(len(s.faces)), "pose_and_bvh_ms": 1e3 * float(np.median(pose)),
                     "lines_ms": 1e3 * float(np.median(lines)), "still_lines_ms": 1e3 * float(np.median(sl))}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=120)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--only", default="turntable,exact,wheels,cost")
    ap.add_argument("--json", type=Path, default=None)
    a = ap.parse_args()
    only = a.only.split(",")
    res = {}
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        if "turntable" in only:
            res["turntable"] = turntable(folder, a.frames)
            print("turntable", json.dumps(res["turntable"], indent=1), flush=True)
        if "noise" in only:
            res["noise"] = orbit_noise(folder, a.frames)
            print("noise", json.dumps(res["noise"], indent=1), flush=True)
        if "exact" in only:
            res["exact"] = exact(folder)
            print("exact", json.dumps(res["exact"], indent=1), flush=True)
        if "wheels" in only:
            res["wheels"] = wheels()
            print("wheels", json.dumps(res["wheels"], indent=1), flush=True)
        if "cost" in only:
            res["cost"] = cost(folder, min(a.frames, 48), a.repeat)
            print("cost", json.dumps(res["cost"], indent=1), flush=True)
    if a.json:
        a.json.write_text(json.dumps(res, indent=1) + "\n")


if __name__ == "__main__":
    main()
