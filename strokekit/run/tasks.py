"""The tasks a worker runs: a frame's lines (and raster pass), and a tracked frame's writes
(SVG, JSON, GLB, PNG), each file written atomically."""

from __future__ import annotations

import time
import traceback

from strokekit.camera.view import Camera
from strokekit.errors import StrokekitError
from strokekit.fileio import atomic_write_bytes
from strokekit.model import BrushPaths, Strokes
from strokekit.options import LineOptions
from strokekit.raster.bands import band_regions, render_raster
from strokekit.raster.rays import surface_depth_at
from strokekit.run.spec import OutputOptions
from strokekit.run.workers import _renderer
from strokekit.scene.occluder import Occluder
from strokekit.writers.gltf import glb_for_frame
from strokekit.writers.png import png_files
from strokekit.writers.strokes_json import strokes_json
from strokekit.writers.svg import bands_layer, svg_document


def frame_task(scene_path: str, scene_hash: str, lines: LineOptions, frame: int, camera: Camera,
               outputs: OutputOptions, do_lines: bool = True, write: tuple | None = None) -> dict:
    """Per-frame work that needs no other frame: lines, and the raster outputs (written here).
    Returns {'frame', 'strokes', 'seconds', 'files'}; errors come back as {'error': message}.
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
        files = []
        underlays = None
        if outputs.raster_options is not None:

            t1 = time.perf_counter()
            stem = outputs.out_dir / outputs.stem(frame)
            pngs, underlays = raster_outputs_with_bands_layer(r.scene, camera, r.occluder, outputs.raster_options)
            for suffix, data in pngs.items():
                files.append(str(atomic_write_bytes(f"{stem}_{suffix}.png", data)))
            timings["raster pass"] = time.perf_counter() - t1
        res = {"frame": frame, "strokes": strokes, "seconds": time.perf_counter() - t0, "files": files,
               "timings": timings, "underlays": underlays or None, "ray_tracer": r.occluder.backend}
        if write is not None and strokes is not None:
            kinds, extra, keep_strokes = write
            res["written"] = write_task(strokes, frame, outputs, kinds, extra, res.pop("underlays"), occluder=r.occluder)
            if not keep_strokes:
                res["strokes"] = None
        return res
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
    """Write one frame's SVG, JSON and GLB (atomic). Returns {'frame', 'files', 'seconds'}.
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
                                stroke_width=outputs.stroke_width_px, underlays=underlays)
            files.append(str(atomic_write_bytes(outputs.frame_file(frame, ".svg"), text.encode())))
            timings["svg"] = time.perf_counter() - t0
        if outputs.json:

            files.append(str(atomic_write_bytes(outputs.frame_file(frame, ".json"),
                                                strokes_json(strokes, cam.width, cam.height, frame, extra=extra,
                                                             paths=paths))))
            timings["json"] = time.perf_counter() - t0 - sum(timings.values())
        if outputs.gltf and not outputs.gltf_sequence:

            files.append(str(atomic_write_bytes(outputs.frame_file(frame, ".glb"), glb_for_frame(
                strokes, cam, outputs.gltf_options, _surface_depth(outputs, scene_key, occluder)))))
            timings["ribbons + glTF"] = time.perf_counter() - t0 - sum(timings.values())
        return {"stage": "write", "frame": frame, "files": files, "seconds": time.perf_counter() - t0,
                "timings": timings}
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


def raster_outputs(scene, camera: Camera, occluder: Occluder, options) -> dict[str, bytes]:
    """{file suffix: PNG bytes} of one frame for RasterOptions (see strokekit.raster; write them
    as frame_0001_<suffix>.png)."""

    return png_files(render_raster(scene, camera, occluder, options).images())


def raster_outputs_with_bands_layer(scene, camera: Camera, occluder: Occluder, options) -> tuple[dict[str, bytes], list]:
    """(PNG outputs, the SVG text of the 'bands' layer in a list, [] when options.band_polygons is
    off): pass it as svg_document(..., underlays=...) so the bands sit under the line layers."""
    frame = render_raster(scene, camera, occluder, options)
    return png_files(frame.images()), ([bands_layer(band_regions(frame))] if options.band_polygons else [])
