"""Fitting a multi-task Interaction ProMP: from demonstrations and parameters to a :class:`FittedModel`.

What :meth:`IProMP.fit <ipromp_pin.promp.estimator.IProMP.fit>` runs, as pure functions of the
estimator's parameters (its ``get_params()``):

1. :func:`~ipromp_pin.promp.training.prepare_training`: layout, scaling, per-demo weights and phases;
2. :func:`select_hyperparameters`: the noise ratio and temperature, the recognition head, the coupled
   groups with the conditioning noise ratio and the hand-over regression, by cross-validation on the
   training demos (:mod:`~ipromp_pin.promp.selection`, :mod:`~ipromp_pin.promp.handover_selection`);
3. :func:`~ipromp_pin.promp.training.task_models` with the chosen coupling, frozen in a
   :class:`~ipromp_pin.promp.fitted.FittedModel` and checked
   (:func:`~ipromp_pin.promp.validation.check_fitted`).
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..data import Dataset, Demo
from ..exceptions import ModelError
from .basis import GaussianBasis
from .branches import warn_mixed_branches
from .fitted import FittedModel
from .gripper_side import aligned_demos, gripper_kinematics, is_gripper_group
from .handover import HandoverRegression
from .handover_orientation import OrientationEstimate
from .handover_selection import HandoverChoice, choose_handover, final_configurations
from .head import RecognitionHead
from .novelty import NoveltyDetector, NoveltyRow, fit_novelty
from .provenance import demo_record
from .selection import (
    NOISE_GRID,
    TEMPERATURE_GRID,
    HeldOutRow,
    choose_coupling,
    choose_noise,
    explained_rows,
    fit_recognition_head,
)
from .training import PhaseSettings, TrainingSet, demos_by_task, log_task_prior, prepare_training, task_models
from .validation import check_fitted

ForwardKinematics = Callable[[np.ndarray], np.ndarray]
"""Joint angles (n, J) in [rad] -> hand-over positions (n, 3) in [m]."""


@dataclass
class Hyperparameters:
    """What the cross-validations on the training demos chose (see :class:`FittedModel`).

    Attributes:
        noise_ratio: ``nu``; ``noise_cv_scores`` its candidates' scores (empty when given).
        temperature: ``tau``.
        head: The recognition head (None: none).
        coupled_groups: Observed groups coupled to the robot; ``coupling_cv_scores`` the candidates'.
        condition_noise_ratio: ``nu_c``; ``condition_cv_scores`` the candidates'.
        handover: The hand-over regression (None: none); ``handover_cv_scores`` the trust factors'.
        orientation: The hand-over orientation estimate (None: none); ``orientation_cv_scores`` the
            trust factors'.
        novelty: The novelty detector (None: none).
    """

    noise_ratio: float
    temperature: float
    coupled_groups: list[str]
    condition_noise_ratio: float
    head: RecognitionHead | None = None
    handover: HandoverRegression | None = None
    noise_cv_scores: Mapping[float, float] = field(default_factory=dict)
    coupling_cv_scores: Mapping[str, float] = field(default_factory=dict)
    condition_cv_scores: Mapping[float, float] = field(default_factory=dict)
    handover_cv_scores: Mapping[float, float] = field(default_factory=dict)
    orientation: OrientationEstimate | None = None
    orientation_cv_scores: Mapping[float, float] = field(default_factory=dict)
    novelty: NoveltyDetector | None = None


def phase_settings(params: Mapping[str, Any]) -> PhaseSettings:
    """The phase candidates' and covariances' settings of the estimator's parameters."""
    return PhaseSettings(int(params["n_alpha"]), float(params["alpha_width"]), float(params["pooling"]))


def select_hyperparameters(
    training: TrainingSet,
    params: Mapping[str, Any],
    observe: list[str],
    coupling: str | list[str],
    task_log_prior: np.ndarray,
    fk: ForwardKinematics | None = None,
    fk_rot: ForwardKinematics | None = None,
) -> Hyperparameters:
    """Choose the noise ratio, temperature, head, coupling, conditioning noise and hand-over
    regression of ``params`` (given values kept, ``"auto"`` ones cross-validated)."""
    settings = phase_settings(params)
    nus = NOISE_GRID if isinstance(params["noise"], str) else (float(params["noise"]),)
    temp = params["temperature"]
    taus = TEMPERATURE_GRID if isinstance(temp, str) else (float(temp),)
    head, rows, novelty = None, [], None
    alpha = params.get("novelty_alpha")
    if len(nus) > 1 or len(taus) > 1 or params["head"] or params["handover"] or alpha is not None:
        noise = choose_noise(training, settings, task_log_prior, nus, taus)
        nu, tau, rows = (
            noise.nu,
            noise.temperature,
            explained_rows(noise.rows, noise.temperature, training.demos),
        )
        nu_scores = noise.scores if len(nus) > 1 else {}
        if params["head"] and rows:
            head = fit_recognition_head(rows, tau, len(training.tasks))
        if alpha is not None and rows:
            novelty = fit_novelty(
                novelty_rows(rows, tau),
                len(training.tasks),
                training.layout.n_obs_dims,
                training.duration_nominal_s,
                float(alpha),
            )
    else:
        nu, tau, nu_scores = nus[0], taus[0], {}
    nu_c = {"auto": None, "same": nu}.get(params["condition_noise"], params["condition_noise"])
    nu_c = None if nu_c is None else float(nu_c)
    cands = None if coupling == "auto" else [list(observe) if coupling == "all" else list(coupling)]
    choice = choose_coupling(training, settings, nu_c, cands, fk)
    ho = HandoverChoice(None, {})
    if params["handover"] and rows:
        ho = choose_handover(training, settings, choice.groups, choice.nu_condition, rows, tau, fk, fk_rot)
    return Hyperparameters(
        noise_ratio=nu,
        temperature=tau,
        coupled_groups=choice.groups,
        condition_noise_ratio=choice.nu_condition,
        head=head,
        handover=ho.regression,
        orientation=ho.orientation,
        noise_cv_scores=nu_scores,
        coupling_cv_scores=choice.scores,
        condition_cv_scores=choice.nu_scores,
        handover_cv_scores=ho.scores,
        orientation_cv_scores=ho.orientation_scores,
        novelty=novelty,
    )


def novelty_rows(rows: list[HeldOutRow], temperature: float) -> list[NoveltyRow]:
    """The held-out rows as the novelty detector reads them (MAP phases at the temperature)."""
    return [
        NoveltyRow(r.task, r.demo, r.window, r.ratio, r.recognised(temperature)[2], r.t_last) for r in rows
    ]


def fit_model(
    data: Dataset | Iterable[Demo],
    params: Mapping[str, Any],
    observe: list[str],
    coupling: str | list[str],
    fk: ForwardKinematics | None = None,
    limit_threads: Callable[[], contextlib.AbstractContextManager] = contextlib.nullcontext,
    fk_rot: ForwardKinematics | None = None,
) -> FittedModel:
    """The fitted model of demonstrations with the estimator's parameters ``params``.

    Args:
        data: A :class:`~ipromp_pin.data.Dataset` or demos (grouped by ``demo.task``).
        params: The estimator's parameters (``IProMP.get_params()``, validated).
        observe, coupling: The parsed observed groups and coupling (``parse_params``).
        fk: The robot's forward kinematics (the cross-validations then score the hand-over position;
            a gripper model's default: its position channels, :mod:`.gripper_side`).
        limit_threads: A context limiting the BLAS threads during the cross-validations.
        fk_rot: The gripper's rotations (joint angles (n, J) in [rad] -> rotation matrices (n, 3, 3));
            with ``fk``, the model gets a hand-over orientation estimate
            (:mod:`~ipromp_pin.promp.handover_orientation`) when its cross-validation keeps one.

    Raises:
        ModelError: the training produced an unusable model.
    """
    basis = GaussianBasis(params["n_basis"], params["width"], params["ridge"], params["margin"])
    by_task = demos_by_task(data)
    fitted_demos = by_task
    if is_gripper_group(params["robot_group"]):  # a gripper pose path: sign-consistent quaternions
        fitted_demos = aligned_demos(by_task)
        fk, fk_rot = (fk, fk_rot) if fk is not None else gripper_kinematics()
    training = prepare_training(fitted_demos, observe, params["robot_group"], basis, params["log_groups"])
    if fk is not None and not is_gripper_group(params["robot_group"]):
        warn_mixed_branches(final_configurations(training), fk)  # a task's demos on two IK branches
    prior = log_task_prior(training.tasks, params["task_prior"])
    with limit_threads():
        hp = select_hyperparameters(training, params, observe, coupling, prior, fk, fk_rot)
    models = task_models(
        training, training.weights, training.alphas, hp.coupled_groups, phase_settings(params)
    )
    fitted = FittedModel(
        layout=training.layout,
        basis=basis,
        scaler=training.scaler,
        tasks=training.tasks,
        models=models,
        duration_nominal_s=training.duration_nominal_s,
        task_log_prior=prior,
        noise_ratio=hp.noise_ratio,
        temperature=hp.temperature,
        head=hp.head,
        coupled_groups=tuple(hp.coupled_groups),
        residual_var=training.residual_var,
        noise_cv_scores=hp.noise_cv_scores,
        coupling_cv_scores=hp.coupling_cv_scores,
        condition_noise_ratio=hp.condition_noise_ratio,
        condition_cv_scores=hp.condition_cv_scores,
        handover=hp.handover,
        handover_cv_scores=hp.handover_cv_scores,
        orientation=hp.orientation,
        orientation_cv_scores=hp.orientation_cv_scores,
        novelty=hp.novelty,
        trained_on=tuple(demo_record(d) for demos in by_task.values() for d in demos),
    )
    return checked(fitted)


def checked(fitted: FittedModel) -> FittedModel:
    """``fitted`` if :func:`check_fitted` accepts it (raises ModelError naming the problem)."""
    try:
        check_fitted(fitted)
    except ModelError as exc:
        raise ModelError(f"training produced an unusable model (implausible training data?): {exc}") from None
    return fitted
