"""Sampling whole demonstrations from a task's prior (the learned distribution, before any observation).

A sample draws the stacked weights of every channel from the task's Gaussian,
``w = mean + sqrt(delta_d) xi + F eta`` with ``xi, eta ~ N(0, I)`` (the covariance
``blockdiag(delta_d I_K) + F F^T`` is never formed), and the phase ``alpha`` from the task's phase
prior (kept inside the span of its candidates, ``mu +- alpha_width sigma``); the channels are the
basis times the weights, mapped back to original units (EMG through ``exp``), on ``n_points``
uniform times over ``[0, alpha T_norm]``.
"""

from __future__ import annotations

import numpy as np

from ..data import Demo
from ..exceptions import ModelError
from .fitted import FittedModel


def sample_task_prior(
    fitted: FittedModel, task: str, n: int, n_points: int, rng: np.random.Generator | int | None = None
) -> list[Demo]:
    """``n`` demonstrations (every modelled group: observed human groups and the robot) drawn from
    the prior of ``task``, each with ``n_points`` samples; times in [s] from the start of the motion."""
    if task not in fitted.models:
        raise ModelError(f"unknown task '{task}' (tasks: {', '.join(fitted.tasks)})")
    if int(n) != n or n < 1:
        raise ModelError(f"the number of samples must be a positive integer, got {n!r}")
    rng = np.random.default_rng(rng)
    m = fitted.models[task]
    d, k, r = m.factor.shape
    xi = rng.standard_normal((n, d, k)) * np.sqrt(m.diag)[None, :, None]
    w = m.mean[None] + xi + np.einsum("dkr,nr->ndk", m.factor, rng.standard_normal((n, r)))
    z = np.linspace(0.0, 1.0, int(n_points))
    values = fitted.scaler.inverse(np.einsum("mk,ndk->nmd", fitted.basis(z), w))
    alpha = np.clip(rng.normal(m.alpha_mu, m.alpha_sigma, n), m.alpha_grid[0], m.alpha_grid[-1])
    layout = fitted.layout
    out = []
    for i in range(n):
        out.append(
            Demo(
                task=task,
                name=f"{task}_prior_{i:03d}",
                source=f"prior({task})",
                t=z * alpha[i] * fitted.duration_nominal_s,
                groups={g: values[i][:, lo:hi] for g, (lo, hi) in layout.slices.items()},
                channel_names={g: tuple(layout.channel_names[g]) for g in layout.groups},
            )
        )
    return out
