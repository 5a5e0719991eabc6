"""Shared fixtures. Helper functions live in tests/helpers.py."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import settings

# Tests read mesh files through trimesh every time: the scene cache (strokekit.scene) would make
# "loads the same twice" checks pass trivially. Its own test turns it on in a temporary folder.
os.environ["STROKEKIT_CACHE"] = "0"

# CI draws the same property-test examples on every run (a failure there is reproducible from the
# log); locally hypothesis keeps exploring new ones.
settings.register_profile("ci", derandomize=True, print_blob=True)
if os.environ.get("CI"):
    settings.load_profile("ci")

from helpers import MODELS  # noqa: E402


@pytest.fixture
def models_dir() -> Path:
    if not MODELS.exists():
        pytest.skip(f"shared models folder not found at {MODELS}")
    return MODELS


@pytest.fixture(scope="session", autouse=True)
def kernels():
    """The numba kernels, compiled (a machine's first run) or loaded once for the session, before
    any test: a test that checks a run's stderr line by line must not see the one-line compile
    notice of whichever test happens to run first."""
    from strokekit.lines.kernels import HIDDEN_LINES
    from strokekit.paths.kernels import BRUSH_PATHS
    from strokekit.raster.hits import RASTER
    from strokekit.tracking.kernels import TRACKING

    for group in (RASTER, HIDDEN_LINES, BRUSH_PATHS, TRACKING):
        group.warm()
