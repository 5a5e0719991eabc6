"""A sequence of frames: what it draws (`RenderRequest`), each frame's way (`render_frame`, then
`StrokeCarry` in frame order), in memory (`render_sequence`) or as a render run (`run`: frames in
parallel in a process pool or a dask cluster, atomic writes, resumption and the run report)."""

from strokekit.run.frame import Frame, StrokeCarry, render_frame
from strokekit.run.report import run_report
from strokekit.run.request import RenderRequest, SequencePlan
from strokekit.run.runner import run
from strokekit.run.sequence import render_sequence
from strokekit.run.spec import OutputOptions, RunInterrupted, RunResult, RunSpec, RunWriteError
from strokekit.run.workers import Workers, make_executor

__all__ = ["Frame", "OutputOptions", "RenderRequest", "RunInterrupted", "RunResult", "RunSpec", "RunWriteError",
           "SequencePlan", "StrokeCarry", "Workers", "make_executor", "render_frame", "render_sequence", "run",
           "run_report"]
