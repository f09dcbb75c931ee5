"""Helpers of the command-line tests: the shipped pipeline and robot files, a ``run`` of the shared
``tiny`` dataset and model (see conftest.py), and the one error line a refused command prints."""

from __future__ import annotations

import dataclasses
from pathlib import Path

from ipromp_pin.app import main
from ipromp_pin.planning.one_shot import PlanResult
from ipromp_pin.safety import CheckContext, CheckReport, CheckSuite

PROJECT_ROOT = Path(__file__).resolve().parents[1]
PIPELINE = PROJECT_ROOT / "pipelines" / "baxter_handover.toml"
ROBOT_FILE = PROJECT_ROOT / "robots" / "baxter_left.toml"


def run_tiny(tiny: tuple[Path, Path], out: Path, *extra: str) -> int:
    """``ipromp-pin run`` of the shipped pipeline on the ``tiny`` (dataset, model), no preview; exit code."""
    ds, model = tiny
    return main(["run", str(PIPELINE), "--dataset", str(ds), "--model", str(model), "--out", str(out),
                 "--no-preview", *extra])  # fmt: skip


def one_error_line(err: str) -> str:
    """The single ``...: error: ...`` line of a command's stderr (asserts no traceback, exactly one)."""
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert "Traceback" not in err
    errors = [ln for ln in lines if ": error: " in ln]
    assert len(errors) == 1, err
    return errors[0]


def without_uncertainty(result: PlanResult, suite: CheckSuite) -> PlanResult:
    """``result`` as if the prediction had given no uncertainty (``suite``'s check skipped)."""
    check = suite.get("uncertainty")
    assert check is not None
    skipped = check.check(result.trajectory, CheckContext())
    verdicts = [skipped if v.name == "uncertainty" else v for v in result.checks]
    return dataclasses.replace(result, checks=CheckReport(verdicts))
