"""The baselines' inputs and targets: window features of an observed window, and a demo's robot
trajectory at normalised phases over its unobserved part."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from ...data import ROBOT, Demo
from .base import Transformer

N_PHASES = 50
"""Normalised phases over ``[obs_ratio, 1]`` at which trajectories are predicted and compared."""

FK = Callable[[np.ndarray], np.ndarray]
"""Forward kinematics: joint configurations (n, 7) in [rad] -> gripper positions (n, 3) in [m]."""


def window_features(window: Demo, observe: Sequence[str]) -> np.ndarray:
    """Window features (2 D_o,) of an observed window: per channel of the observed groups, in
    ``observe`` order, the mean and the last valid value (NaN for a group with no valid sample)."""
    means, lasts = [], []
    for g in observe:
        v = np.asarray(window.groups[g], dtype=float)
        valid = ~window.missing[g] if g in window.missing else np.ones(v.shape[0], dtype=bool)
        if np.any(valid):
            means.append(v[valid].mean(axis=0))
            lasts.append(v[valid][-1])
        else:
            means.append(np.full(v.shape[1], np.nan))
            lasts.append(np.full(v.shape[1], np.nan))
    return np.concatenate(means + lasts)


def phase_trajectory(demo: Demo, obs_ratio: float) -> np.ndarray:
    """The demo's robot joint angles (N_PHASES, J) in [rad] at normalised phases over [obs_ratio, 1]."""
    q = demo.groups[ROBOT]
    z = np.linspace(obs_ratio, 1.0, N_PHASES)
    t = demo.t - demo.t[0]
    return np.stack([np.interp(z * t[-1], t, q[:, j]) for j in range(q.shape[1])], axis=1)


def standardiser() -> Transformer:
    """Imputation of missing window features by the training mean, then standardisation."""
    from sklearn.impute import SimpleImputer
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler

    return make_pipeline(SimpleImputer(), StandardScaler())
