"""Metrics read what the stages made: coherence of a sequence (BRIEF 3), accuracy against a
reference (BRIEF 2), golden-file differences of SVGs, and the speed/accuracy benchmark.

Imported at once (not through strokekit.lazy as the other packages): `accuracy` names both a
module and its function, and a lazy name is shadowed by the module once that is imported."""

from strokekit.metrics.accuracy import Accuracy, accuracy
from strokekit.metrics.bench import run_bench
from strokekit.metrics.coherence import folder_metrics, pair_metrics, sequence_metrics
from strokekit.metrics.diff import diff_paths

__all__ = ["Accuracy", "accuracy", "diff_paths", "folder_metrics", "pair_metrics", "run_bench", "sequence_metrics"]
