"""Shared test fixtures: the real recordings' folders, a private package cache, and ``tiny`` (a small
synthetic dataset and its model) for the command-line tests.

Real recordings live in ``../shared/datasets`` beside the project root (or in
``$IPROMP_PIN_DATASETS``); tests that need them skip with a clear message when
that folder is absent.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest
import threadpoolctl

PROJECT_ROOT = Path(__file__).resolve().parents[1]
DATASETS = Path(os.environ.get("IPROMP_PIN_DATASETS", PROJECT_ROOT.parent / "shared" / "datasets"))


# The command line's "auto" kernels would compile the numba kernels in a background process when
# numba's cache is cold: the tests use the compiled kernels in-process (tests of "auto" set it).
os.environ.setdefault("IPROMP_PIN_KERNELS", "numba")

# The suite runs one test worker per core (pytest -n): BLAS threads on top of them would only
# contend for the cores (about 7 % more CPU time on 2 cores). One thread per worker and per command
# it starts; the library is loaded already, so its pool is also limited now.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
threadpoolctl.threadpool_limits(1)


@pytest.fixture(scope="session", autouse=True)
def private_cache_dir(tmp_path_factory) -> Path:
    """The package's cache (decimated preview meshes) in a folder of the test session, not the user's."""
    folder = tmp_path_factory.mktemp("ipromp_pin_cache")
    previous = os.environ.get("IPROMP_PIN_CACHE_DIR")
    os.environ["IPROMP_PIN_CACHE_DIR"] = str(folder)
    yield folder
    if previous is None:
        os.environ.pop("IPROMP_PIN_CACHE_DIR", None)
    else:
        os.environ["IPROMP_PIN_CACHE_DIR"] = previous


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


@pytest.fixture(scope="session")
def tiny(tmp_path_factory) -> tuple[Path, Path]:
    """A native dataset of 2 tasks x 4 synthetic demos and a model trained on it, built once per session:
    (dataset folder, model file). Tests read them and never change them."""
    from ipromp_pin.app import main  # imported here: after IPROMP_PIN_KERNELS is set above

    root = tmp_path_factory.mktemp("tiny")
    assert main(["synth", str(root / "ds"), "--tasks", "2", "--demos", "4"]) == 0
    assert main(["train", str(root / "ds"), "--out", str(root / "m.npz")]) == 0
    return root / "ds", root / "m.npz"
