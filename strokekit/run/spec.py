"""What a run is asked to do (`RunSpec`: a RenderRequest for some cameras, with
`OutputOptions`: typed, picklable), which stages that needs (`plan_stages`), and what it did
(`RunResult`)."""

from __future__ import annotations

import os
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING

from strokekit.errors import UsageError
from strokekit.fileio import TEMP_SUFFIX
from strokekit.options import LineOptions, option
from strokekit.raster.options import PassOptions, RasterOptions
from strokekit.ribbons.options import BUNDLED
from strokekit.run.request import RenderRequest, SequencePlan
from strokekit.writers.options import SVG_LINES, GltfOptions

if TYPE_CHECKING:  # (annotations only: the options load without the scene or camera code)
    from strokekit.camera.view import Camera
    from strokekit.scene.load import Scene

#: The most processes a local run starts (--workers): each loads the scene and its BVH, and more
#: than a few per core only share the cores.
MAX_WORKERS = max(8, 4 * (os.cpu_count() or 1))
#: --worker-kind: threads of this process, or a pool of processes; "auto": the kind `pool_for` picks.
WORKER_KINDS = ("auto", "threads", "processes")
#: Without a raster pass, processes pay from this many frames on: threads there share Python's
#: lock with the frame-order tracking and lose to one worker, a process starts in about a second.
PROCESSES_FROM = 48


def pool_for(n_frames: int, raster: bool, workers: int | None = None, kind: str = "auto") -> tuple[int, str]:
    """(workers, kind) of a run of `n_frames` where --workers (None) or --worker-kind ("auto") is
    unsaid. With a raster pass, threads (its kernels let go of Python's lock, and they start at
    once); without one, processes from PROCESSES_FROM frames on, else one worker. A said kind
    keeps the old counts: threads on every core for a sequence; processes from 8 frames on,
    from 16 with a raster pass (each process starts numba for its kernels)."""
    cores = os.cpu_count() or 1
    if kind == "auto":
        if workers is None:
            workers = cores if (raster and n_frames >= 2) or n_frames >= PROCESSES_FROM else 1
        # (one worker runs no pool: said as threads, the kind whose one worker is this process)
        kind = "threads" if raster or n_frames < PROCESSES_FROM or workers == 1 else "processes"
    if workers is None:
        least = 2 if kind == "threads" else (16 if raster else 8)
        workers = cores if n_frames >= least else 1
    return workers, kind


#: The longest file name (bytes) of Linux, macOS and Windows file systems.
NAME_MAX = 255


@dataclass(frozen=True)
class OutputOptions:
    """What to write and where. `pattern` names a frame's files (without extension)."""

    out_dir: Path
    pattern: str = option("frame_{frame:04d}", "--pattern", "File name pattern (no extension).", show_default=True)
    svg: bool = option(True, "--svg", "Write frame_NNNN.svg (the drawing).", off="--no-svg", show_default=True)
    json: bool = option(True, "--json", "Write frame_NNNN.json (strokes with ids, kinds and u, for tools).",
                        off="--no-json", show_default=True)
    gltf: bool = option(False, "--gltf", "Write textured ribbons as frame_NNNN.glb.", off="--no-gltf",
                        show_default=True)
    gltf_sequence: bool = option(False, "--gltf-sequence",
                                 "One sequence.glb for all frames (a node per frame) instead.", switch=True)
    decimals: int = option(2, "--decimals", "SVG coordinate decimals.", low=0, high=8, show_default=True, needs="svg")
    svg_lines: str = option(
        "outline", "--svg-lines", "How the SVG draws a line whose width varies (a --style): as a filled outline (its "
        "width everywhere: for viewing and print), or as its centreline at its mean width (for plotters and cutters: "
        "one path per stroke).", choices=SVG_LINES, show_default=True, needs="svg")
    gltf_options: GltfOptions | None = None  # None: GltfOptions()
    dash_paths: bool = option(  # the dashes as geometry (a subpath each), for plotters: svg_document
        False, "--dash-paths", "Write the hidden lines' dashes as geometry (a subpath per dash) instead of a dash "
        "style: for plotters (vpype draws a styled dash pattern solid).", switch=True)
    exr: PassOptions | None = None  # one multilayer EXR per frame with these passes; None: no EXR (--exr)
    lines_png: bool = option(  # the strokes as an RGBA PNG (the EXR's lines layer)
        False, "--lines-png", "Also lines/frame_NNNN.png: the visible strokes as an RGBA image.", switch=True)

    def stem(self, frame: int) -> str:
        return self.pattern.format(frame=frame)

    def check_names(self, frames, raster: RasterOptions | None) -> None:
        """UsageError when the pattern gives two of `frames` the same name (a pattern such as
        f_{frame:.0e} writes frames 10, 11 and 12 to one file: each would overwrite the last)."""
        seen: dict[str, int] = {}
        longest = max((len(p.name) - len(self.stem(0)) for p in self.frame_files(0, raster)), default=0)
        for f in frames:
            name = self.stem(f)
            if name in seen:
                raise UsageError(f"--pattern {self.pattern!r} names frames {seen[name]} and {f} alike ({name!r}): "
                                 "one would overwrite the other")
            seen[name] = f
            # (Files are written as .<name>.<8 random><TEMP_SUFFIX> first.)
            if len(name.encode()) + longest + 10 + len(TEMP_SUFFIX) > NAME_MAX:
                raise UsageError(f"--pattern {self.pattern!r} makes frame {f}'s file names longer than the "
                                 f"{NAME_MAX} bytes a file name may have")

    def frame_file(self, frame: int, suffix: str) -> Path:
        """OUT/<pattern>.<suffix>: the suffix is appended, never replaces a dotted part of the
        name (a pattern like shot.{frame:04d} keeps its frame number)."""
        return self.out_dir / f"{self.stem(frame)}{suffix}"

    def frame_files(self, frame: int, raster: RasterOptions | None) -> list[Path]:
        """The files one frame produces with these options and the raster pass `raster`."""
        out = []
        if self.svg:
            out.append(self.frame_file(frame, ".svg"))
        if self.json:
            out.append(self.frame_file(frame, ".json"))
        if self.gltf and not self.gltf_sequence:
            out.append(self.frame_file(frame, ".glb"))
        out += self.pass_files(frame, raster)
        if self.exr is not None:
            out.append(self.frame_file(frame, ".exr"))
        return out

    def pass_folders(self, raster: RasterOptions | None) -> list[str]:
        """The image passes written as PNG with the raster pass `raster`, one folder each
        (OUT/<pass>/<pattern>.png), so that the frame number is the last number of every file
        name and each folder is one image sequence."""
        out = raster_file_suffixes(raster) if raster is not None else []
        return out + (["lines"] if self.lines_png else [])

    def pass_files(self, frame: int, raster: RasterOptions | None) -> list[Path]:
        """OUT/<pass>/<pattern>.png of one frame, for each pass in `pass_folders`."""
        return [self.out_dir / p / f"{self.stem(frame)}.png" for p in self.pass_folders(raster)]


@dataclass(frozen=True)
class RunSpec:
    """Everything a run needs: the scene file, the (frame number, camera) pairs, what they draw
    and what is written."""

    scene_path: str
    cameras: tuple[tuple[int, Camera], ...]
    outputs: OutputOptions
    request: RenderRequest = field(default_factory=RenderRequest)
    workers: int = option(
        1, "--workers", "Frames drawn at once: by this process and N-1 workers beside it (--worker-kind; default: "
        "the machine's cores for a sequence with a raster pass or of at least "
        f"{PROCESSES_FROM} frames, else 1; at most 4 per core, 8 on smaller machines).",
        low=1, high=MAX_WORKERS, needs="no scheduler")
    worker_kind: str = option(
        "auto", "--worker-kind", "What the workers are: threads of this process (they share its scene and BVH and "
        "start at once) or processes (each imports strokekit and loads the scene, about a second, then draws frames "
        "without sharing Python's lock with the others: for long runs); auto: threads with a raster pass, processes "
        f"without one from {PROCESSES_FROM} frames on.",
        choices=WORKER_KINDS, show_default=True, needs="no scheduler")
    scheduler: str | None = option(None, "--scheduler", "dask.distributed scheduler address, e.g. tcp://host:8786.")
    skip_existing: bool = option(  # resume: see run(); frames of another scene or options are a UsageError
        False, "--skip-existing", "Resume: do not rewrite frames whose files all exist and were rendered from the "
        "same scene, options and camera (OUT/.strokekit-run.json says so; with fewer outputs than then, the others' "
        "files stay as they are); frames of another scene or other options are a usage error.", switch=True)
    fail_fast: bool = option(False, "--fail-fast", "Stop at the first failed frame (frames already written stay; the "
                             "run streams them out in order).", switch=True)
    camera_source: str = ""  # where the cameras come from (a camera file's path, "orbit"): for the report
    fps: float = 24.0  # the camera path's frame rate: frame N shows the scene's animation at (N - 1) / fps

    def __post_init__(self):
        if self.worker_kind == "auto":
            kind = pool_for(len(self.cameras), self.raster is not None, self.workers)[1]
            object.__setattr__(self, "worker_kind", kind)
        # A cluster's workers resolve a relative name in their own folders (frames written on
        # their disks, the scene not found): a run on one names every file the tasks read or
        # write by its absolute path.
        if self.scheduler:
            o = self.outputs
            g = o.gltf_options
            if g is not None and g.brush not in BUNDLED:  # a PNG of the user's, read by the GLB writer
                g = replace(g, brush=os.path.abspath(g.brush))
            object.__setattr__(self, "scene_path", os.path.abspath(self.scene_path))
            object.__setattr__(self, "outputs", replace(o, out_dir=Path(os.path.abspath(o.out_dir)), gltf_options=g))

    @property
    def raster_threads(self) -> int:
        """Threads of each frame's z-buffer: the machine's cores where the frames are drawn one at
        a time (one worker, no cluster), else 1 (the workers share the cores)."""
        return (os.cpu_count() or 1) if self.workers == 1 and not self.scheduler else 1

    @cached_property
    def plan(self) -> SequencePlan:
        """The request settled for this run's frames."""
        return self.request.plan(len(self.cameras), self.fps)

    @property
    def lines(self) -> LineOptions:
        return self.request.lines

    @property
    def raster(self) -> RasterOptions | None:
        return self.request.raster

    def frame_files(self, frame: int) -> list[Path]:
        """The files one frame of the run produces."""
        return self.outputs.frame_files(frame, self.raster)

    def pass_folders(self) -> list[str]:
        """The folders of the run's PNG passes (OutputOptions.pass_folders)."""
        return self.outputs.pass_folders(self.raster)


@dataclass
class StageRecord:
    name: str
    ran: bool
    why: str
    seconds: float = 0.0


def add_timings(stages: dict[str, StageRecord], timings: dict) -> None:
    """Add a task's seconds per stage (keys: stage names, or RASTER_STAGES' keys) to the run's
    stages: a stage's time is the work done in all processes."""
    for key, sec in timings.items():
        name = RASTER_STAGES[key][0] if key in RASTER_STAGES else key
        if name in stages:
            stages[name].seconds += sec


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
    #: The first file the run could not write ("PATH: strerror"; it stopped there, RunWriteError).
    write_error: str | None = None

    @property
    def exit_code(self) -> int:
        if self.interrupted:
            return 130  # the shell's code for a process stopped by SIGINT
        if self.write_error is not None:
            return 1  # an unwritable output, as one found before the run
        if not self.failures:
            return 0
        return 3 if self.frames_ok or self.frames_skipped else 1

    @property
    def status(self) -> str:
        """'ok', 'interrupted', 'partial' (some frames failed) or 'failed' (no frame done)."""
        if self.interrupted:
            return "interrupted"
        return {0: "ok", 3: "partial"}.get(self.exit_code, "failed")


class RunWriteError(OSError):
    """A file of the run could not be written (disk full, no permission, a failing device). The
    run stopped at the first such error (errno, strerror and filename are its), removed the files
    of the frames it left part-written (a frame is on disk whole or not at all) and raises it;
    `result` holds what was done before, with `result.write_error` set. An OSError, so code that
    does not know it reports it as any unwritable file."""

    def __init__(self, error: OSError, result: RunResult):
        super().__init__(error.errno, error.strerror, error.filename)
        self.result = result


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
    o, L, plan = spec.outputs, spec.lines, spec.plan
    kinds = set(L.kinds)
    st = [StageRecord("load scene + BVH", True, "every run needs the scene and its occlusion BVH")]
    if scene.motion is not None and scene.motion.moves(scene.motion.animation(spec.request.animation)):
        st.append(StageRecord("pose scene", True, "the scene's animation moves its objects: each frame poses them "
                              "(still and rigidly moving objects keep their BVH, deforming ones get one a frame)"))

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
    if L.occlusion is None:
        st.append(StageRecord("visibility", True, "Embree occlusion samples and bisection of every change"))
    else:
        lo, hi = L.occlusion
        st.append(StageRecord("visibility", False, "replaced by the occlusion levels (their level 0)"))
        st.append(StageRecord("occlusion levels", True,
                              f"--hidden / --occlusion {lo}-{hi}: surfaces in front of the samples counted "
                              "(Embree hit lists), carried across outline crossings by Appel's rule where the "
                              "geometry is clear, every other change of level bisected"))
    st.append(StageRecord("chaining", True, "visible runs linked into strokes"))
    n = len(spec.cameras)
    add("tracking", plan.tracking is not None,
        f"{n} frames with coherence on", "brush paths drawn (--strokes brush: they carry their own ids)"
        if plan.paths is not None else "single frame or --no-coherence")
    add("brush paths", plan.paths is not None,
        f"--strokes brush ({'carried from frame to frame' if plan.carried else 'one frame at a time'})",
        "--strokes lines: the lines are drawn")
    add("svg", o.svg, "SVG output requested", "--no-svg")
    add("json", o.json, "JSON output requested", "--no-json")
    add("ribbons + glTF", o.gltf, "glTF output requested", "no glTF output requested")
    add("raster pass", plan.raster is not None, "a raster output was requested", "no raster output requested")
    if plan.raster is not None:
        for name, why in RASTER_STAGES.values():
            st.append(StageRecord(name, True, why))
    add("EXR", o.exr is not None, "--exr: " + ", ".join(o.exr.passes) if o.exr is not None else "", "no --exr")
    add("lines PNG", o.lines_png, "--lines-png", "no --lines-png")
    return st


#: The raster pass's parts as --explain lists them: {key of the frame task's timings: (stage name,
#: what it is)}. The kernels are compiled or loaded once per run in the main process, before
#: any frame; a worker loads them from numba's disk cache before its first raster frame.
RASTER_STAGES = {
    "kernels": ("  raster kernels", "numba kernels loaded once a process (compiled on a machine's first run)"),
    "rasterize": ("  z-buffer", "face, depth and barycentrics at K x K samples a pixel"),
    "shading": ("  labels + mixed pixels", "n.l, bands, the pixels a label, material or object edge crosses"),
    "edge samples": ("  edge samples", "z-buffer R x R samples of the mixed pixels"),
    "images": ("  images", "bands, shade colours, masks, ids, depth, fill from the pixels and edge samples"),
    "png": ("  PNG encode", "Up filter, zlib level 1"),
}


def raster_file_suffixes(options) -> list[str]:
    """The PNG passes (folder names) the raster pass writes for RasterOptions (none when it runs
    for the EXR alone: options.pngs off)."""
    if not options.pngs:
        return []
    out = ["bands"]
    if options.shade:
        out.append("shade")
    if options.masks:
        out += [f"mask{b}" for b in range(1, int(options.bands) + 1)]
    out += [name for name, on in (("objectid", options.objectid), ("depth", options.depth), ("fill", options.fill))
            if on]
    return out
