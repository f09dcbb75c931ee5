"""Conditioning: a task's weight distribution given the observation at its MAP phase -> the prediction.

The latent posterior of one candidate is ``N(Q^-1 a, Q^-1)`` with ``P``, ``a`` and ``Q = I + P``
as in :mod:`ipromp_pin.promp.likelihood`, computed here for the winning task at its MAP phase,
per independent latent block (the blocks' posteriors are independent; the compiled
``condition_block`` kernel): per part ``X = nu I + G`` (one Cholesky), the observed dims' weights
get the extra correction ``X^-1 (b_d - G F_d eta)``, and the robot's weights are ``mu + F eta``
(its dims are never observed). The robot's covariance needs only the blocks whose factor columns
load on the robot (with two blocks, half the latent dims); the other blocks are conditioned only
when the predicted human channels are first asked for.

Everything that depends only on the model (a task's blocks, where the blocks' dims sit in the
observation parts, the basis on the prediction's phase grid) is computed once and cached in typed
caches (:class:`TaskBlocks`, :class:`BlockLayout`, :class:`PhaseGridTerms`).
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..exceptions import ModelError
from .basis import GaussianBasis
from .compiled import kernels
from .distribution import TaskModel
from .fitted import FittedModel
from .latent_blocks import LatentBlock
from .likelihood import InferenceEngine
from .observation import ObservationEncoder, ObservationPart
from .posterior import LazyGroups, Prediction, Recognition, RobotWeightPosterior

_NO_LOG = np.zeros(0, dtype=np.int64)


@dataclass(frozen=True)
class TaskBlocks:
    """The independent latent blocks of one task's model.

    Attributes:
        blocks: Per block of the inference engine, the block and the task's factor columns it uses.
        factors: Per block, those columns of the task's factor (D, K, r_b).
        robot_blocks: Indices of the blocks whose columns load on the robot.
        robot_cols: The columns of these blocks, then the robot's columns that load on no observed
            dim (their latent posterior is the prior).
        robot_factor: The factor restricted to ``robot_cols`` (D, K, r_R).
    """

    blocks: list[tuple[LatentBlock, np.ndarray]]
    factors: list[np.ndarray]
    robot_blocks: list[int]
    robot_cols: np.ndarray
    robot_factor: np.ndarray


@dataclass(frozen=True)
class BlockLayout:
    """Where one latent block's observed dims are in a list of observation parts.

    Attributes:
        parts: Indices of the parts that observe the block (None: all of them).
        positions: Columns of their values, concatenated over those parts.
        dims: Their model dims, concatenated likewise.
        offsets: Offsets of each part's entries in ``positions``/``dims``.
    """

    parts: list[int] | None
    positions: np.ndarray
    dims: np.ndarray
    offsets: np.ndarray


@dataclass(frozen=True)
class PhaseGridTerms:
    """Model-only quantities of one task on the prediction's phase grid (M phases in [0, 1]).

    Attributes:
        z: (M,) phases.
        phi: (M, K) basis values; ``phi2`` (M,) their squared norms.
        prior_mean: (M, J) the task's prior robot mean in [rad]; ``prior_std`` (M, J) in [rad].
        phi_f: (r, J, M) ``phi`` times the robot rows of the factor columns used.
    """

    z: np.ndarray
    phi: np.ndarray
    phi2: np.ndarray
    prior_mean: np.ndarray
    prior_std: np.ndarray
    phi_f: np.ndarray


def flatten_parts(parts: list[ObservationPart]) -> tuple[np.ndarray, ...]:
    """Observation parts as flat arrays (see ``condition_block``): concatenated times and their
    offsets, concatenated row-major values, their offsets and the parts' widths."""
    if len(parts) == 1:
        p = parts[0]
        return (
            p.t,
            np.array([0, p.t.size], dtype=np.int64),
            p.y.reshape(-1),
            np.array([0, p.y.size], dtype=np.int64),
            np.array([p.dims.size], dtype=np.int64),
        )
    return (
        np.concatenate([p.t for p in parts]),
        np.cumsum([0] + [p.t.size for p in parts]),
        np.concatenate([p.y.reshape(-1) for p in parts]),
        np.cumsum([0] + [p.y.size for p in parts]),
        np.array([p.dims.size for p in parts], dtype=np.int64),
    )


def block_diag_chol(chols: list[np.ndarray], n_eye: int) -> np.ndarray:
    """Block-diagonal matrix of the lower Cholesky factors ``chols`` then an identity of size ``n_eye``."""
    n = sum(c.shape[0] for c in chols) + n_eye
    out = np.eye(n)
    i = 0
    for c in chols:
        out[i : i + c.shape[0], i : i + c.shape[0]] = c
        i += c.shape[0]
    return out


def robot_posterior_mean(
    basis: GaussianBasis,
    robot: slice,
    t_norm: float,
    nu: float,
    mean: np.ndarray,
    diag: np.ndarray,
    factor: np.ndarray,
    parts: list[ObservationPart],
    alpha: float,
) -> np.ndarray:
    """Conditioned mean (J, K) of the robot weights (dims ``robot``) of a weight distribution (``mean``
    (D, K), ``diag`` (D,), ``factor`` (D, K, r)) given an observation at the phase ``alpha``, with the
    noise ratio ``nu`` and nominal duration ``t_norm`` in [s] (one latent block)."""
    r = factor.shape[2]
    inv_dur = 1.0 / (alpha * t_norm)
    ke_p = np.array([basis.support_count(float(p.t[-1]) * inv_dur) for p in parts], dtype=np.int64)
    pos_cat = np.concatenate([np.arange(p.dims.size) for p in parts])  # every column of every part
    dims_cat = np.concatenate([p.dims for p in parts]).astype(np.int64)
    p_off = np.cumsum([0] + [p.dims.size for p in parts]).astype(np.int64)
    w = np.array(mean, dtype=float)  # conditioned in place (robot rows: mu + F eta)
    ok = kernels().condition_block(
        *flatten_parts(parts), pos_cat, dims_cat, p_off, ke_p, inv_dur, basis.centres, basis.width,
        basis.step_factor, w.copy(), np.ascontiguousarray(diag, dtype=float),
        np.ascontiguousarray(factor, dtype=float), nu, w, np.empty((r, r)),
    )  # fmt: skip
    if not ok:
        raise ModelError("X = nu I + B^T B or Q = I + P is not numerically positive definite")
    return w[robot]


class Conditioner:
    """Conditioned predictions of one fitted model (caches the model-only quantities).

    Args:
        fitted: The fitted model.
        engine: Its inference engine (the latent blocks).
        encoder: Its observation encoder (the observed dims' scaling).
        n_points: Number M of points of the predicted trajectories.
    """

    def __init__(
        self, fitted: FittedModel, engine: InferenceEngine, encoder: ObservationEncoder, n_points: int
    ) -> None:
        self.fitted = fitted
        self.engine = engine
        self.encoder = encoder
        self.n_points = int(n_points)
        self._task_blocks: dict[str, TaskBlocks] = {}
        self._layouts: dict[tuple[str, tuple[bytes, ...]], list[BlockLayout | None]] = {}
        self._grids: dict[tuple[str, str], PhaseGridTerms] = {}

    def condition(self, rec: Recognition, parts: list[ObservationPart]) -> Prediction:
        """Condition the recognised task's weights on the observation parts at its MAP phase."""
        kern = kernels()
        fm = self.fitted
        task = rec.task
        m = fm.models[task]
        alpha = float(rec.alpha[fm.tasks.index(task)])
        w_post = m.mean.copy()
        info = self.task_blocks(task)
        inv_dur = 1.0 / (alpha * fm.duration_nominal_s)
        basis = fm.basis
        ke_p = np.array([basis.support_count(float(p.t[-1]) * inv_dur) for p in parts], dtype=np.int64)
        flat = flatten_parts(parts)
        layouts = self.block_layouts(task, parts)

        def run(b: int, w: np.ndarray) -> np.ndarray:
            """Condition latent block ``b`` into the weights ``w`` -> the Cholesky factor of its ``Q``."""
            factor = info.factors[b]
            r = factor.shape[2]
            lay = layouts[b]
            if lay is None:  # no observed dim of this block: its latent posterior is the prior
                return np.eye(r)
            if lay.parts is None:
                args = (*flat, ke_p)
            else:
                args = (*flatten_parts([parts[i] for i in lay.parts]), ke_p[lay.parts])
            lq = np.empty((r, r))
            ok = kern.condition_block(
                *args[:5], lay.positions, lay.dims, lay.offsets, args[5], inv_dur,
                basis.centres, basis.width, basis.step_factor, m.mean, m.diag, factor, fm.nu_condition,
                w, lq,
            )  # fmt: skip
            if not ok:
                raise ModelError("X = nu I + B^T B or Q = I + P is not numerically positive definite")
            return lq

        robot_chol = [run(b, w_post) for b in info.robot_blocks]
        others = [b for b in range(len(layouts)) if b not in info.robot_blocks]

        def human_weights() -> np.ndarray:
            # the blocks that do not load on the robot only move the observed dims' weights
            # (human predictions): conditioned when those are first asked for
            w = w_post.copy()
            for b in others:
                run(b, w)
            return w

        n_free = info.robot_cols.size - sum(c.shape[0] for c in robot_chol)
        lq = robot_chol[0] if len(robot_chol) == 1 and n_free == 0 else block_diag_chol(robot_chol, n_free)
        return self.prediction(rec, info.robot_factor, m, alpha, w_post, lq, human=human_weights)

    def prior_prediction(self, rec: Recognition) -> Prediction:
        """The unconditioned prediction (the prior) of the recognised task at its phase estimate: what
        an observation no task explains leaves (it informs no weight)."""
        fm = self.fitted
        m = fm.models[rec.task]
        alpha = float(rec.alpha[fm.tasks.index(rec.task)])
        info = self.task_blocks(rec.task)
        lq = np.eye(info.robot_cols.size)
        return self.prediction(rec, info.robot_factor, m, alpha, m.mean.copy(), lq)

    def observe_handover(
        self, pred: Prediction, readout: np.ndarray, values: np.ndarray, cov: np.ndarray
    ) -> Prediction:
        """The prediction also conditioned on an observation ``values = readout q(T) + e``,
        ``e ~ N(0, cov)``, of its final joint angles (the hand-over regression of
        :mod:`~ipromp_pin.promp.handover`): exact Gaussian conditioning of the robot's weights
        (:meth:`~ipromp_pin.promp.weight_posterior.RobotWeightPosterior.readout_update`); the task,
        phase and human estimates are unchanged."""
        info = self.task_blocks(pred.task)
        c = self.grid_terms(pred.task, info.robot_factor, "robot")
        if pred.robot_weights is None:
            raise ValueError("this prediction holds no weight posterior to condition")
        rw, d_mean, d_cov = pred.robot_weights.readout_update(c.phi[-1], readout, values, cov, c.phi_f)
        out = copy.copy(pred)  # a shallow copy (dataclasses.replace runs the whole __init__)
        out.q_mean, out.q_cov, out.robot_weights = pred.q_mean + d_mean, pred.q_cov - d_cov, rw
        return out

    def block_layouts(self, task: str, parts: list[ObservationPart]) -> list[BlockLayout | None]:
        """Per latent block of a task, where its observed dims are in the parts (None when no part
        observes the block; cached per the parts' dims)."""
        key = (task, tuple(p.dims.tobytes() for p in parts))
        out = self._layouts.get(key)
        if out is None:
            out = []
            for block, _ in self.task_blocks(task).blocks:
                sel = [block.select(p.dims) for p in parts]
                keep = [i for i, (pos, _) in enumerate(sel) if pos.size]
                if not keep:
                    out.append(None)
                    continue
                out.append(
                    BlockLayout(
                        parts=None if len(keep) == len(parts) else keep,
                        positions=np.concatenate([sel[i][0] for i in keep]),
                        dims=block.dims[np.concatenate([sel[i][1] for i in keep])],
                        offsets=np.cumsum([0] + [sel[i][0].size for i in keep]).astype(np.int64),
                    )
                )
            self._layouts[key] = out
        return out

    def task_blocks(self, task: str) -> TaskBlocks:
        """The independent latent blocks of a task's model (cached)."""
        info = self._task_blocks.get(task)
        if info is None:
            fm = self.fitted
            m = fm.models[task]
            loads = np.any(m.factor != 0.0, axis=1)  # (D, r)
            robot = np.any(loads[fm.layout.robot_slice], axis=0)
            blocks, factors, robot_blocks, cols_r = [], [], [], []
            seen = np.zeros(m.rank, dtype=bool)
            ti = fm.tasks.index(task)
            for block in self.engine.blocks:
                cols = block.cols[ti]
                seen[cols] = True
                blocks.append((block, cols))
                factors.append(np.ascontiguousarray(m.factor[:, :, cols]))
                if np.any(robot[cols]):
                    robot_blocks.append(len(blocks) - 1)
                    cols_r.append(cols)
            cols_r.append(np.flatnonzero(robot & ~seen))
            robot_cols = np.concatenate(cols_r).astype(np.int64)
            info = TaskBlocks(
                blocks=blocks,
                factors=factors,
                robot_blocks=robot_blocks,
                robot_cols=robot_cols,
                robot_factor=np.ascontiguousarray(m.factor[:, :, robot_cols]),
            )
            self._task_blocks[task] = info
        return info

    def grid_terms(self, task: str, factor: np.ndarray, which: str) -> PhaseGridTerms:
        """Model-only quantities on the prediction's phase grid (cached per task and ``which`` factor
        columns: ``"robot"`` those of :meth:`task_blocks`, ``"all"`` every column)."""
        key = (task, which)
        c = self._grids.get(key)
        if c is None:
            fm = self.fitted
            rs = fm.layout.robot_slice
            m = fm.models[task]
            z = np.linspace(0.0, 1.0, self.n_points)
            phi = fm.basis(z)
            mean, std = m.distribution(phi)
            fr = factor[rs]
            c = PhaseGridTerms(
                z=z,
                phi=phi,
                phi2=np.sum(phi * phi, axis=1),
                prior_mean=fm.scaler.inverse(mean[:, rs], rs),
                prior_std=std[:, rs] * fm.scaler.scale[rs],
                phi_f=np.ascontiguousarray(np.einsum("mk,jkr->rjm", phi, fr)),  # (r, J, M)
            )
            self._grids[key] = c
        return c

    def prediction(
        self,
        rec: Recognition,
        factor: np.ndarray,
        m: TaskModel,
        alpha: float,
        w_post: np.ndarray,
        lq: np.ndarray,
        which: str = "robot",
        human: Callable[[], np.ndarray] | None = None,
    ) -> Prediction:
        """The prediction from the conditioned weights ``w_post`` (D, K) (their observed dims' rows
        completed by ``human()`` when given), the factor columns ``factor`` (D, K, r) of the robot's
        latent posterior and the lower Cholesky factor ``lq`` (r, r) of its precision."""
        fm = self.fitted
        rs = fm.layout.robot_slice
        nj = rs.stop - rs.start
        duration = alpha * fm.duration_nominal_s
        c = self.grid_terms(m.task, factor, which)
        phi = c.phi
        scale = fm.scaler.scale[rs]
        offset = fm.scaler.offset[rs]
        kern = kernels()
        q_mean = kern.channel_values(phi, np.ascontiguousarray(w_post[rs]), scale, offset, _NO_LOG, scale)
        if lq.shape[0]:
            cov = kern.prediction_cov(lq, c.phi_f, c.phi2, m.diag[rs], scale)
        else:
            cov = np.zeros((phi.shape[0], nj, nj))
            idx = np.arange(nj)
            cov[:, idx, idx] += c.phi2[:, None] * m.diag[rs]
            cov *= scale[:, None] * scale[None, :]
        n_obs = fm.layout.n_obs_dims
        enc = self.encoder
        slices = [(g, *fm.layout.slices[g]) for g in fm.layout.observe]

        def human_means() -> dict[str, np.ndarray]:
            w = w_post if human is None else human()
            w_obs = np.ascontiguousarray(w[:n_obs])
            vals = kern.channel_values(phi, w_obs, enc.scale, enc.offset, enc.log_idx, fm.scaler.log_shift)
            return {g: np.ascontiguousarray(vals[:, glo:ghi]) for g, glo, ghi in slices}

        return Prediction(
            **vars(rec),
            t=c.z * duration,
            q_mean=q_mean,
            q_cov=cov,
            q_prior_mean=c.prior_mean,
            q_prior_std=c.prior_std,
            joint_names=tuple(fm.layout.joint_names),
            human_mean=LazyGroups(fm.layout.observe, human_means),
            robot_weights=RobotWeightPosterior(
                mean=w_post[rs],
                diag=m.diag[rs],
                factor=factor[rs],
                q_chol=lq,
                phi=phi,
                offset=offset,
                scale=scale,
                basis=fm.basis,
            ),
        )
