"""Benchmark and measurements for smooth contours, suggestive contours and intersection lines.

    python benchmarks/bench_line_types.py [--frames 8] [--repeats 3] [--gallery /tmp/gallery_suggestive.png]

Prints tables:
1. time per frame on the bunny (1024 x 1024 orbit): lines only (mesh contours, default kinds)
   vs contours="smooth", vs + suggestive, vs + intersection; medians over frames x repeats;
2. sphere contour error against the analytic circle, smooth vs mesh contour (px at 1024 x 1024);
3. share of smooth contour length wrongly reported hidden (sphere: analytic truth, everything
   visible; torus and bunny: where a visible exact mesh contour (BRIEF 2) runs within 1 px on
   screen and 2 face sizes in space), with and without the ray lift;
4. bunny smooth contour screen-tangent reversals between linked segments, without and with
   cusp splitting;
5. coherence metrics (BRIEF 3, strokekit.metrics.coherence, Kalnins tracking) of mesh vs smooth contours
   on a 3 degree/frame orbit of spot and the bunny;
6. normals split at creases: a box on a slab drawn with contours=smooth vs mesh (largest point
   difference, px), a cylinder's smooth contour vs its analytic tangent lines and the number of
   strokes of its outline, and the drawn length per object of samples/still_life.glb.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from strokekit.camera.paths import orbit_path  # noqa: E402
from strokekit.camera.view import Camera  # noqa: E402
from strokekit.lines import contours as C  # noqa: E402
from strokekit.lines.contours import smooth_contour_edges  # noqa: E402
from strokekit.lines.facing import FrameView  # noqa: E402
from strokekit.lines.intersections import intersection_edges  # noqa: E402
from strokekit.lines.renderer import LineRenderer  # noqa: E402
from strokekit.metrics.accuracy import screen_reversals, smooth_contour_wrongly_hidden  # noqa: E402
from strokekit.model import KINDS  # noqa: E402
from strokekit.options import DEFAULT_KINDS, LineOptions  # noqa: E402
from strokekit.scene.load import build_scene, load_scene  # noqa: E402

MODELS = Path(__file__).resolve().parents[2] / "shared" / "models"


def torus_scene(R=1.0, r=0.35, nu=160, nv=64):
    u = np.linspace(0, 2 * np.pi, nu, endpoint=False)
    v = np.linspace(0, 2 * np.pi, nv, endpoint=False)
    U, Vv = np.meshgrid(u, v, indexing="ij")
    P = np.stack([(R + r * np.cos(Vv)) * np.cos(U), (R + r * np.cos(Vv)) * np.sin(U), r * np.sin(Vv)], -1)
    i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    a, b = i * nv + j, ((i + 1) % nu) * nv + j
    c, d = ((i + 1) % nu) * nv + (j + 1) % nv, i * nv + (j + 1) % nv
    F = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    return build_scene(P.reshape(-1, 3), F)


def sphere_scene(sub):
    import trimesh

    m = trimesh.creation.icosphere(subdivisions=sub, radius=1.0)
    return build_scene(m.vertices, m.faces)


def sample(a, b, n):
    s = np.linspace(0, 1, n)[:, None, None]
    return (a[None] * (1 - s) + b[None] * s).reshape(-1, a.shape[1])


def time_renders(scene, cams, configs, repeats):
    """Median process CPU time per frame (s) of each LineOptions in `configs` (dict name ->
    options). Configurations are interleaved frame by frame so that load from other processes
    on the shared machine hits them alike; CPU time is steadier than wall time there."""
    rs = {k: LineRenderer(scene, o) for k, o in configs.items()}
    for r in rs.values():
        r.render(cams[0])  # warm the per-scene caches
    ts = {k: [] for k in configs}
    for _ in range(repeats):
        for cam in cams:
            for k, r in rs.items():
                t = time.process_time()
                r.render(cam)
                ts[k].append(time.process_time() - t)
    return {k: float(np.median(v)) for k, v in ts.items()}


def sphere_errors(sub, eye=np.array([0.3, 0.5, 4.0])):
    sc = sphere_scene(sub)
    cam = Camera(eye=tuple(eye), target=(0, 0, 0), fov_y=40, width=1024, height=1024)
    from scipy.spatial import cKDTree

    d = np.linalg.norm(eye)
    u = -eye / d
    a1 = np.cross(u, [0.0, 1.0, 0.0])
    a1 /= np.linalg.norm(a1)
    a2 = np.cross(u, a1)
    th = np.linspace(0, 2 * np.pi, 400_000, endpoint=False)
    circ = eye / d ** 2 + np.sqrt(1 - 1 / d ** 2) * (np.cos(th)[:, None] * a1 + np.sin(th)[:, None] * a2)
    tree = cKDTree(cam.project(circ)[0])
    st = LineRenderer(sc, LineOptions(contours="smooth")).render(cam)
    sm = []
    for s in range(len(st)):
        p = st.points[st.stroke(s)]
        sm.append(sample(p[:-1], p[1:], 9))
    e_s, _ = tree.query(np.concatenate(sm))
    E = sc.edges[FrameView(sc, cam).silhouettes]
    e_m, _ = tree.query(sample(cam.project(sc.vertices[E[:, 0]])[0], cam.project(sc.vertices[E[:, 1]])[0], 9))
    return len(sc.faces), e_s.max(), e_s.mean(), e_m.max(), e_m.mean()


def wrongly_hidden(scene, cams, analytic_all_visible=False, lift=True):
    """(wrongly hidden share, visible share farther than 2 px from any visible mesh contour)."""
    return smooth_contour_wrongly_hidden(scene, cams, lift=lift, all_visible=analytic_all_visible)


def reversals(scene, cam, split):
    fe = smooth_contour_edges(FrameView(scene, cam), split_cusps=split)
    return screen_reversals(fe, cam), int((fe.va < 0).sum())


def gallery(path, thresholds=(0.05, 50.0, 500.0), size=512):
    """Strokes of cow and bunny with smooth contours (black) and suggestive contours (red), one row
    per view, one column per derivative threshold."""
    from PIL import Image, ImageDraw

    colors = {"smooth_contour": (0, 0, 0), "silhouette": (0, 0, 0), "suggestive": (200, 30, 30),
              "border": (30, 60, 160)}
    tiles = []
    for name in ("cow.obj", "stanford-bunny.obj"):
        sc = load_scene(MODELS / name)
        for k in range(3):
            a, el = 2 * np.pi * k / 3 + 0.6, 0.25
            eye = sc.center + sc.radius * 2.6 * np.array([np.sin(a) * np.cos(el), np.sin(el), np.cos(a) * np.cos(el)])
            cam = Camera(eye=tuple(eye), target=tuple(sc.center), fov_y=40, width=size, height=size)
            row = []
            for t in thresholds:
                opts = LineOptions(kinds=("silhouette", "suggestive", "border"), contours="smooth",
                                   suggestive_derivative_threshold=t)
                st = LineRenderer(sc, opts).render(cam)
                im = Image.new("RGB", (size, size), "white")
                dr = ImageDraw.Draw(im)
                for s in range(len(st)):
                    p = st.points[st.stroke(s)]
                    if len(p) > 1:
                        dr.line([tuple(x) for x in p], fill=colors.get(KINDS[st.kind[s]], (0, 0, 0)), width=2)
                dr.text((8, 8), f"{name}  suggestive threshold {t:g}", fill=(0, 0, 0))
                row.append(im)
            tiles.append(row)
    g = Image.new("RGB", (size * len(thresholds), size * len(tiles)), "white")
    for i, row in enumerate(tiles):
        for j, im in enumerate(row):
            g.paste(im, (j * size, i * size))
    g.save(path)
    return g.size


def split_normal_checks():
    import trimesh

    def box(ext, c):
        m = trimesh.creation.box(extents=ext)
        m.apply_translation(c)
        return np.asarray(m.vertices), np.asarray(m.faces)

    (v1, f1), (v2, f2) = box((1.0, 0.8, 1.2), (0.0, 0.4, 0.0)), box((4.0, 0.2, 3.0), (0.0, -0.1, 0.0))
    sc = build_scene(np.vstack([v1, v2]), np.vstack([f1, f2 + len(v1)]))
    worst = 0.0
    for eye in ((2.5, 2.0, 3.5), (-3.0, 1.2, 1.0), (0.5, 4.0, -2.0)):
        cam = Camera(eye=eye, target=(0.0, 0.3, 0.0), fov_y=40, width=1024, height=1024)
        pts = {}
        for mode in ("mesh", "smooth"):
            st = LineRenderer(sc, LineOptions(contours=mode)).render(cam)
            pts[mode] = st.points
        from scipy.spatial import cKDTree

        a, b = pts["mesh"], pts["smooth"]
        worst = max(worst, cKDTree(a).query(b)[0].max(), cKDTree(b).query(a)[0].max(), abs(len(a) - len(b)))
    print(f"   box on slab, 3 views: largest point distance smooth vs mesh strokes {worst:.2e} px")
    print(f"   {'cylinder sections':>18s} {'tangent line err max px':>24s} {'outline strokes':>16s} {'closed':>7s}")
    R, H = 0.5, 2.0
    eye = np.array([3.0, 1.5, 3.0])
    for sections in (32, 64, 128):
        m = trimesh.creation.cylinder(radius=R, height=H, sections=sections)
        cy = build_scene(np.asarray(m.vertices), np.asarray(m.faces))
        cam = Camera(eye=tuple(eye), target=(0, 0, 0), up=(0, 0, 1), fov_y=40, width=1024, height=1024)
        fe = smooth_contour_edges(FrameView(cy, cam))
        side = np.abs(np.abs(fe.a[:, 2]) - H / 2) > 1e-12
        side |= np.abs(np.abs(fe.b[:, 2]) - H / 2) > 1e-12
        rho, base = np.hypot(eye[0], eye[1]), np.arctan2(eye[1], eye[0])
        err = np.inf * np.ones(2 * side.sum())
        ends = np.vstack([cam.project(fe.a[side])[0], cam.project(fe.b[side])[0]])
        for ph in (base + np.arccos(R / rho), base - np.arccos(R / rho)):
            L = cam.project(np.array([[R * np.cos(ph), R * np.sin(ph), -H / 2], [R * np.cos(ph), R * np.sin(ph), H / 2]]))[0]
            d = L[1] - L[0]
            t = np.clip((ends - L[0]) @ d / (d @ d), 0, 1)
            err = np.minimum(err, np.linalg.norm(ends - (L[0] + t[:, None] * d), axis=1))
        st = LineRenderer(cy, LineOptions(contours="smooth", kinds=("silhouette",))).render(cam)
        print(f"   {sections:18d} {err.max():24.4f} {len(st):16d} {str(bool(np.allclose(st.points[0], st.points[-1]))):>7s}")
    sample = Path(__file__).resolve().parents[1] / "samples"
    if (sample / "still_life.glb").exists():
        from strokekit.camera.paths import load_camera_path

        sl = load_scene(sample / "still_life.glb")
        cam = load_camera_path(sample / "orbit.json").cameras[0]
        print(f"   still_life frame 1, drawn length per object (px): {'object':8s} {'mesh':>8s} {'smooth':>8s}")
        lens = {}
        for mode in ("mesh", "smooth"):
            st = LineRenderer(sl, LineOptions(contours=mode)).render(cam)
            sop = st.stroke_of_point
            seg = np.linalg.norm(np.diff(st.points, axis=0), axis=1)
            same = sop[1:] == sop[:-1]
            obj = sl.face_object[st.face[1:]]
            lens[mode] = np.bincount(obj[same], seg[same], minlength=len(sl.objects))
        for o, name in enumerate(sl.objects):
            print(f"   {'':49s} {name:8s} {lens['mesh'][o]:8.1f} {lens['smooth'][o]:8.1f}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--frames", type=int, default=8)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--coherence-frames", type=int, default=30, help="0 to skip section 5")
    ap.add_argument("--gallery", default=None, help="write the suggestive contour gallery PNG here")
    args = ap.parse_args()
    bunny_path = MODELS / "stanford-bunny.obj"
    if not bunny_path.exists():
        sys.exit(f"{bunny_path}: shared models absent")
    bunny = load_scene(bunny_path)
    path = orbit_path(bunny.center, bunny.radius, args.frames)
    cams = list(path.cameras)

    print(f"1. bunny ({len(bunny.faces)} faces), {args.frames} orbit frames x {args.repeats}, 1024 x 1024, median CPU ms/frame")
    t = time.perf_counter()
    n_int = len(intersection_edges(load_scene(bunny_path)))
    t_int = time.perf_counter() - t
    med = time_renders(bunny, cams, {
        "lines only (mesh contours)": LineOptions(),
        "contours=smooth": LineOptions(contours="smooth"),
        "contours=smooth + suggestive": LineOptions(contours="smooth", kinds=DEFAULT_KINDS + ("suggestive",)),
        "mesh + intersection (after setup)": LineOptions(kinds=DEFAULT_KINDS + ("intersection",)),
    }, args.repeats)
    rows = list(med.items())
    base = rows[0][1]
    print(f"   {'configuration':40s} {'ms':>8s} {'vs lines only':>14s}")
    for name, v in rows:
        print(f"   {name:40s} {1e3 * v:8.1f} {100 * (v / base - 1):+13.0f}%")
    print(f"   intersection setup (BVH + narrow phase, once per scene, incl. load): {1e3 * t_int:.0f} ms, "
          f"{n_int} self-intersection segments")

    print("\n2. sphere contour vs analytic circle, px at 1024 x 1024 (eye (0.3, 0.5, 4), fov 40)")
    print(f"   {'faces':>7s} {'smooth max':>11s} {'smooth mean':>12s} {'mesh max':>9s} {'mesh mean':>10s}")
    for sub in (4, 5, 6):
        f, a, b, c, d = sphere_errors(sub)
        print(f"   {f:7d} {a:11.4f} {b:12.4f} {c:9.4f} {d:10.4f}")

    print(f"\n3. smooth contour wrongly reported hidden (share of length; lift gains normal "
          f"{C.LIFT_GAIN}, view {C.VIEW_LIFT_GAIN})")
    sph = sphere_scene(5)
    tor = torus_scene()

    def cams_of(sc):
        p = orbit_path(sc.center, sc.radius, args.frames, elevation=25.0)
        return list(p.cameras)

    print(f"   {'model':20s} {'wrongly hidden':>15s} {'(no lift)':>10s} {'visible >2px from mesh contour':>31s}")
    for name, sc, analytic in (("sphere (analytic)", sph, True), ("torus", tor, False), ("bunny", bunny, False)):
        w, far = wrongly_hidden(sc, cams_of(sc), analytic, lift=True)
        w0, _ = wrongly_hidden(sc, cams_of(sc), analytic, lift=False)
        print(f"   {name:20s} {100 * w:14.4f}% {100 * w0:9.3f}% {100 * far:30.3f}%")

    print("\n4. bunny smooth contour: screen reversals between linked segments (no split / cusp split)")
    for k, cam in enumerate(cams[:4]):
        r0, _ = reversals(bunny, cam, False)
        r1, nc = reversals(bunny, cam, True)
        print(f"   frame {k + 1}: {r0:4d} reversals unsplit -> {r1} after splitting at {nc} detected cusps")

    if args.coherence_frames > 1:
        from strokekit.metrics.coherence import sequence_metrics
        from strokekit.tracking.options import TrackingOptions
        from strokekit.tracking.tracker import Tracker

        print(f"\n5. coherence, {args.coherence_frames}-frame orbit at 3 deg/frame, kalnins tracking")
        print(f"   {'model':10s} {'contours':8s} {'M1':>6s} {'M2 med':>7s} {'M4 med':>7s} {'M4 p95':>7s} {'M5':>6s}")
        for name in ("spot.obj", "stanford-bunny.obj"):
            sc = load_scene(MODELS / name)
            orbit = orbit_path(sc.center, sc.radius, args.coherence_frames, degrees_per_frame=3.0)
            for contours in ("mesh", "smooth"):
                r = LineRenderer(sc, LineOptions(contours=contours))
                tr = Tracker(TrackingOptions(method="kalnins"))
                out = [tr.step(r.render(c, k + 1)) for k, c in enumerate(orbit.cameras)]
                _, ov = sequence_metrics(out)
                print(f"   {name.split('.')[0]:10s} {contours:8s} {ov['M1']:6.3f} {ov['M2_median']:7.4f} "
                      f"{ov['M4_median']:7.2f} {ov['M4_p95']:7.2f} {ov['M5']:6.3f}")

    print("\n6. normals split at creases (crease angle 60 deg), 1024 x 1024")
    split_normal_checks()

    if args.gallery:
        print(f"\ngallery: {args.gallery} {gallery(args.gallery)}")


if __name__ == "__main__":
    main()
