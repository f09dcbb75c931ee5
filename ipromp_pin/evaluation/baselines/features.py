"""The baselines' inputs and targets: window features of an observed window, and a demo's robot
trajectory at normalised phases over its unobserved part."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from ...data import ROBOT, Demo
from ...promp.window import window_features as promp_window_features
from ...promp.window import window_summary
from .base import Transformer

N_PHASES = 50
"""Normalised phases over ``[obs_ratio, 1]`` at which trajectories are predicted and compared."""

FK = Callable[[np.ndarray], np.ndarray]
"""Forward kinematics: joint configurations (n, 7) in [rad] -> gripper positions (n, 3) in [m]."""


def window_features(window: Demo, observe: Sequence[str]) -> np.ndarray:
    """Window features (2 D_o,) of an observed window: the mean values, then the last valid values, of
    every channel of the observed groups in ``observe`` order (NaN for a group with no valid sample;
    :func:`ipromp_pin.promp.window.window_summary`, as the model's hand-over regression reads them)."""
    summaries = [
        window_summary(window.groups[g], ~window.missing[g] if g in window.missing else None, fill=np.nan)
        for g in observe
    ]
    return promp_window_features(np.concatenate(summaries, axis=1))


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
