"""How much slower a motion must go for its failing checks to pass.

A failing check that going slower would fix says so in ``values["slowdown"]`` (a uniform
slow-down factor ``k >= 1``: velocities / k, accelerations / k^2, durations * k). The one-shot plan
re-times its path with limits scaled by ``k``; the closed loop re-plans with the reference followed
``k`` times slower (:meth:`~ipromp_pin.motion.retarget.Retargeter.plan`'s ``min_scale``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from ..robot import CheckResult

MAX_SLOWDOWN = 4.0
"""The largest slow-down a plan is given before it is refused (4x the duration)."""

MAX_SLOWDOWN_ROUNDS = 3
"""How many times a plan is slowed again when its slowed version still fails a check that asks for
a slower motion (the factor a check asks for is a first-order estimate: a slower motion meets the
moving human at other times and places)."""


def needed_slowdown(results: Sequence[CheckResult]) -> float | None:
    """The slow-down factor ``k >= 1`` that the failing required checks ask for together.

    Returns:
        1.0 when no required check failed; the largest requested ``k`` when every failing required
        check requested one (finite and at most :data:`MAX_SLOWDOWN`); ``None`` when a failing check
        cannot be fixed by slowing down.
    """
    k = 1.0
    for r in results:
        if not r.required or r.passed:
            continue
        hint = r.values.get("slowdown")
        if hint is None or not math.isfinite(float(hint)) or float(hint) > MAX_SLOWDOWN:
            return None
        k = max(k, float(hint))
    return k
