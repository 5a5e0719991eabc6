"""The numba kernels a run needs, warmed in one place (`RunKernels`): loaded from numba's disk
cache, or compiled on a machine's first run, in the main process before any frame, so that the
workers load them from the cache instead of each compiling them. Runs that need none never
import numba."""

from __future__ import annotations

from typing import Callable

from strokekit.lines.kernels import HIDDEN_LINES
from strokekit.numba_cache import KernelGroup, Warmup
from strokekit.paths.kernels import BRUSH_PATHS
from strokekit.raster.hits import RASTER, RASTER_THREADS
from strokekit.run.spec import RASTER_STAGES, RunSpec
from strokekit.scene.occluder import MOVING_SCENE
from strokekit.style.widths import STYLE_KERNELS
from strokekit.tracking.kernels import TRACKING
from strokekit.writers.exr import EXR_KERNELS, WRITTEN_COMPILED
from strokekit.writers.outline import OUTLINE_KERNELS

#: The kernels of styles with thickness modifiers: their widths and their SVG outlines.
LINE_STYLE = KernelGroup("line style", (STYLE_KERNELS, OUTLINE_KERNELS), compile_seconds=12)

#: The run stage each group's load time is counted in (the report, --explain).
STAGE_OF = {RASTER: RASTER_STAGES["kernels"][0], HIDDEN_LINES: "occlusion levels", BRUSH_PATHS: "brush paths",
            TRACKING: "tracking", MOVING_SCENE: "load scene + BVH", LINE_STYLE: "svg",
            RASTER_THREADS: RASTER_STAGES["kernels"][0],
            EXR_KERNELS: RASTER_STAGES["kernels"][0]}


def kernels_needed(spec: RunSpec, frames_here: bool, moving: bool = False) -> list[KernelGroup]:
    """The groups of kernels a run of `spec` uses in this process: those of the stages it runs in
    frame order (brush paths, the tracker), and those of the frames' own work (hidden lines, the
    raster pass, a `moving` scene's rays) where `frames_here` (this process draws frames, or its
    workers share this machine's cache; a style's thickness modifiers: the frames' widths and
    outlines)."""
    plan = spec.plan
    out = []
    if frames_here and moving:
        out.append(MOVING_SCENE)
    if plan.paths is not None:
        out.append(BRUSH_PATHS)
    elif plan.tracking is not None and plan.tracking.method == "kalnins" and len(spec.cameras) > 1:
        out.append(TRACKING)
    if frames_here and spec.lines.occlusion is not None:
        out.append(HIDDEN_LINES)
    if frames_here and spec.raster is not None:
        out.append(RASTER)
        if spec.raster_threads > 1:
            out.append(RASTER_THREADS)
        exr = spec.outputs.exr
        if exr is not None and exr.codec in WRITTEN_COMPILED:
            out.append(EXR_KERNELS)
    if frames_here and plan.style.has_thickness:
        out.append(LINE_STYLE)
    return out


class RunKernels:
    """The warm-up of a run's kernels. `raster`: start the raster kernels now, beside the
    caller's scene load (the caller draws frames in this process); `ready` warms the rest and
    waits where they compile; `seconds()` gives each stage's load time once the frames are
    drawn."""

    def __init__(self, notice: Callable[[str], None] | None = None, raster: bool = False):
        self.notice = notice
        self.warmups = [Warmup([RASTER], notice)] if raster else []

    def ready(self, spec: RunSpec, frames_here: bool, work: bool = True, moving: bool = False) -> None:
        """Before any frame: the kernels `spec` needs (none when no frame is drawn, `work`
        False; `moving`: the scene's animation moves it) loading, compiled first where the cache
        lacks them."""
        started = {g for w in self.warmups for g in w.groups}
        todo = [g for g in kernels_needed(spec, frames_here, moving) if g not in started] if work else []
        if todo:
            self.warmups.append(Warmup(todo, self.notice))
        for w in self.warmups:
            if w.compiles() is not False:
                w.join()

    def seconds(self) -> dict[str, float]:
        """{stage: seconds} the kernels took to load or compile (waits for the warm-up)."""
        out: dict[str, float] = {}
        for w in self.warmups:
            for g in w.groups:
                s = w.join().get(g.label, 0.0)
                out[STAGE_OF[g]] = out.get(STAGE_OF[g], 0.0) + s
        return out
