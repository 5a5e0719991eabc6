"""A sequence of frames: what it draws (`RenderRequest`), each frame's way (`render_frame`, then
`StrokeCarry` in frame order), in memory (`render_sequence`) or as a render run (`run`: frames in
parallel in a process pool or a dask cluster, atomic writes, resumption and the run report)."""

from strokekit.lazy import exports

#: Public names and their modules, each imported when first used.
_EXPORTS = {
    "Frame": "strokekit.run.frame",
    "OutputOptions": "strokekit.run.spec",
    "RenderRequest": "strokekit.run.request",
    "RunInterrupted": "strokekit.run.spec",
    "RunResult": "strokekit.run.spec",
    "RunSpec": "strokekit.run.spec",
    "RunWriteError": "strokekit.run.spec",
    "SequencePlan": "strokekit.run.request",
    "StrokeCarry": "strokekit.run.frame",
    "Workers": "strokekit.run.workers",
    "make_executor": "strokekit.run.workers",
    "render_frame": "strokekit.run.frame",
    "render_sequence": "strokekit.run.sequence",
    "run": "strokekit.run.runner",
    "run_report": "strokekit.run.report",
}
__all__ = list(_EXPORTS)
__getattr__ = exports(__name__, _EXPORTS)
