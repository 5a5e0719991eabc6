"""The line styles' bars, measured (docs/styles.md has the numbers):

    python benchmarks/bench_styles.py formula  OUT   # JSON widths = the modifiers' formulas (sphere, bunny)
    python benchmarks/bench_styles.py ink      OUT   # the SVG drawn by cairosvg has the JSON widths' ink
    python benchmarks/bench_styles.py ribbons  OUT   # image-space ribbons' cross-section = the JSON widths
    python benchmarks/bench_styles.py coherence OUT  # noise on a 120-frame bunny orbit: width under a point
    python benchmarks/bench_styles.py cost           # lines + SVG + JSON of a bunny frame, five modifiers

Each renders with the CLI into OUT (kept, to look at) and prints one JSON line of results. The
formulas are written out here again from the frame JSON alone (points, u, surface, ids, camera,
line sets, depth range, which ends are joined): only the noise's lattice values
(strokekit.style.widths.value_noise, the noise's definition) come from the library.
"""

from __future__ import annotations

import argparse
import io
import json
import tempfile
import time
from pathlib import Path

import numpy as np
from same_bytes import strokekit  # (this folder: the CLI in a subprocess, quiet)

ROOT = Path(__file__).resolve().parents[1]
MODELS = ROOT.parent / "shared" / "models"

#: Every thickness modifier in one line set (the sample style file).
FIVE = (ROOT / "samples" / "five.toml").read_text()
NOISE = """\
[[lineset]]
name = "noise"
width = 2.0
thickness = [{{ by = "noise", amplitude = 0.3, wavelength = 30, boil = {boil} }}]
"""


def sphere(out: Path) -> Path:
    import trimesh

    f = out / "sphere.obj"
    if not f.exists():
        out.mkdir(parents=True, exist_ok=True)
        trimesh.creation.icosphere(subdivisions=5).export(f)
    return f


def write_style(out: Path, name: str, text: str) -> Path:
    out.mkdir(parents=True, exist_ok=True)
    f = out / name
    f.write_text(text)
    return f


# --- the formulas, from the JSON -----------------------------------------------------------------

def _arc(p: np.ndarray) -> np.ndarray:
    return np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))]


def _at(p: np.ndarray, s: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Points at arc lengths q of a polyline p with arc lengths s (held at the ends)."""
    return np.stack([np.interp(q, s, p[:, 0]), np.interp(q, s, p[:, 1])], 1)


def expected_widths(doc: dict) -> list[np.ndarray]:
    """Each stroke's widths by the formulas of strokekit.style.widths' docstring."""
    from strokekit.camera.view import Camera
    from strokekit.style.widths import value_noise

    cam = Camera.from_json(dict(doc["camera"]))
    P = doc["period_px"]
    sets = {s["name"]: (k, s) for k, s in enumerate(doc["linesets"])}
    strokes = doc["strokes"]
    pts = [np.asarray(s["points"], float) for s in strokes]
    joined = np.array([s.get("joined", [0, 0]) for s in strokes], bool).reshape(-1, 2)
    out = []
    for i, st in enumerate(strokes):
        p = pts[i]
        s = _arc(p)
        L = s[-1]
        _, ls = sets[st["lineset"]]
        w = np.full(len(p), ls["width"])
        for m in ls.get("thickness", []):
            if m["by"] == "along":
                unit = P if m["unit"] == "period" else 1.0
                h = m["head"] * unit * (not joined[i, 0])
                t = m["tail"] * unit * (not joined[i, 1])
                k = min(1.0, L / (h + t)) if h + t > 0 else 1.0
                h, t = h * k, t * k

                def ease(x):
                    x = np.clip(x, 0, 1)
                    return x * (2 - x)
                grow = ease(s / h) if h > 0 else np.ones(len(s))
                fade = ease((L - s) / t) if t > 0 else np.ones(len(s))
                f = m["tip"] + (1 - m["tip"]) * np.minimum(grow, fade)
            elif m["by"] == "depth":
                zn, zf = (m["near_depth"], m["far_depth"]) if m["near_depth"] is not None else doc["depth_range"]
                z = cam.depth(np.asarray(st["surface"], float))
                f = m["near"] + (m["far"] - m["near"]) * np.clip((z - zn) / (zf - zn), 0, 1)
            elif m["by"] == "curvature":
                a, b = np.minimum(m["span"], s), np.minimum(m["span"], L - s)
                c1 = p - _at(p, s, s - a)
                c2 = _at(p, s, s + b) - p
                ang = np.arctan2(np.abs(c1[:, 0] * c2[:, 1] - c1[:, 1] * c2[:, 0]), (c1 * c2).sum(1))
                ok = (a >= 0.5) & (b >= 0.5)
                kappa = np.where(ok, ang / np.where(ok, 0.5 * (a + b), 1), 0.0)
                f = m["flat"] + (m["curved"] - m["flat"]) * np.clip(kappa * m["radius"], 0, 1)
            elif m["by"] == "calligraphy":
                a, b = np.minimum(m["span"], s), np.minimum(m["span"], L - s)
                d = _at(p, s, s + b) - _at(p, s, s - a)
                theta = np.arctan2(-d[:, 1], d[:, 0])
                f = m["thin"] + (1 - m["thin"]) * np.abs(np.sin(theta - np.radians(m["angle"])))
            elif m["by"] == "noise":
                key = doc["frame"] // m["boil"] if m["boil"] else 0
                u = np.asarray(st["u"], float)
                f = 1 + m["amplitude"] * value_noise(u * P / m["wavelength"], np.full(len(u), st["id"]), m["seed"],
                                                     key)
            w = w * f
        out.append(np.maximum(w, 0.01))
    return out


def formula(out: Path) -> dict:
    style = write_style(out, "five.toml", FIVE)
    res = {}
    for name, model, extra in (("sphere", sphere(out), ["--strokes", "lines"]),
                               ("bunny lines", MODELS / "stanford-bunny.obj", ["--strokes", "lines"]),
                               ("bunny brush", MODELS / "stanford-bunny.obj", [])):
        d = out / name.replace(" ", "_")
        strokekit("render", model, "--orbit", "24", "--frames", "1-3", "--style", style, *extra, "--out", d)
        err = []
        for f in sorted(d.glob("frame_*.json")):
            doc = json.loads(f.read_text())
            want = expected_widths(doc)
            err += [np.abs(np.asarray(s["width"]) - w) for s, w in zip(doc["strokes"], want)]
        e = np.concatenate(err)
        res[name] = {"points": int(len(e)), "max_px": float(e.max()), "p99_px": float(np.percentile(e, 99))}
    return res


# --- ink ------------------------------------------------------------------------------------------------

def _alpha(svg: bytes, scale: float) -> float:
    import cairosvg
    from PIL import Image

    png = cairosvg.svg2png(bytestring=svg, scale=scale)
    return float(np.asarray(Image.open(io.BytesIO(png)).convert("RGBA"))[..., 3].sum() / 255.0 / scale ** 2)


def ink(out: Path) -> dict:
    """Every stroke drawn alone by cairosvg (its own SVG around it, 4 px a px) against the
    JSON's sum of width x length (the trapezoids between points), and against that plus the
    round caps (half discs of the end widths); and the whole SVG drawn at once (where strokes
    overlap, at joins and crossings, the ink counts once)."""
    import re

    style = write_style(out, "five.toml", FIVE)
    res = {}
    for name, model, extra in (("sphere", sphere(out), ["--strokes", "lines"]),
                               ("bunny brush", MODELS / "stanford-bunny.obj", [])):
        d = out / ("ink_" + name.replace(" ", "_"))
        strokekit("render", model, "--orbit", "24", "--frames", "2", "--style", style, *extra, "--out", d)
        doc = json.loads((d / "frame_0002.json").read_text())
        text = (d / "frame_0002.svg").read_text()
        paths = {i: body for body, i in re.findall(r'<path d="([^"]*)" id="s(\d+)"', text)}
        drawn = want = caps = 0.0
        for st in doc["strokes"]:
            p = np.asarray(st["points"], float)
            w = np.asarray(st["width"], float)
            seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
            want += float((0.5 * (w[1:] + w[:-1]) * seg).sum())
            caps += float(np.pi / 8 * (w[0] ** 2 + w[-1] ** 2))
            lo, hi = p.min(0) - w.max() - 2, p.max(0) + w.max() + 2
            size = hi - lo
            body = paths[str(st["id"])]
            attrs = 'fill="black"' if body.endswith("Z") else \
                f'fill="none" stroke="black" stroke-width="{w[0]}" stroke-linecap="round" stroke-linejoin="round"'
            svg = (f'<svg xmlns="http://www.w3.org/2000/svg" width="{size[0]:.3f}" height="{size[1]:.3f}" '
                   f'viewBox="{lo[0]:.3f} {lo[1]:.3f} {size[0]:.3f} {size[1]:.3f}"><path d="{body}" {attrs}/></svg>')
            drawn += _alpha(svg.encode(), 4.0)
        whole = _alpha((d / "frame_0002.svg").read_bytes(), 4.0)  # overlaps (joins, crossings) count once
        res[name] = {"strokes": len(doc["strokes"]), "ink_px2": drawn, "sum_w_len_px2": want, "caps_px2": caps,
                     "ratio": drawn / want, "ratio_with_caps": drawn / (want + caps), "whole_svg_px2": whole,
                     "whole_ratio": whole / want}
    return res


# --- ribbons --------------------------------------------------------------------------------------------

def ribbons(out: Path) -> dict:
    """Image-space ribbons: at the middle of every JSON segment, the ribbon's extent along the
    segment's normal (the line through the middle cut with the stroke's triangles) against the
    mean of the segment's two JSON widths. Segments next to a stroke's ends (where joins move
    them) are left out."""
    import struct

    style = write_style(out, "five.toml", FIVE)
    d = out / "ribbons"
    strokekit("render", MODELS / "stanford-bunny.obj", "--orbit", "24", "--frames", "2", "--style", style,
              "--gltf", "--ribbon-space", "image", "--out", d)
    doc = json.loads((d / "frame_0002.json").read_text())
    H = doc["height"]
    b = (d / "frame_0002.glb").read_bytes()
    n = struct.unpack("<I", b[12:16])[0]
    j = json.loads(b[20:20 + n])
    blob = b[20 + n + 8:]

    def acc(i, comps, dtype):
        a = j["accessors"][i]
        v = j["bufferViews"][a["bufferView"]]
        return np.frombuffer(blob, dtype, a["count"] * comps, v["byteOffset"]).reshape(a["count"], comps)

    tris_of = {}
    for prim in j["meshes"][0]["primitives"]:
        pos = acc(prim["attributes"]["POSITION"], 3, "<f4").astype(float)
        node_t = 0.0
        xy = np.c_[pos[:, 0] + node_t, H - pos[:, 1]]
        ia = j["accessors"][prim["indices"]]
        idx = acc(prim["indices"], 1, "<u2" if ia["componentType"] == 5123 else "<u4").ravel().reshape(-1, 3)
        ex = prim["extras"]["strokes"]
        for sid, f0, cnt in zip(ex["id"], ex["first_triangle"], ex["triangle_count"]):
            tris_of[sid] = xy[idx[f0:f0 + cnt]]
    errs = []
    for st in doc["strokes"]:
        T = tris_of.get(st["id"])
        p = np.asarray(st["points"], float)
        w = np.asarray(st["width"], float)
        if T is None or len(p) < 5:
            continue
        for k in range(2, len(p) - 3):
            a, c = p[k], p[k + 1]
            t = c - a
            L = np.linalg.norm(t)
            if L < 0.5:
                continue
            t /= L
            nrm = np.array([-t[1], t[0]])
            m = 0.5 * (a + c)
            # the line m + x nrm cut with each triangle: the x range inside it
            v = T - m
            x = v @ nrm
            y = v @ t
            lo, hi = np.inf, -np.inf
            for e0, e1 in ((0, 1), (1, 2), (2, 0)):
                y0, y1, x0, x1 = y[:, e0], y[:, e1], x[:, e0], x[:, e1]
                cross = (y0 * y1 <= 0) & (y0 != y1)
                xc = x0[cross] + (x1[cross] - x0[cross]) * (-y0[cross]) / (y1[cross] - y0[cross])
                if len(xc):
                    lo, hi = min(lo, xc.min()), max(hi, xc.max())
            if np.isfinite(lo):
                errs.append(abs((hi - lo) - 0.5 * (w[k] + w[k + 1])))
    e = np.asarray(errs)
    return {"segments": int(len(e)), "median_px": float(np.median(e)), "p95_px": float(np.percentile(e, 95)),
            "p99_px": float(np.percentile(e, 99)), "max_px": float(e.max()),
            "within_0.05": float((e <= 0.05).mean())}


# --- coherence -------------------------------------------------------------------------------------------

def coherence(out: Path, frames: int = 120) -> dict:
    """A bunny orbit with the noise modifier (brush paths): every stroke resampled at 1 px with
    its width, frame f-1's samples matched to frame f's as BRIEF 3 matches them (surface point
    projected, nearest within 6 px with agreeing tangent, both ways); the change of width of
    the matched pairs. Without a boil, and with boil = 4 (a new noise every 4 frames)."""
    from strokekit.sampling import match_samples, resample_strokes
    from strokekit.writers.strokes_json import read_strokes_json

    res = {}
    for boil in (0, 4):
        style = write_style(out, f"noise{boil}.toml", NOISE.format(boil=boil))
        d = out / f"orbit_boil{boil}"
        if not (d / f"frame_{frames:04d}.json").exists():
            strokekit("render", MODELS / "stanford-bunny.obj", "--orbit", frames, "--style", style, "--no-svg",
                      "--out", d)
        prev = None
        changes, same_id, per_pair = [], [], []
        for f in range(1, frames + 1):
            path = d / f"frame_{f:04d}.json"
            st = read_strokes_json(path)
            doc = json.loads(path.read_text())
            wid = np.concatenate([np.asarray(s["width"], float) for s in doc["strokes"]]) if doc["strokes"] \
                else np.zeros(0)
            smp = resample_strokes(st, 1.0)
            # the width at each sample: linear in arc length between the stroke's points
            arc = st.arc_length
            ws = np.empty(len(smp))
            for k in range(len(st)):
                sel = smp.stroke == k
                a, b = st.offsets[k], st.offsets[k + 1]
                ws[sel] = np.interp(smp.s[sel], arc[a:b], wid[a:b])
            cur = (st, smp, ws)
            if prev is not None:
                pst, psmp, pws = prev
                m = match_samples(psmp, st.camera, smp, exact=True)
                ok = m >= 0
                dw = np.abs(ws[m[ok]] - pws[ok])
                same = psmp.ids[ok] == smp.ids[m[ok]]
                m2 = match_samples(smp, pst.camera, psmp, exact=True)
                ok2 = m2 >= 0
                dw2 = np.abs(pws[m2[ok2]] - ws[ok2])
                same2 = smp.ids[ok2] == psmp.ids[m2[ok2]]
                dd = np.r_[dw, dw2]
                changes.append(dd)
                same_id.append(np.r_[same, same2])
                per_pair.append((f, float(np.median(dd)) if len(dd) else 0.0, float(np.percentile(dd, 95))))
            prev = cur
        allc = np.concatenate(changes)
        ids = np.concatenate(same_id)
        key = {"matched_samples": int(len(allc)), "p95_px": float(np.percentile(allc, 95)),
               "median_px": float(np.median(allc)), "p95_same_id_px": float(np.percentile(allc[ids], 95)),
               "share_same_id": float(ids.mean())}
        if boil:
            new = [p for p in per_pair if p[0] % boil == 0]
            held = [p for p in per_pair if p[0] % boil != 0]
            key.update({"pairs_new_noise": len(new), "median_of_pair_medians_new": float(np.median([p[1] for p in new])),
                        "median_of_pair_medians_held": float(np.median([p[1] for p in held])),
                        "p95_held_px": float(np.percentile(np.concatenate(
                            [c for c, p in zip(changes, per_pair) if p[0] % boil != 0]), 95))})
        res[f"boil {boil}"] = key
    return res


# --- cost ----------------------------------------------------------------------------------------------

def cost(turns: int = 7) -> dict:
    """A bunny frame (1024 x 1024, brush paths off: one frame draws its lines): the line pass,
    then SVG + JSON, with the default style and with FIVE's five modifiers (its style context
    found in render_frame: the visible depth range), in turns; medians."""
    from strokekit.camera.paths import orbit_path
    from strokekit.lines.renderer import LineRenderer
    from strokekit.run.frame import render_frame
    from strokekit.run.request import RenderRequest
    from strokekit.scene.load import load_scene
    from strokekit.style.file import read_style

    with tempfile.TemporaryDirectory() as tmp:
        style = read_style(write_style(Path(tmp), "five.toml", FIVE))
    scene = load_scene(MODELS / "stanford-bunny.obj")
    cam = orbit_path(scene.center, scene.radius, 24).cameras[3]
    plans = {"default": RenderRequest().plan(1), "five": RenderRequest(style=style).plan(1)}
    renderer = LineRenderer(scene, plans["default"].lines)
    times = {k: [] for k in plans}
    parts = {k: [] for k in plans}
    for _ in range(turns):
        for name, plan in plans.items():
            t0 = time.perf_counter()
            fr = render_frame(renderer, 4, cam, plan)
            t1 = time.perf_counter()
            svg = fr.to_svg()
            js = fr.to_json()
            t2 = time.perf_counter()
            times[name].append(t2 - t0)
            parts[name].append((t1 - t0, t2 - t1, len(svg), len(js)))
    med = {k: float(np.median(v)) for k, v in times.items()}
    return {"median_s": med, "ratio": med["five"] / med["default"],
            "lines_s": {k: float(np.median([p[0] for p in v])) for k, v in parts.items()},
            "svg_json_s": {k: float(np.median([p[1] for p in v])) for k, v in parts.items()},
            "svg_bytes": {k: v[0][2] for k, v in parts.items()}, "json_bytes": {k: v[0][3] for k, v in parts.items()}}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("what", choices=("formula", "ink", "ribbons", "coherence", "cost"))
    ap.add_argument("out", type=Path, nargs="?", default=None)
    ap.add_argument("--frames", type=int, default=120)
    ap.add_argument("--turns", type=int, default=7)
    a = ap.parse_args()
    if a.what == "cost":
        r = cost(a.turns)
    elif a.out is None:
        raise SystemExit("give an output folder")
    elif a.what == "coherence":
        r = coherence(a.out, a.frames)
    else:
        r = {"formula": formula, "ink": ink, "ribbons": ribbons}[a.what](a.out)
    print(json.dumps(r))


if __name__ == "__main__":
    main()
