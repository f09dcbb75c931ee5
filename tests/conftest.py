"""Shared test fixtures.

Real recordings live in ``../shared/datasets`` beside the project root (or in
``$IPROMP_PIN_DATASETS``); tests that need them skip with a clear message when
that folder is absent.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

PROJECT_ROOT = Path(__file__).resolve().parents[1]
DATASETS = Path(os.environ.get("IPROMP_PIN_DATASETS", PROJECT_ROOT.parent / "shared" / "datasets"))


@pytest.fixture(scope="session")
def datasets_dir() -> Path:
    """Folder of the real recordings; skips the test when it is absent."""
    if not DATASETS.is_dir():
        pytest.skip(f"real datasets not found at {DATASETS} (set IPROMP_PIN_DATASETS)")
    return DATASETS


@pytest.fixture(scope="session")
def chen2017_dir(datasets_dir: Path) -> Path:
    """The paper's own recordings (Myo IMU + EMG + Baxter)."""
    path = datasets_dir / "chen2017_handover"
    if not path.is_dir():
        pytest.skip(f"{path} not found")
    return path


@pytest.fixture(scope="session")
def handover2017_dir(datasets_dir: Path) -> Path:
    """The later session (skeleton + EMG + Baxter, multiModal_states.csv)."""
    path = datasets_dir / "handover_20171128"
    if not path.is_dir():
        pytest.skip(f"{path} not found")
    return path
