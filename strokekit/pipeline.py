"""A render run: which stages the requested outputs need, per-frame work in parallel (process
pool started with spawn, or a dask.distributed cluster), the tracking pass in frame order, then
writing, with atomic files, resumption and a run report.

Per-frame tasks carry only the scene path and content hash, the frame number and its camera;
each worker loads the scene and builds its BVH once (cached per process).
"""

from __future__ import annotations

import hashlib
import json
import os
import platform
import time
import traceback
from collections import deque
from concurrent.futures import FIRST_COMPLETED, Executor, ProcessPoolExecutor, wait
from dataclasses import dataclass, field, fields, is_dataclass, replace
from pathlib import Path
from typing import Callable


from .camera import Camera
from .errors import InputError, StrokekitError, UsageError
from .fileio import atomic_write_bytes, check_pattern, temp_file_target
from .lines import LineRenderer
from .model import Strokes
from .options import LineOptions
from .scene import Scene, load_scene


@dataclass(frozen=True)
class OutputOptions:
    """What to write and where. `pattern` names a frame's files (without extension)."""

    out_dir: Path
    pattern: str = "frame_{frame:04d}"
    svg: bool = True
    json: bool = True
    gltf: bool = False
    gltf_sequence: bool = False
    decimals: int = 2
    stroke_width_px: float = 1.5
    gltf_options: object | None = None  # strokekit.writers.gltf options
    raster_options: object | None = None  # strokekit.raster options; None: no raster pass

    def stem(self, frame: int) -> str:
        return self.pattern.format(frame=frame)

    def check_names(self, frames) -> None:
        """UsageError when the pattern gives two of `frames` the same name (a pattern such as
        f_{frame:.0e} writes frames 10, 11 and 12 to one file: each would overwrite the last)."""
        seen: dict[str, int] = {}
        for f in frames:
            name = self.stem(f)
            if name in seen:
                raise UsageError(f"--pattern {self.pattern!r} names frames {seen[name]} and {f} alike ({name!r}): "
                                 "one would overwrite the other")
            seen[name] = f

    def frame_file(self, frame: int, suffix: str) -> Path:
        """OUT/<pattern>.<suffix>: the suffix is appended, never replaces a dotted part of the
        name (a pattern like shot.{frame:04d} keeps its frame number)."""
        return self.out_dir / f"{self.stem(frame)}{suffix}"

    def frame_files(self, frame: int) -> list[Path]:
        """The files one frame produces with these options."""
        stem = self.out_dir / self.stem(frame)
        out = []
        if self.svg:
            out.append(self.frame_file(frame, ".svg"))
        if self.json:
            out.append(self.frame_file(frame, ".json"))
        if self.gltf and not self.gltf_sequence:
            out.append(self.frame_file(frame, ".glb"))
        if self.raster_options is not None:
            from .raster import raster_file_suffixes

            out += [Path(f"{stem}_{s}.png") for s in raster_file_suffixes(self.raster_options)]
        return out


@dataclass(frozen=True)
class RunSpec:
    """Everything a run needs; cheap to pickle."""

    scene_path: str
    cameras: tuple[tuple[int, Camera], ...]
    lines: LineOptions
    outputs: OutputOptions
    tracking: object | None = None  # strokekit.tracking.TrackingOptions; None: no tracking
    workers: int = 1
    scheduler: str | None = None
    skip_existing: bool = False  # resume: see run(); frames of another scene or options are a UsageError
    fail_fast: bool = False
    camera_source: str = ""  # where the cameras come from (a camera file's path, "orbit"): for the report


@dataclass
class StageRecord:
    name: str
    ran: bool
    why: str
    seconds: float = 0.0


@dataclass
class RunResult:
    frames_ok: list[int] = field(default_factory=list)
    frames_skipped: list[int] = field(default_factory=list)
    failures: dict[int, str] = field(default_factory=dict)
    outputs: list[str] = field(default_factory=list)
    stages: list[StageRecord] = field(default_factory=list)
    frame_seconds: dict[int, float] = field(default_factory=dict)
    wall_seconds: float = 0.0
    scene_hash: str = ""
    scene_summary: dict = field(default_factory=dict)
    #: Stopped by Ctrl-C (KeyboardInterrupt): frames_ok are the frames written before it.
    interrupted: bool = False
    #: The occlusion backends the frames' lines came from (Occluder.backend: 'open3d', or a
    #: fallback whose drawing can differ in the last digits): one, unless processes differed.
    ray_tracers: set = field(default_factory=set)

    @property
    def exit_code(self) -> int:
        if self.interrupted:
            return 130  # the shell's code for a process stopped by SIGINT
        if not self.failures:
            return 0
        return 3 if self.frames_ok or self.frames_skipped else 1

    @property
    def status(self) -> str:
        """'ok', 'interrupted', 'partial' (some frames failed) or 'failed' (no frame done)."""
        if self.interrupted:
            return "interrupted"
        return {0: "ok", 3: "partial"}.get(self.exit_code, "failed")


class RunInterrupted(KeyboardInterrupt):
    """Ctrl-C stopped a run. The run has shut its workers down and removed the temporary files
    they left; `result` holds what was done before (frames written, failures, timings), with
    `result.interrupted` set. A KeyboardInterrupt, so code that does not know it stops as usual."""

    def __init__(self, result: RunResult):
        super().__init__("run interrupted")
        self.result = result


# --- the stage plan -------------------------------------------------------------------------------

def plan_stages(scene: Scene, spec: RunSpec) -> list[StageRecord]:
    """Which stages run for this scene and these outputs, and why (for --explain and the report)."""
    o, L = spec.outputs, spec.lines
    kinds = set(L.kinds)
    st = [StageRecord("load scene + BVH", True, "every run needs the scene and its occlusion BVH")]

    def add(name, ran, yes, no):
        st.append(StageRecord(name, bool(ran), yes if ran else no))

    st.append(StageRecord("feature edges", True, "candidate edges of the kinds below that ran"))
    add("  silhouette (mesh contour)", "silhouette" in kinds and L.contours == "mesh" and scene.is_manifold.any(),
        "silhouette lines requested", "not requested, smooth contours chosen, or no manifold edges")
    add("  smooth contour", L.contours == "smooth" or "smooth_contour" in kinds, "smooth contours requested",
        "mesh contours chosen")
    add("  border", "border" in kinds and scene.is_border.any(), "border lines requested and the scene has borders",
        "not requested or the scene has no border edges")
    add("  crease", "crease" in kinds and scene.crease_mask(L.crease_angle_deg).any(),
        f"crease lines requested, creases above {L.crease_angle_deg:g} deg exist",
        "not requested or no edge is sharper than the crease angle")
    add("  material boundary", "material" in kinds and len(scene.materials) > 1 and scene.is_material_boundary.any(),
        "requested and faces of different materials meet",
        "not requested, or no edge between faces of different materials")
    add("  nonmanifold", "nonmanifold" in kinds and scene.is_nonmanifold.any(),
        "requested and non-manifold edges exist", "not requested or no non-manifold edge")
    add("  suggestive contour", "suggestive" in kinds, "requested", "not requested")
    add("  intersection", "intersection" in kinds, "requested", "not requested")
    st.append(StageRecord("visibility", True, "Embree occlusion samples and bisection of every change"))
    st.append(StageRecord("chaining", True, "visible runs linked into strokes"))
    n = len(spec.cameras)
    add("tracking", spec.tracking is not None and n > 1,
        f"{n} frames with coherence on", "single frame or --no-coherence")
    add("svg", o.svg, "SVG output requested", "--no-svg")
    add("json", o.json, "JSON output requested", "--no-json")
    add("ribbons + glTF", o.gltf, "glTF output requested", "no glTF output requested")
    add("raster pass", o.raster_options is not None, "a raster output was requested", "no raster output requested")
    return st


# --- worker side -----------------------------------------------------------------------------------

_WORKER_CACHE: dict = {}


def _renderer(scene_path: str, scene_hash: str, lines: LineOptions) -> LineRenderer:
    """This process's renderer of the scene (loaded and its BVH built once per worker).
    `scene_hash` (when given) must be the hash the run started with."""
    key = (scene_path, lines)
    r = _WORKER_CACHE.get(key)
    if r is not None and scene_hash and r.scene.content_hash != scene_hash:
        r = None  # kept from an earlier run (a dask worker lives on): the file has changed since
    if r is None:
        _WORKER_CACHE.clear()
        r = LineRenderer(load_scene(scene_path), lines)
        _WORKER_CACHE[key] = r
    if scene_hash and r.scene.content_hash != scene_hash:
        raise InputError("scene file changed during the run", scene_path)
    return r


def _warm_worker(scene_path: str, lines: LineOptions, started) -> None:
    """Pool initializer: import, load the scene and build its BVH while the main process loads
    its own copy, instead of after it, then count this worker in `started` (a shared integer).
    Errors are left to the frame tasks to report (an initializer that raises would break the
    whole pool)."""
    try:
        _renderer(scene_path, "", lines)
    except Exception:
        _WORKER_CACHE.clear()
    with started.get_lock():
        started.value += 1


def _noop() -> None:
    return None


def _keep_renderer(scene_path: str, scene: Scene, lines: LineOptions) -> None:
    """Make `scene` (already loaded here) this process's renderer for frame tasks."""
    r = _WORKER_CACHE.get((scene_path, lines))
    if r is None or r.scene.content_hash != scene.content_hash:
        _WORKER_CACHE.clear()
        _WORKER_CACHE[(scene_path, lines)] = LineRenderer(scene, lines)


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
            from .raster import raster_outputs_with_bands_layer

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


def write_task(strokes: Strokes, frame: int, outputs: OutputOptions, kinds: tuple[str, ...], extra: dict,
               underlays: list | None = None, scene_key: tuple | None = None, occluder=None) -> dict:
    """Write one frame's SVG, JSON and GLB (atomic). Returns {'frame', 'files', 'seconds'}.
    The GLB's world ribbons lie on the scene's surface (raster.surface_depth_at): `occluder`, or
    this process's renderer of `scene_key` = (scene path, scene hash, LineOptions)."""
    t0 = time.perf_counter()
    try:
        cam = strokes.camera
        files = []
        timings: dict = {}
        if outputs.svg:
            from .writers.svg import svg_document

            text = svg_document(strokes, cam.width, cam.height, kinds, decimals=outputs.decimals,
                                stroke_width=outputs.stroke_width_px, underlays=underlays)
            files.append(str(atomic_write_bytes(outputs.frame_file(frame, ".svg"), text.encode())))
            timings["svg"] = time.perf_counter() - t0
        if outputs.json:
            from .writers.strokes_json import strokes_json

            files.append(str(atomic_write_bytes(outputs.frame_file(frame, ".json"),
                                                strokes_json(strokes, cam.width, cam.height, frame, extra=extra))))
            timings["json"] = time.perf_counter() - t0 - sum(timings.values())
        if outputs.gltf and not outputs.gltf_sequence:
            from .writers.gltf import glb_for_frame

            files.append(str(atomic_write_bytes(outputs.frame_file(frame, ".glb"), glb_for_frame(
                strokes, cam, outputs.gltf_options, _surface_depth(outputs, scene_key, occluder)))))
            timings["ribbons + glTF"] = time.perf_counter() - t0 - sum(timings.values())
        return {"stage": "write", "frame": frame, "files": files, "seconds": time.perf_counter() - t0,
                "timings": timings}
    except Exception as e:
        return {"stage": "write", "frame": frame, "error": f"frame {frame}: writing failed: {type(e).__name__}: {e}"}


def _surface_depth(outputs: OutputOptions, scene_key: tuple | None, occluder=None):
    """raster.surface_depth_at for world ribbons (None for image-space ones, or without a scene)."""
    if getattr(outputs.gltf_options, "space", "world") != "world":  # (None: GltfOptions(), world)
        return None
    if occluder is None:
        if scene_key is None:
            return None
        occluder = _renderer(*scene_key).occluder
    from .raster import surface_depth_at

    return surface_depth_at(occluder)


# --- executors ---------------------------------------------------------------------------------------

class _NoPool:
    """The `started` count of a run without pool workers: none will ever start."""

    value = 0


@dataclass
class Workers:
    """Where frame tasks run. `executor` takes them; beside a local pool (`started` set: --workers
    N is this process and N - 1 pool workers) this process runs tasks too (`main_helps`)."""

    executor: Executor | None  # None: this process runs every task (main_helps, no pool)
    close: Callable[[], None]  # may be called more than once (an interrupted run closes them itself)
    #: Pool workers that have finished starting (imports, scene, BVH): a shared integer (always
    #: 0 when this process is the only one), or None when this process does not render (dask).
    started: object | None = None

    @property
    def main_helps(self) -> bool:
        return self.started is not None

    def _capacity(self) -> int:
        return 2 * self.started.value if self.main_helps else 1 << 30

    def map(self, tasks, handle: Callable[[dict], bool]) -> None:
        """Run every (fn, *args) of `tasks`, calling `handle(result)` in this process as each
        finishes (in any order); `handle` returning False stops the rest. `tasks` may be a deque
        that `handle` adds to while the map runs (appendleft: next in line): those run too.

        With main_helps, each pool worker that has started gets at most two tasks queued and
        this process runs the others one by one, so frames get done while the workers are
        still starting (a spawned worker needs seconds of imports and scene loading; a short
        run ends before they are up) and no worker idles."""
        if self.main_helps and self.executor is not None:
            return self._map_helping(tasks, handle)
        pending = tasks if isinstance(tasks, deque) else deque(tasks)
        running: set = set()
        go = True

        def collect(futs) -> bool:
            for fut in futs:
                running.discard(fut)
                if not handle(fut.result()):
                    return False
            return True

        while go and (pending or running):
            while pending and len(running) < self._capacity():
                fn, *args = pending.popleft()
                running.add(self.executor.submit(fn, *args))
            if self.main_helps and pending:
                fn, *args = pending.popleft()
                go = handle(fn(*args)) and collect([f for f in running if f.done()])
            elif running:
                done, _ = wait(running, return_when=FIRST_COMPLETED)
                go = collect(done)
        _stop(running, handle)

    def _map_helping(self, tasks, handle: Callable[[dict], bool]) -> None:
        """map() beside a local pool that this process helps. A worker's next task is sent the
        moment its result arrives (by the pool's result thread, in a done-callback), not when
        this process has finished the frame it is rendering and handled the results (with
        tracking, the tracking pass too): so a worker does not wait for this process. Measured,
        warm 48-frame bunny orbit with tracking, 2 workers against 1: 1.44x -> 1.68x (the worker
        starved while this process rendered and tracked); without tracking unchanged (1.7x).

        A worker gets a second task queued (to cover the round trip) only while more than two
        tasks per worker remain; near the end it gets one at a time and this process takes the
        rest, so a worker is not left with a queued frame while this process has nothing to do.
        Results are still handled here, in this thread."""
        import threading

        pending = tasks if isinstance(tasks, deque) else deque(tasks)
        lock = threading.RLock()
        running: set = set()  # submitted, result not yet handled here
        # busy: submitted and not finished; feeding: feed() is running (in the thread holding
        # `lock`: a future already done when its callback is added calls it right there).
        state = {"stop": False, "busy": 0, "feeding": False}

        def capacity() -> int:
            # Two tasks per started worker; one each once no more than two per worker remain for
            # the workers and this process to share.
            n = self.started.value
            return 2 * n if len(pending) > 2 * n else n

        def feed() -> None:
            """Top the pool up from `pending` (holding `lock`)."""
            state["feeding"] = True
            try:
                while not state["stop"] and pending and state["busy"] < capacity():
                    item = pending.popleft()
                    try:
                        fut = self.executor.submit(item[0], *item[1:])
                    except Exception:
                        pending.appendleft(item)  # the pool is closed or broken: this thread runs it
                        state["stop"] = True
                        return
                    state["busy"] += 1
                    running.add(fut)
                    fut.add_done_callback(finished)
            finally:
                state["feeding"] = False

        def finished(fut) -> None:  # in the pool's result thread (or in feed(), if already done)
            if fut.cancelled() or fut.exception() is not None:
                # A dead worker (the tasks catch their own errors): the pool is broken. Python >= 3.12
                # completes the futures while holding the executor's _shutdown_lock, which submit()
                # needs (and `lock` may be held by a feed() waiting for it): feed nothing, take no lock.
                state["stop"] = True
                return
            with lock:
                state["busy"] -= 1
                if not state["feeding"]:
                    feed()

        def handled(r: dict) -> bool:
            if handle(r):
                return True
            with lock:
                state["stop"] = True  # fail-fast: no more tasks go to the pool
            return False

        def collect() -> bool:
            with lock:
                done = [f for f in running if f.done()]
            for f in done:
                with lock:
                    running.discard(f)
                if not handled(f.result()):
                    return False
            return True

        try:
            go = True
            while go:
                with lock:
                    feed()
                    item = pending.popleft() if pending else None
                    waiting = list(running)
                if item is not None:
                    go = handled(item[0](*item[1:])) and collect()
                elif waiting:
                    wait(waiting, return_when=FIRST_COMPLETED)
                    go = collect()
                else:
                    break
        finally:
            with lock:
                state["stop"] = True
                left = list(running)
        _stop(left, handle)


def _stop(running, handle: Callable[[dict], bool]) -> None:
    """Stopped early (or done): tasks already running finish (they may be writing files) and
    their results are handled (the files they wrote are reported); queued ones are dropped."""
    for fut in running:
        fut.cancel()
    wait(running)
    for fut in running:
        if not fut.cancelled() and fut.exception() is None:
            handle(fut.result())


def make_executor(workers: int, scheduler: str | None, warm: tuple) -> Workers:
    """Where the run's tasks go. `scheduler` 'tcp://host:port': a dask.distributed cluster.
    Otherwise `workers` processes on this machine: this one, plus a spawn-started pool of
    workers - 1 processes, started now; each loads the scene and builds its BVH right away
    (`warm` = (scene_path, lines))."""
    if scheduler:
        try:
            from distributed import Client
        except ImportError:
            raise UsageError("--scheduler needs dask.distributed (pip install 'dask[distributed]')") from None
        try:
            client = Client(scheduler, timeout=10)
        except Exception as e:
            raise InputError(f"cannot reach the dask scheduler at {scheduler} ({e})") from None
        ex = client.get_executor(pure=False)
        return Workers(ex, _once(client.close))
    if workers <= 1:
        # This process does every task, one by one, handling each result before the next task.
        return Workers(None, lambda: None, started=_NoPool())
    import multiprocessing as mp
    import signal

    ctx = mp.get_context("spawn")
    started = ctx.Value("i", 0)
    ex = ProcessPoolExecutor(max_workers=workers - 1, mp_context=ctx, initializer=_warm_worker,
                             initargs=(*warm, started))
    # A pool spawns its workers on demand: ask for all of them now. They inherit an ignored
    # SIGINT, so Ctrl-C reaches this process alone (one "aborted" line, no traceback from a
    # worker interrupted in its imports) and close() ends them.
    try:
        old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    except ValueError:  # not the main thread: signals are not ours to change
        old = None
    try:
        for _ in range(workers - 1):
            ex.submit(_noop)
    finally:
        if old is not None:
            signal.signal(signal.SIGINT, old)

    def close() -> None:
        # Our tasks have all finished by now (Workers.map waits for running ones; an interrupt
        # or error ends the run anyway); a worker may still be in its initializer, as a short
        # run can end before the pool is up. Waiting would add its whole start-up to the run, so
        # idle or starting workers are stopped instead (ProcessPoolExecutor has no public way).
        procs = list((getattr(ex, "_processes", None) or {}).values())  # shutdown forgets them
        ex.shutdown(wait=False, cancel_futures=True)
        for proc in procs:
            proc.terminate()
        ex.shutdown(wait=True)

    return Workers(ex, _once(close), started=started)


def _once(fn: Callable[[], None]) -> Callable[[], None]:
    done = []

    def call_once() -> None:
        if not done:
            done.append(True)
            fn()

    return call_once


# --- the run manifest ----------------------------------------------------------------------------------

#: The output folder's record of what its frame files were rendered from (a dotfile: not a frame file).
RUN_MANIFEST = ".strokekit-run.json"


def _canon(v):
    """`v` as plain JSON values, deterministically (dataclasses field by field, tuples as lists)."""
    if is_dataclass(v) and not isinstance(v, type):
        return {f.name: _canon(getattr(v, f.name)) for f in fields(v)}
    if isinstance(v, (list, tuple)):
        return [_canon(x) for x in v]
    if isinstance(v, dict):
        return {str(k): _canon(x) for k, x in v.items()}
    if isinstance(v, Path):
        return str(v)
    if v is None or isinstance(v, (bool, int, float, str)):
        return v
    if hasattr(v, "item"):  # a numpy scalar
        return v.item()
    raise TypeError(f"cannot digest a {type(v).__name__} in the run options")


def _digest(v) -> str:
    text = json.dumps(_canon(v), sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def run_manifest(spec: RunSpec, scene: Scene, tracking_on: bool) -> dict:
    """What determines the bytes of the run's frame files: `scene` and `options` digests (the
    set of frames aside) and per frame a digest of its camera. With tracking a frame's lines
    also depend on every frame tracked before it in the run, so its digest chains theirs: a
    longer range of the same path (1-10, then 1-20) keeps the digests of the frames they share."""
    scene_d = _digest({"content_hash": scene.content_hash, "objects": len(scene.objects),
                       "materials": [m.base_color for m in scene.materials]})
    o = spec.outputs
    outputs = {f.name: getattr(o, f.name) for f in fields(o) if f.name != "out_dir"}
    brush = getattr(o.gltf_options, "brush", None)
    if o.gltf and brush is not None:
        from .brushes import BUNDLED

        if brush not in BUNDLED:  # a user's image: its bytes go into every GLB
            try:
                outputs["brush_sha256"] = hashlib.sha256(Path(brush).read_bytes()).hexdigest()
            except OSError:
                pass  # the run reports it
    options_d = _digest({"lines": spec.lines.to_json(), "outputs": outputs,
                         "tracking": spec.tracking if tracking_on else None})
    frames, chain = {}, ""
    for f, cam in spec.cameras:
        d = _digest(cam.to_json())
        if tracking_on:
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


def _not_a_resume(out_dir: Path, old: dict | None, new: dict, present: set[int]) -> str:
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


# --- the run -------------------------------------------------------------------------------------------

def _load_and_plan(spec: RunSpec, res: RunResult, scene: Scene | None = None, load_seconds: float = 0.0):
    """The main process's scene (hash, summary) and the stage plan, timed as the first stage.
    `scene`: the scene file already loaded by the caller (not loaded again) in `load_seconds`."""
    t = time.perf_counter() - load_seconds
    scene = load_scene(spec.scene_path) if scene is None else scene
    res.scene_hash = scene.content_hash
    res.scene_summary = {"faces": int(len(scene.faces)), "objects": len(scene.objects),
                         "materials": len(scene.materials)}
    res.stages = plan_stages(scene, spec)
    res.stages[0].seconds = time.perf_counter() - t
    return scene


def run(spec: RunSpec, progress: Callable[[str, int, int], None] | None = None, *,
        workers: Workers | None = None, scene: Scene | None = None, load_seconds: float = 0.0,
        started_at: float | None = None) -> RunResult:
    """Render every frame of `spec`. `progress(phase, done, total)` is called as frames finish.
    `workers`: make_executor(spec.workers, spec.scheduler, (spec.scene_path, spec.lines)) started
    by the caller (and closed by it), e.g. before it loads the scene, so the workers start sooner;
    `scene`: spec.scene_path already loaded by the caller, in `load_seconds` (reported as the
    load stage); `started_at`: the caller's time.perf_counter() when the run began for the user
    (the report's wall time counts from there: the pool start and the load are part of it).

    The output folder's RUN_MANIFEST is written before the first frame file (see run_manifest).
    With spec.skip_existing a frame is skipped when its files exist and the manifest has this run's
    scene and options digests and this frame's camera digest; frame files there with a manifest
    of another scene or options, or none, raise UsageError before any frame is rendered."""
    t_start = time.perf_counter() if started_at is None else started_at
    # The frame files there before the run, by (inode, mtime, size): a file this run wrote is one
    # missing from it or changed since (an atomic write replaces the inode). No clock compared.
    before: dict[str, tuple] | None = None
    res = RunResult()
    check_pattern(spec.outputs.pattern)
    spec.outputs.check_names(f for f, _ in spec.cameras)
    if spec.outputs.raster_options is not None:
        from .raster import check_raster_fits

        for w, h in sorted({(c.width, c.height) for _, c in spec.cameras}):
            check_raster_fits(w, h, spec.outputs.raster_options.supersample)
    # Workers start first: their imports and scene load overlap the main process's own load.
    own = workers is None
    if own:
        workers = make_executor(spec.workers, spec.scheduler, warm=(spec.scene_path, spec.lines))
    try:
        scene = _load_and_plan(spec, res, scene, load_seconds if scene is not None else 0.0)
        stage = {s.name: s for s in res.stages}
        out = spec.outputs
        out.out_dir.mkdir(parents=True, exist_ok=True)
        # Temporary files of an interrupted earlier run are ours to remove (their final names never existed).
        for stale in out.out_dir.glob(".*.part"):
            stale.unlink(missing_ok=True)
        frames = [f for f, _ in spec.cameras]
        cams = dict(spec.cameras)
        tracking_on = stage["tracking"].ran

        # Resume: frames whose every file exists, rendered by this run's scene and options with this
        # frame's camera (the manifest says so), are not written again. With tracking their lines are
        # still computed (the tracker's state depends on every earlier frame), so a resumed run gives
        # the same bytes as an uninterrupted one.
        manifest = run_manifest(spec, scene, tracking_on)
        old = read_run_manifest(out.out_dir)
        same_run = old is not None and old["run"] == manifest["run"]
        before = _file_states(p for f in frames for p in out.frame_files(f))
        on_disk = {f: [str(p) in before for p in out.frame_files(f)] for f in frames}
        done_before = set()
        if spec.skip_existing:
            present = {f for f in frames if all(on_disk[f])}
            if present and not same_run:
                raise UsageError(_not_a_resume(out.out_dir, old, manifest, present))
            done_before = {f for f in present if old["frames"].get(f) == manifest["frames"][f]}
        res.frames_skipped = sorted(done_before)
        # The manifest is written before any frame file: the same run's entries are kept (merged),
        # another run's replaced. A frame of this run is entered now unless files of it from
        # something else are there (they stay until rewritten): it is entered once written, so
        # a run stopped before that never leaves such a file looking like this run's.
        entries = dict(old["frames"]) if same_run else {}
        enter_later: set[int] = set()
        for f in frames:
            new = manifest["frames"][f]
            if entries.get(f) == new or not any(on_disk[f]):
                entries[f] = new
            else:
                entries.pop(f, None)
                enter_later.add(f)
        res.outputs.append(str(write_run_manifest(out.out_dir, manifest, entries)))

        def enter_written() -> None:
            done = enter_later.intersection(res.frames_ok)
            entries.update((f, manifest["frames"][f]) for f in done)
            stale = []
            if tracking_on and lines_failed:
                # The frames after a frame whose lines failed were tracked without it: they are
                # not what a run with it gives, so they leave the manifest and a resume renders
                # them again (their digests chain through the failed frame).
                first = frames.index(min(lines_failed, key=frames.index))
                stale = [f for f in frames[first + 1:] if entries.pop(f, None) is not None]
            if done or stale:
                write_run_manifest(out.out_dir, manifest, entries)
        # The lines of frames kept from an earlier run are computed again (not written) when the
        # tracker needs every frame, or when sequence.glb holds every frame of the run.
        need_lines = [f for f in frames if f not in done_before or tracking_on or (out.gltf and out.gltf_sequence)]

        lines_results: dict[int, Strokes] = {}
        underlays: dict[int, list | None] = {}
        if workers.main_helps:
            # Frames rendered here use this load; building the renderer (open3d, the BVH) is part
            # of the load stage.
            t = time.perf_counter()
            _keep_renderer(spec.scene_path, scene, spec.lines)
            stage["load scene + BVH"].seconds += time.perf_counter() - t
        to_write = [f for f in need_lines if f not in done_before]
        extra = {"contours": spec.lines.contours,
                 "tracking": getattr(spec.tracking, "method", "none") if tracking_on else "none"}
        keep_strokes = out.gltf and out.gltf_sequence
        # Without tracking a frame needs no other: it is written where its lines are computed.
        write_in_task = None if tracking_on else (spec.lines.kinds, extra, keep_strokes)
        pending = deque((frame_task, spec.scene_path, scene.content_hash, spec.lines, f, cams[f],
                         out if f not in done_before else replace(out, raster_options=None), True,
                         write_in_task if f not in done_before else None) for f in need_lines)
        n_lines = len(pending)
        tracker = None
        if tracking_on:
            from .tracking import Tracker

            tracker = Tracker(spec.tracking)
        finished: set[int] = set()  # frames whose lines are done or failed
        lines_failed: set[int] = set()
        ordered: list[int] = []  # frames with lines, in frame order, tracked when tracking is on
        n_done = n_written = 0

        def lines_done(r: dict) -> None:
            nonlocal n_done
            n_done += 1
            f = r["frame"]
            finished.add(f)
            if "error" in r:
                res.failures[f] = r["error"]
                lines_failed.add(f)
            else:
                lines_results[f] = r["strokes"]
                underlays[f] = r.get("underlays")
                res.ray_tracers.add(r["ray_tracer"])
                res.frame_seconds[f] = r["seconds"]
                res.outputs += r["files"]
                _add_timings(stage, r["timings"])
            if progress:
                progress("lines", n_done, n_lines)
            if "written" in r:
                written(r["written"])
            # Frames go on in frame order as soon as every earlier one is done: the tracking
            # pass (the only sequential stage) runs here, beside the workers' line work, and
            # each tracked frame is written next (its write task goes first in line), so
            # output appears from the start and no stage waits for all frames.
            advance()

        cursor = 0

        def advance() -> None:
            nonlocal cursor
            while cursor < len(need_lines) and need_lines[cursor] in finished:
                f = need_lines[cursor]
                if f in lines_failed and spec.fail_fast:
                    return  # --fail-fast: no frame after a failed one is tracked or written
                cursor += 1
                if f not in lines_results:
                    continue
                if tracker is not None:
                    t = time.perf_counter()
                    lines_results[f] = tracker.step(lines_results[f])
                    stage["tracking"].seconds += time.perf_counter() - t
                ordered.append(f)
                if write_in_task is not None:
                    continue  # written by its frame task
                if f not in done_before:
                    pending.appendleft((write_task, lines_results[f], f, out, spec.lines.kinds, extra,
                                        underlays.pop(f, None), (spec.scene_path, scene.content_hash, spec.lines)))
                if not keep_strokes and f in done_before:
                    lines_results.pop(f)

        def written(r: dict) -> None:
            nonlocal n_written
            n_written += 1
            f = r["frame"]
            if "error" in r:
                res.failures[f] = r["error"]
            else:
                res.outputs += r["files"]
                res.frames_ok.append(f)
                res.frame_seconds[f] = res.frame_seconds.get(f, 0.0) + r["seconds"]
                _add_timings(stage, r["timings"])
            if not keep_strokes:
                lines_results.pop(f, None)
            if progress:
                # Frames whose lines failed are never written: they leave the total.
                progress("write", n_written, len(to_write) - len(lines_failed.intersection(to_write)))

        def handle(r: dict) -> bool:
            if r.get("stage") == "write":
                written(r)
            else:
                lines_done(r)
            return not (spec.fail_fast and ("error" in r or "error" in r.get("written", ())))

        try:
            workers.map(pending, handle)
            if spec.fail_fast and res.failures:
                # Stopped at a failure: the frames before it whose lines are done are still
                # tracked (above) and written, here (their write tasks were left in line).
                # (A failed write stops the frames after it too; in frame order.)
                order = {f: k for k, f in enumerate(frames)}
                stop_at = min((order[f] for f in res.failures), default=len(frames))
                rest = sorted((item for item in pending if item[0] is write_task and order[item[2]] < stop_at),
                              key=lambda item: order[item[2]])
                pending.clear()
                for item in rest:
                    written(write_task(*item[1:]))
        finally:
            enter_written()
        if out.gltf and out.gltf_sequence and ordered:
            from .writers.gltf import glb_for_sequence

            t = time.perf_counter()
            seq = [lines_results[f] for f in ordered]
            path = out.out_dir / "sequence.glb"
            depth_at = _surface_depth(out, (spec.scene_path, scene.content_hash, spec.lines))
            res.outputs.append(str(atomic_write_bytes(path, glb_for_sequence(seq, out.gltf_options, depth_at))))
            stage["ribbons + glTF"].seconds += time.perf_counter() - t
    except KeyboardInterrupt:
        # Ctrl-C: the frames in progress are abandoned. The workers stop now (also the caller's:
        # their tasks belong to this run), then the temporary files of the writes they were in
        # are removed; every file left is complete (written whole, then renamed).
        workers.close()
        remove_temp_files(spec)
        _frames_found_whole(spec, res, before)
        _remove_partial_frames(spec, res, before)
        res.interrupted = True
        _finish(res, t_start)
        raise RunInterrupted(res) from None
    finally:
        if own:
            workers.close()
    if res.failures:
        _remove_partial_frames(spec, res, before)
    return _finish(res, t_start)


def _file_states(paths) -> dict[str, tuple]:
    """{path: (inode, mtime_ns, size)} of the files among `paths` that exist."""
    out = {}
    for p in paths:
        try:
            s = os.stat(p)
        except OSError:
            continue
        out[str(p)] = (s.st_ino, s.st_mtime_ns, s.st_size)
    return out


def _written_by_run(p: Path, before: dict[str, tuple] | None) -> bool:
    """Whether file `p` exists and was written by this run: it was not there at the start (see
    `before`), or has changed since. False when the run never took stock (nothing written yet)."""
    if before is None:
        return False
    now = _file_states([p])
    return str(p) in now and before.get(str(p)) != now[str(p)]


def _frames_found_whole(spec: RunSpec, res: RunResult, before: dict[str, tuple] | None) -> None:
    """After Ctrl-C: frames whose every file this run wrote count as written, though their results
    never came back (the interrupt fell between the last rename and the report of a worker, or
    of this process)."""
    known = set(res.frames_ok) | set(res.failures) | set(res.frames_skipped)
    listed = set(res.outputs)
    for f, _ in spec.cameras:
        if f in known:
            continue
        paths = spec.outputs.frame_files(f)
        if paths and all(_written_by_run(p, before) for p in paths):
            res.frames_ok.append(f)
            res.outputs += [str(p) for p in paths if str(p) not in listed]


def _remove_partial_frames(spec: RunSpec, res: RunResult, before: dict[str, tuple] | None) -> None:
    """Files this run wrote of frames it did not write whole: the raster images of a frame whose
    lines failed to be written, or that a stop (Ctrl-C, --fail-fast) left untracked. Removed with
    the rest of the frame's files (an earlier run's, which would make a frame of two runs), so that
    a frame is on disk whole or not at all. A frame this run did not touch stays as it was."""
    keep = set(res.frames_ok) | set(res.frames_skipped)
    gone = set()
    for f, _ in spec.cameras:
        if f in keep:
            continue
        paths = spec.outputs.frame_files(f)
        if not any(_written_by_run(p, before) for p in paths):
            continue  # untouched: an earlier run's frame stays as it was
        # Some of it is new: an earlier run's files of it would make a frame of two runs.
        for p in paths:
            try:
                p.unlink()
                gone.add(str(p))
            except OSError:
                continue
    if gone:
        res.outputs[:] = [o for o in res.outputs if o not in gone]


def _finish(res: RunResult, t_start: float) -> RunResult:
    res.frames_ok.sort()
    res.outputs.sort()
    res.wall_seconds = time.perf_counter() - t_start
    return res


def remove_temp_files(spec: RunSpec) -> list[Path]:
    """Remove the temporary files (.<name>.<random>.part) that writes of this run's outputs left
    in its output folder (a worker stopped mid-write); returns them. Others' files are not touched."""
    out = spec.outputs
    names = {p.name for f, _ in spec.cameras for p in out.frame_files(f)} | {"sequence.glb"}
    removed = []
    try:
        temps = list(out.out_dir.glob(".*.part"))
    except OSError:
        return removed
    for tmp in temps:
        if temp_file_target(tmp) in names:
            tmp.unlink(missing_ok=True)
            removed.append(tmp)
    return removed


def _add_timings(stage: dict, timings: dict) -> None:
    """Stage times are the sum of the work done in all workers (CPU time spent per stage)."""
    for name, sec in timings.items():
        if name in stage:
            stage[name].seconds += sec


def run_report(spec: RunSpec, res: RunResult) -> dict:
    """The JSON run report: versions, input hashes, per-frame status, outputs, timings, stages."""
    def versions():
        from importlib.metadata import PackageNotFoundError, version

        out = {"python": platform.python_version()}
        for dist in ("strokekit", "numpy", "scipy", "trimesh", "open3d", "embreex", "shapely", "svgwrite",
                     "pygltflib", "click", "pillow"):
            try:
                out[dist] = version(dist)
            except PackageNotFoundError:
                out[dist] = None
        return out

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
    cams = {f: _canon(c.to_json()) for f, c in spec.cameras}
    o = spec.outputs
    outputs = _canon({f.name: getattr(o, f.name) for f in fields(o)})
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
        "versions": versions(),
        "platform": platform.platform(),
        "scene": {"path": spec.scene_path, "sha256": file_hash, "content_hash": res.scene_hash, **res.scene_summary},
        "cameras": cameras,
        "options": {"lines": spec.lines.to_json(), "workers": spec.workers, "scheduler": spec.scheduler,
                    "tracking": getattr(spec.tracking, "method", None) if spec.tracking is not None else "none",
                    "tracking_options": _canon(spec.tracking) if spec.tracking is not None else None,
                    "contours": spec.lines.contours, "outputs": outputs},
        "ray_tracer": ", ".join(sorted(res.ray_tracers)) or None,
        "stages": [{"stage": s.name, "ran": s.ran, "why": s.why, "seconds": round(s.seconds, 6)} for s in res.stages],
        "frames": frames,
        "failures": {str(k): v for k, v in sorted(res.failures.items())},
        "outputs": res.outputs,
        "wall_seconds": round(res.wall_seconds, 4),
        "exit_code": res.exit_code,
    }
