"""A render run: the stages the requested outputs need, frames in parallel (a process pool or a
dask cluster), tracking in frame order, atomic writes, resumption and the run report."""

from strokekit.run.report import run_report
from strokekit.run.runner import run
from strokekit.run.spec import OutputOptions, RunInterrupted, RunResult, RunSpec, RunWriteError
from strokekit.run.workers import Workers, make_executor

__all__ = ["OutputOptions", "RunInterrupted", "RunResult", "RunSpec", "RunWriteError", "Workers", "make_executor", "run",
           "run_report"]
