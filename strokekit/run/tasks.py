"""The tasks a worker runs: a frame's lines (and raster pass), and a tracked frame's writes
(SVG, JSON, GLB, PNG), each file written atomically."""

from __future__ import annotations

import time
import traceback

import numpy as np

from strokekit.camera.view import Camera
from strokekit.colour import srgb_encode
from strokekit.cryptomatte import name_to_hex
from strokekit.errors import StrokekitError
from strokekit.fileio import atomic_write_bytes
from strokekit.model import BrushPaths, Strokes
from strokekit.options import LineOptions
from strokekit.raster.bands import band_regions, render_raster
from strokekit.raster.hits import ensure_kernels, thread_workspace
from strokekit.raster.passes import compositing_passes
from strokekit.raster.rays import surface_depth_at
from strokekit.raster.strokes import stroke_coverage
from strokekit.run.spec import RASTER_STAGES, OutputOptions
from strokekit.run.workers import _renderer
from strokekit.scene.occluder import Occluder
from strokekit.writers.exr import exr_bytes, lines_sparse
from strokekit.writers.gltf import glb_for_frame
from strokekit.writers.png import png_files
from strokekit.writers.strokes_json import strokes_json
from strokekit.writers.svg import bands_layer, svg_document


class _WriteFailed(Exception):
    """A file of the frame could not be written (atomic_write_bytes raised `error`): the task
    reports it as a write error, which stops the run, not as a failed frame."""

    def __init__(self, error: OSError):
        super().__init__(str(error))
        self.error = error


def _write(path, data: bytes) -> str:
    try:
        return str(atomic_write_bytes(path, data))
    except OSError as e:
        raise _WriteFailed(e) from None


def _write_error(e: OSError) -> tuple:
    """(errno, strerror, filename) of a failed write: what a task result carries (picklable, and
    the run raises it again as OSError(*...))."""
    return (e.errno, e.strerror, e.filename)


def frame_task(scene_path: str, scene_hash: str, lines: LineOptions, frame: int, camera: Camera,
               outputs: OutputOptions, do_lines: bool = True, write: tuple | None = None) -> dict:
    """Per-frame work that needs no other frame: lines, and the raster outputs (written here).
    Returns {'frame', 'strokes', 'seconds', 'files'}; errors come back as {'error': message}, a
    file that cannot be written (disk full, no permission) as {'write_error': (errno, strerror,
    filename)}.
    `write` = (kinds, extra, keep_strokes): the frame needs nothing from other frames (no
    tracking), so its SVG/JSON/GLB are written here too, and the result carries the write
    task's result under 'written' (and the strokes only when `keep_strokes`): strokes are not
    shipped to the main process and back."""
    t0 = time.perf_counter()
    try:
        r = _renderer(scene_path, scene_hash, lines)
        r.check_camera(camera, frame)
        timings: dict = {}
        strokes = r.render(camera, frame, timings) if do_lines else None
        if outputs.raster_options is not None:
            # The kernels' load (a worker's first frame) is the 'raster kernels' stage, not this frame's.
            timings["kernels"] = ensure_kernels()
        files, underlays, json_extra = raster_files(r.scene, camera, r.occluder, strokes, frame, outputs, timings,
                                                    lines.crease_angle_deg)
        res = {"frame": frame, "strokes": strokes, "seconds": time.perf_counter() - t0, "files": files,
               "timings": timings, "underlays": underlays or None, "json_extra": json_extra,
               "ray_tracer": r.occluder.backend}
        if write is not None and strokes is not None:
            kinds, extra, keep_strokes = write
            res["written"] = write_task(strokes, frame, outputs, kinds, {**extra, **res.pop("json_extra")},
                                        res.pop("underlays"), occluder=r.occluder)
            if not keep_strokes:
                res["strokes"] = None
        return res
    except _WriteFailed as w:
        return {"frame": frame, "write_error": _write_error(w.error)}
    except StrokekitError as e:
        return {"frame": frame, "error": str(e)}
    except Exception as e:  # a failed frame must not lose the others
        return {"frame": frame, "error": f"frame {frame}: {type(e).__name__}: {e}",
                "traceback": traceback.format_exc()}


def drawn_strokes(frame: Strokes | BrushPaths) -> Strokes:
    """What a frame draws: its brush paths, or its lines."""
    return frame.strokes if isinstance(frame, BrushPaths) else frame


def write_task(frame_strokes: Strokes | BrushPaths, frame: int, outputs: OutputOptions, kinds: tuple[str, ...],
               extra: dict, underlays: list | None = None, scene_key: tuple | None = None, occluder=None) -> dict:
    """Write one frame's SVG, JSON and GLB (atomic). Returns {'frame', 'files', 'seconds'}, or
    {'frame', 'write_error': (errno, strerror, filename)} for a file that cannot be written.
    `frame_strokes`: the frame's lines, or its brush paths (drawn; the JSON keeps the lines beside
    them). The GLB's world ribbons lie on the scene's surface (raster.surface_depth_at):
    `occluder`, or this process's renderer of `scene_key` = (scene path, scene hash, LineOptions)."""
    t0 = time.perf_counter()
    try:
        paths = frame_strokes if isinstance(frame_strokes, BrushPaths) else None
        strokes = drawn_strokes(frame_strokes)
        cam = strokes.camera
        files = []
        timings: dict = {}
        if outputs.svg:
            text = svg_document(strokes, cam.width, cam.height, kinds, decimals=outputs.decimals,
                                stroke_width=outputs.stroke_width_px, underlays=underlays,
                                dashes=outputs.hidden_dashes, dash_paths=outputs.dash_paths)
            files.append(_write(outputs.frame_file(frame, ".svg"), text.encode()))
            timings["svg"] = time.perf_counter() - t0
        if outputs.json:
            files.append(_write(outputs.frame_file(frame, ".json"),
                                strokes_json(strokes, cam.width, cam.height, frame, extra=extra, paths=paths)))
            timings["json"] = time.perf_counter() - t0 - sum(timings.values())
        if outputs.gltf and not outputs.gltf_sequence:
            files.append(_write(outputs.frame_file(frame, ".glb"), glb_for_frame(
                strokes, cam, outputs.gltf_options, _surface_depth(outputs, scene_key, occluder))))
            timings["ribbons + glTF"] = time.perf_counter() - t0 - sum(timings.values())
        return {"stage": "write", "frame": frame, "files": files, "seconds": time.perf_counter() - t0,
                "timings": timings}
    except _WriteFailed as w:
        return {"stage": "write", "frame": frame, "write_error": _write_error(w.error)}
    except Exception as e:
        return {"stage": "write", "frame": frame, "error": f"frame {frame}: writing failed: {type(e).__name__}: {e}"}


def _surface_depth(outputs: OutputOptions, scene_key: tuple | None, occluder=None):
    """raster.surface_depth_at for world ribbons (None for image-space ones, or without a scene)."""
    if outputs.gltf_options is not None and outputs.gltf_options.space != "world":
        return None
    if occluder is None:
        if scene_key is None:
            return None
        occluder = _renderer(*scene_key).occluder

    return surface_depth_at(occluder)


def raster_files(scene, camera: Camera, occluder: Occluder, strokes: Strokes | None, frame: int,
                 outputs: OutputOptions, timings: dict, crease_angle_deg: float = 60.0
                 ) -> tuple[list[str], list[str], dict]:
    """Write one frame's image passes (PNGs, one folder per pass) and EXR. Returns (files written,
    the SVG's bands layer ([] unless band polygons), what the frame JSON says of them: the depth
    PNG's range, and the objects and materials with their ids in the object-id PNG and their
    Cryptomatte ids). `crease_angle_deg`: the line options' (smooth shading splits normals there)."""
    files: list[str] = []
    underlays: list[str] = []
    info: dict = {}
    o = outputs.raster_options
    stem = outputs.stem(frame)
    covered: dict = {}

    def coverage(width_px: float) -> dict:
        """The strokes' coverage per kind, once for the lines PNG and the EXR's lines layer."""
        if width_px not in covered:
            covered[width_px] = stroke_coverage(strokes, int(camera.width), int(camera.height), width_px) \
                if strokes is not None else {}
        return covered[width_px]

    if o is not None:
        t1 = time.perf_counter()
        raster = render_raster(scene, camera, occluder, o, crease_angle_deg, work=thread_workspace(), timings=timings)
        t2 = time.perf_counter()
        images = raster.images() if o.pngs else {}
        timings["images"] = timings.get("images", 0.0) + (time.perf_counter() - t2)
        text = {}
        if "depth" in images:
            zn, zf = raster.depth_range()
            text["depth"] = {"near": repr(zn), "far": repr(zf)}
            info["depth_range"] = [zn, zf]
        if outputs.lines_png:
            t2 = time.perf_counter()
            images["lines"] = _lines_image(coverage(outputs.stroke_width_px), camera)
            timings["lines PNG"] = time.perf_counter() - t2
        t2 = time.perf_counter()
        pngs = png_files(images, text)
        timings["png"] = timings.get("png", 0.0) + (time.perf_counter() - t2)
        for name, data in pngs.items():
            files.append(_write(outputs.out_dir / name / f"{stem}.png", data))
        if o.band_polygons:
            underlays = [bands_layer(band_regions(raster))]
        timings["raster pass"] = time.perf_counter() - t1 - timings.get("lines PNG", 0.0)
        for key, (name, _) in RASTER_STAGES.items():
            if key in timings:
                timings[name] = timings.pop(key)
        if outputs.exr is not None:
            t1 = time.perf_counter()
            passes = compositing_passes(raster, strokes, outputs.exr, crease_angle_deg,
                                        coverage(outputs.exr.stroke_width_px) if "lines" in outputs.exr.passes else None)
            files.append(_write(outputs.frame_file(frame, ".exr"), exr_bytes(passes, outputs.exr.codec)))
            timings["EXR"] = time.perf_counter() - t1
        info.update(objects_and_materials(scene))
    elif outputs.lines_png:
        t1 = time.perf_counter()
        images = {"lines": _lines_image(coverage(outputs.stroke_width_px), camera)}
        for name, data in png_files(images).items():
            files.append(_write(outputs.out_dir / name / f"{stem}.png", data))
        timings["lines PNG"] = time.perf_counter() - t1
    return files, underlays, ({"raster": info} if info else {})


def _lines_image(cov: dict, camera: Camera) -> np.ndarray:
    """(H, W, 4) uint8 RGBA, sRGB-encoded straight alpha: the visible strokes in their colours, from
    their coverage per kind (raster.strokes.stroke_coverage)."""
    W, H = int(camera.width), int(camera.height)
    out = np.zeros((H * W, 4), np.uint8)
    if cov:
        pix, _, total = lines_sparse(cov)
        a = total[:, 3:4]
        with np.errstate(invalid="ignore", divide="ignore"):
            straight = np.where(a > 0, total[:, :3] / np.where(a > 0, a, 1.0), 0.0)
        px = np.concatenate([srgb_encode(np.clip(straight, 0, 1)), a], axis=1)
        out[pix] = np.round(np.clip(px, 0, 1) * 255.0).astype(np.uint8)
    return out.reshape(H, W, 4)


def objects_and_materials(scene) -> dict:
    """The scene's objects and materials for the frame JSON and the report: name, the value of
    its pixels in the object-id PNG (objects: index + 1; 0 is background) and its Cryptomatte id
    (8 hex digits of the float32 bits, as in the EXR's manifest)."""
    return {"objects": [{"name": n, "objectid": i + 1, "cryptomatte": name_to_hex(n)}
                        for i, n in enumerate(scene.objects)],
            "materials": [{"name": m.name, "index": i, "cryptomatte": name_to_hex(m.name)}
                          for i, m in enumerate(scene.materials)]}


def raster_outputs(scene, camera: Camera, occluder: Occluder | None, options, crease_angle_deg: float = 60.0
                   ) -> dict[str, bytes]:
    """{pass: PNG bytes} of one frame for RasterOptions (see strokekit.raster; raster_files
    writes them as OUT/<pass>/frame_0001.png). `crease_angle_deg`: the line options'."""
    return png_files(render_raster(scene, camera, occluder, options, crease_angle_deg).images())


def raster_outputs_with_bands_layer(scene, camera: Camera, occluder: Occluder | None, options,
                                    crease_angle_deg: float = 60.0, timings: dict | None = None,
                                    work=None) -> tuple[dict[str, bytes], list]:
    """(PNG outputs, the SVG text of the 'bands' layer in a list, [] when options.band_polygons is
    off): pass it as svg_document(..., underlays=...) so the bands sit under the line layers.
    `timings` gets the raster stages' seconds (render_raster's, 'images', 'png'); `work`: the
    z-buffer workspace (raster.hits.thread_workspace()) whose buffers this frame reuses."""
    frame = render_raster(scene, camera, occluder, options, crease_angle_deg, work=work, timings=timings)
    t0 = time.perf_counter()
    images = frame.images()
    t1 = time.perf_counter()
    pngs = png_files(images)
    if timings is not None:
        timings["images"] = timings.get("images", 0.0) + (t1 - t0)
        timings["png"] = timings.get("png", 0.0) + (time.perf_counter() - t1)
    return pngs, ([bands_layer(band_regions(frame))] if options.band_polygons else [])
