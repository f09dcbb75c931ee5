"""Inference with one fitted model: encode an observation, recognise the task, predict the robot.

A :class:`Predictor` bundles what every inference of a :class:`~ipromp_pin.promp.fitted.FittedModel`
shares: the observation encoder, the likelihood engine (built once: its tensors depend only on the
model), the phase and task priors, and the conditioner with its caches. The one-shot calls of
:class:`~ipromp_pin.promp.estimator.IProMP` and the streaming estimator both go through it.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..data import Demo
from .conditioning import Conditioner
from .fitted import FittedModel
from .likelihood import InferenceEngine
from .observation import ObservationEncoder, ObservationPart
from .posterior import PhasePriors, Prediction, Recognition, recognise_from_loglik, with_task_posterior
from .window import WindowSummary


class Predictor:
    """Recognition and prediction of one fitted model.

    Args:
        fitted: The fitted model.
        n_points: Number M of points of the predicted trajectories.

    Attributes:
        fitted: The fitted model.
        encoder: Its :class:`ObservationEncoder`.
        engine: Its :class:`InferenceEngine`.
        priors: Its :class:`PhasePriors`.
        conditioner: Its :class:`Conditioner`.
    """

    def __init__(self, fitted: FittedModel, n_points: int) -> None:
        self.fitted = fitted
        self.encoder = ObservationEncoder(fitted.layout, fitted.scaler, fitted.longest_s)
        models = fitted.task_models()
        self.engine = InferenceEngine(
            fitted.basis, models, fitted.layout.n_obs_dims, fitted.duration_nominal_s, fitted.noise_ratio
        )
        self.priors = PhasePriors(
            tasks=fitted.tasks,
            alphas=self.engine.alphas,
            log_prior=self.engine.log_prior,
            alpha_mu=np.array([m.alpha_mu for m in models]),
            task_log_prior=fitted.task_log_prior,
            duration_nominal_s=fitted.duration_nominal_s,
        )
        self.conditioner = Conditioner(fitted, self.engine, self.encoder, n_points)
        self._by_condition_noise: dict[float, Predictor] = {}

    def with_condition_noise(self, noise: float | None) -> Predictor:
        """A predictor whose conditioner conditions the robot's weights with the noise ratio ``noise``
        (its ``condition_noise_ratio``; the same fitted model otherwise: recognition and phase are
        this one's): this predictor when ``noise`` is None or its own ``nu_c``, else one built on
        first use and kept."""
        if noise is None or noise == self.fitted.nu_condition:
            return self
        key = float(noise)
        other = self._by_condition_noise.get(key)
        if other is None:
            fitted = dataclasses.replace(self.fitted, condition_noise_ratio=key)
            other = self._by_condition_noise[key] = Predictor(fitted, self.conditioner.n_points)
        return other

    def encode(self, observation: Demo, check_length: bool = True) -> tuple[list[ObservationPart], float]:
        """Validate and scale an observation (:meth:`ObservationEncoder.encode`)."""
        return self.encoder.encode(observation, check_length)

    def recognition_from_loglik(
        self, loglik: np.ndarray, t_last: float, window: WindowSummary | None = None
    ) -> Recognition:
        """The recognition from the log likelihood (T, C) of every (task, candidate) (tempered by the
        model's ``temperature``); with a recognition head, its task posterior given the observed
        ``window`` (needed then)."""
        fm = self.fitted
        tau = fm.temperature
        rec = recognise_from_loglik(self.priors, loglik if tau == 1.0 else tau * loglik, t_last)[0]
        if not rec.known:  # no task explains the observation: nothing more to decide
            return rec
        if (fm.head is not None or fm.novelty is not None) and window is None:
            raise ValueError("a model with a recognition head or novelty detector needs the window's summary")
        if fm.head is not None:
            assert window is not None
            rec = self._head_posterior(rec, window, t_last)
        if fm.novelty is not None:
            assert window is not None
            novelty, t_norm = fm.novelty, fm.duration_nominal_s
            alpha = np.where(np.isfinite(rec.log_evidence), rec.alpha, np.nan)
            rec.novelty_score = novelty.score(window.vector(), alpha, t_last, t_norm)
            rec.novelty_p_value = novelty.p_value(rec.novelty_score, t_last, t_norm)
            rec.known = rec.novelty_p_value > novelty.alpha
            if not rec.known:
                rec.unknown_reason = unknown_reason(rec, len(fm.tasks))
        return rec

    def _head_posterior(self, rec: Recognition, window: WindowSummary, t_last: float) -> Recognition:
        """``rec`` with the recognition head's task posterior. With tasks added after the fit (which
        the head does not know), the generative posterior splits the mass between the fitted tasks and
        the added ones, the head shares the fitted tasks' mass among them."""
        fm = self.fitted
        assert fm.head is not None
        scale = t_last / fm.duration_nominal_s  # of the observed fraction (observed_fraction)
        n_fit = fm.n_fit_tasks
        if n_fit == len(fm.tasks):
            log_post, post, best = fm.head.task_posterior(
                window, rec.log_posterior, rec.posterior, rec.alpha, scale
            )
            return with_task_posterior(rec, log_post, self.priors, post, best)
        fitted_mass = float(np.logaddexp.reduce(rec.log_posterior[:n_fit]))
        if not np.isfinite(fitted_mass):  # only added tasks explain it: the generative posterior
            return rec
        sub = rec.log_posterior[:n_fit] - fitted_mass
        head_lp, _, _ = fm.head.task_posterior(window, sub, np.exp(sub), rec.alpha[:n_fit], scale)
        log_post = np.concatenate([fitted_mass + head_lp, rec.log_posterior[n_fit:]])
        return with_task_posterior(rec, log_post, self.priors)

    def recognise(
        self, parts: list[ObservationPart], t_last: float, window: WindowSummary | None = None
    ) -> Recognition:
        """Task posterior and phase estimates of encoded observation parts (``window``: their summary,
        computed when the model needs it and it is not given)."""
        engine = self.engine
        loglik = engine.log_likelihood([engine.part_stats(p) for p in parts], t_last)
        if window is None and (self.fitted.head is not None or self.fitted.novelty is not None):
            window = WindowSummary.from_parts(parts, self.fitted.layout.n_obs_dims)
        return self.recognition_from_loglik(loglik, t_last, window)

    def predict(self, parts: list[ObservationPart], t_last: float) -> Prediction:
        """Recognition and the conditioned prediction of the most probable task, with the model's
        hand-over estimates applied (:meth:`with_estimates`)."""
        fm = self.fitted
        window = None
        if fm.head is not None or fm.handover is not None or fm.novelty is not None:
            window = WindowSummary.from_parts(parts, fm.layout.n_obs_dims)
        rec = self.recognise(parts, t_last, window)
        if math.isinf(rec.novelty_score):  # no task explains it: the prior of the most probable task
            return self.conditioner.prior_prediction(rec)
        pred = self.conditioner.condition(rec, parts)
        return self.with_estimates(pred, window, t_last)

    def with_estimates(self, pred: Prediction, window: WindowSummary | None, t_last: float) -> Prediction:
        """``pred`` (conditioned on the observation by this predictor's conditioner) also conditioned on
        the model's hand-over estimates: the hand-over regression given the observed ``window``
        (needed when the model has one) and the fraction ``t_last`` [s] of the predicted motion, then
        the orientation estimate (:meth:`Conditioner.observe_handover`); ``pred`` itself when the
        model has neither. The one step that the one-shot prediction and the stream share."""
        fm = self.fitted
        if fm.handover is None and fm.orientation is None:
            return pred
        k = fm.tasks.index(pred.task)
        if k >= fm.n_fit_tasks:  # a task added after the fit has no hand-over estimates
            return pred
        if fm.handover is not None:
            if window is None:
                raise ValueError("a model with a hand-over regression needs the observed window's summary")
            fraction = t_last / (float(pred.alpha[k]) * fm.duration_nominal_s)
            readout, values, cov = fm.handover.observation(k, window, fraction)
            pred = self.conditioner.observe_handover(pred, readout, values, cov)
        if fm.orientation is not None:
            readout, values, cov = fm.orientation.observation(k, pred.q_mean[-1], pred.q_cov[-1])
            pred = self.conditioner.observe_handover(pred, readout, values, cov)
        return pred


def unknown_reason(rec: Recognition, n_tasks: int) -> str:
    """The one-line reason of an observation recognised as none of the ``n_tasks`` tasks."""
    return f"the observation matches none of the {n_tasks} tasks: p = {rec.novelty_p_value:.3g}"
