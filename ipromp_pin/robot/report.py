"""Results of the feasibility checks: one :class:`CheckResult` per check, gathered in a
:class:`FeasibilityReport` (pass/fail verdict, JSON and text forms)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np


@dataclass
class CheckResult:
    """Outcome of one feasibility check.

    Attributes:
        name: Check name (``joint_limits``, ``self_collision``, ``workspace``, ``hand_distance``,
            ``uncertainty``).
        status: ``"pass"``, ``"fail"`` or ``"skip"`` (not applicable, e.g. hand position unknown).
        reason: One-line human-readable explanation with the deciding numbers.
        values: The numbers (JSON-serialisable: floats, ints, strings, lists).
        required: Whether the check counts towards :attr:`FeasibilityReport.passed`.
    """

    name: str
    status: str
    reason: str
    values: dict = field(default_factory=dict)
    required: bool = True

    @property
    def passed(self) -> bool:
        """True unless the check failed (skipped checks pass)."""
        return self.status != "fail"


@dataclass
class FeasibilityReport:
    """Result of :func:`check_path`.

    Attributes:
        robot: Robot settings name.
        checks: The individual checks, in a fixed order.
        handover_pose: End-effector pose at the last sample (7,): x, y, z [m], quaternion x, y, z, w.
        ee_path: End-effector positions along the path (M, 3) in [m].
        timings_ms: Time spent per stage in [ms].
    """

    robot: str
    checks: list[CheckResult]
    handover_pose: np.ndarray
    ee_path: np.ndarray
    timings_ms: dict[str, float] = field(default_factory=dict)

    @property
    def passed(self) -> bool:
        """Whether every required check passed."""
        return all(c.passed for c in self.checks if c.required)

    def __getitem__(self, name: str) -> CheckResult:
        for c in self.checks:
            if c.name == name:
                return c
        raise KeyError(name)

    @property
    def failures(self) -> list[str]:
        """Names of the required checks that failed."""
        return [c.name for c in self.checks if c.required and not c.passed]

    def to_dict(self) -> dict:
        """JSON-serialisable summary (no arrays larger than the hand-over pose)."""
        return {
            "robot": self.robot,
            "passed": self.passed,
            "failures": self.failures,
            "handover_position_m": [float(x) for x in self.handover_pose[:3]],
            "handover_quat_xyzw": [float(x) for x in self.handover_pose[3:]],
            "checks": {
                c.name: {
                    "status": c.status,
                    "required": c.required,
                    "reason": c.reason,
                    **_jsonable(c.values),
                }
                for c in self.checks
            },
            "timings_ms": {k: round(float(v), 3) for k, v in self.timings_ms.items()},
        }

    def to_text(self) -> str:
        """Multi-line human-readable report."""
        p = self.handover_pose
        verdict = "PASSED" if self.passed else "FAILED: " + ", ".join(self.failures)
        lines = [
            f"Feasibility ({self.robot}): {verdict}",
            f"  hand-over position [m]: ({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f})",
        ]
        for c in self.checks:
            tag = c.status.upper() + ("" if c.required else " (advisory)")
            lines.append(f"  [{tag:>15}] {c.name}: {c.reason}")
        return "\n".join(lines)


def _jsonable(values: dict) -> dict:
    out = {}
    for k, v in values.items():
        if isinstance(v, np.ndarray):
            v = v.tolist()
        elif isinstance(v, np.generic):
            v = v.item()
        if isinstance(v, float) and not math.isfinite(v):
            v = None
        out[k] = v
    return out
