"""Shared fixtures."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SHARED_DATA = Path(os.environ.get("DEPTHGRAM_DATA") or ROOT.parent / "shared" / "data")  # as depthgram bench reads it


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """The real recordings in ``../shared/data``; the test is skipped when they are absent."""
    if not SHARED_DATA.is_dir():
        pytest.skip(f"real recordings not found at {SHARED_DATA} (CI keeps ../shared beside the checkout)")
    return SHARED_DATA
