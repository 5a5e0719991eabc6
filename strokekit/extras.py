"""Optional dependencies, installed with strokekit's extras: dask.distributed for a cluster run
(`strokekit[cluster]`), matplotlib for the benchmark's plot (`strokekit[plot]`). A feature that
needs one says how to install it, in one line, before any work."""

from __future__ import annotations

import importlib.util

from strokekit.errors import UsageError

#: {module: the extra that installs it}.
EXTRAS = {"distributed": "cluster", "matplotlib": "plot"}


def need(module: str, feature: str) -> None:
    """UsageError when `module` (one of EXTRAS) is not installed: `feature` ("--scheduler")
    needs it, and the line says which extra installs it."""
    try:
        found = importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):
        found = False
    if not found:
        raise UsageError(f"{feature} needs {module}, an optional dependency: pip install 'strokekit[{EXTRAS[module]}]'")
