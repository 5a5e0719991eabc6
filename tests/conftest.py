"""Shared fixtures. Helper functions live in tests/helpers.py."""

from __future__ import annotations

from pathlib import Path

import pytest

from helpers import MODELS


@pytest.fixture
def models_dir() -> Path:
    if not MODELS.exists():
        pytest.skip(f"shared models folder not found at {MODELS}")
    return MODELS
