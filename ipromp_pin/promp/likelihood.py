"""Phase (alpha) estimation: exact Gaussian likelihood of a partial observation per phase candidate.

Model (scaled units, one task). Observed channel ``d`` sampled at times ``t_j``
is ``y_dj = phi(z_j)^T w_d + eps``, ``z_j = t_j / (alpha T_norm)``,
``eps ~ N(0, r_d)``, ``w ~ N(mu, Sigma)`` with the structured covariance
``Sigma = blockdiag(delta_d I_K) + F F^T`` and ``r_d = nu delta_d`` (see
:mod:`ipromp_pin.promp.distribution`). For one candidate let ``B`` (n, K) be the basis
matrix of the observed phases, ``G = B^T B`` and ``X = nu I + G``. Writing
``W_d = F_d / sqrt(delta_d)`` and ``b_d = B^T (y_d - B mu_d)``, the textbook
marginal likelihood ``N(y; Phi mu, Phi Sigma Phi^T + R)`` (Phi = block-diagonal
over channels) equals, by the Woodbury identity and the matrix determinant
lemma applied twice (first to the per-channel part, then to the rank-r part)::

    P   = sum_d W_d^T (I - nu X^-1) W_d              (r, r)
    a   = sum_d W_d^T X^-1 b_d / sqrt(delta_d)       (r,)
    Q   = I + P
    log p(y) = -1/2 [ n_y log 2 pi + sum_d (n log delta_d + (n - K) log nu + log|X|)
                      + log|Q| + sum_d (e_d^T e_d - b_d^T X^-1 b_d) / (nu delta_d)
                      - a^T Q^-1 a ]

so a candidate costs one K x K and one r x r Cholesky factorisation, shared by
all channels, instead of one (n D) x (n D) factorisation. The latent
coordinates ``eta`` of ``w = mu + F eta + ...`` have the posterior
``N(Q^-1 a, Q^-1)``, which gives the conditioned robot weights directly
(:mod:`ipromp_pin.promp.conditioning`); the robot's posterior weight covariance is
``blockdiag(delta_j I) + F_r Q^-1 F_r^T``.

Making it fast (:class:`InferenceEngine`, compiled numba kernels in :mod:`ipromp_pin.promp._kernels`):

* ``P`` is linear in ``X^-1``: ``P = sum_{k<=l} (delta_kl - nu X^-1_kl) Z[(k,l), :]``
  with ``Z[(k,l), (a,b)] = sum_d W_dka W_dlb`` (symmetrised, packed, precomputed
  per task), so P of all candidates of a task is ONE matrix product (BLAS); when the tasks'
  candidate windows overlap (the usual case) the ``Z`` tensors of all tasks and blocks sit side by
  side and P of every pair comes from one product per observation part (:data:`FUSE_SPAN`,
  :data:`FUSE_BYTES`).
  ``X^-1`` and ``log|X|`` come from one Cholesky factorisation per distinct
  candidate (``X`` is well conditioned: eigenvalues in ``[nu, nu + ||G||]``);
  the tests check the result against the dense textbook likelihood to 1e-8.
* ``a^T Q^-1 a`` and ``log|Q|`` come from one Cholesky factorisation of ``Q``
  per (task, candidate). The small factorisations run batched with the
  candidate index innermost (every step is a vector operation over candidates,
  exact IEEE arithmetic, no fast-math).
* All tasks' candidates lie on one common lattice (:func:`ipromp_pin.promp.distribution.alpha_candidates`):
  everything that depends only on the candidate (basis matrix, ``G``,
  ``B^T y``, ``X^-1``) is computed once per distinct candidate.
* Basis functions below 1e-11 on every observed phase are dropped (their
  contribution is below 1e-20 relative); the basis is evaluated with two
  exponentials per sample (the running product of :meth:`GaussianBasis.values_prefix_t`),
  and ``G = B^T B`` from 2K - 1 sums instead of K (K + 1) / 2, because with uniform
  centres the product of two bumps depends on ``k - l`` and ``k + l`` only
  (:meth:`GaussianBasis.gram_factors`).
* Every task's candidates are consecutive unique candidates, so the per-task work
  runs on contiguous windows; ``X^-1 B^T y`` is computed once per unique candidate
  and ``X^-1 mu`` of every task in one matrix product.
* Streaming: ``G``, ``B^T y`` and ``y^T y`` are running sums (one basis row per
  candidate per new sample).
* Independent blocks of observed dims (groups not coupled to the robot, see
  ``IProMP(coupling=...)``) have disjoint factor columns, so ``P`` is block-diagonal
  and the log likelihood is the sum of the blocks' (:func:`latent_blocks`); each
  block is handled with its own rank and ``Z``, sharing ``X^-1`` and the packed ``I - nu X^-1``.
  Blocks of equal rank keep their per-pair arrays side by side, so that one batched
  factorisation covers all of them (:attr:`InferenceEngine.lane_groups`).
* The kernels compile on the first inference of a process (importing the package
  does not import numba) and are cached on disk next to the module.

Cost per update: O(T C sum_b (K_e^2 r_b^2 / 4 + r_b^3 / 3 + K_e D_b r_b)) for T tasks,
C candidates, K_e active basis functions, blocks b of D_b observed dims and rank
r_b <= N - 1: linear in tasks and candidates.

Phase candidates: at least ``n_alpha`` (default 20) phases inside ``mu +- 3 sigma``
of every task's phase prior (one uniform lattice). The MAP phase is not limited to the
lattice: the log posterior, an analytic function of the phase, is interpolated around the
best candidate by degree-5 polynomials at 1/8 of the spacing and the best fine point is
refined by a parabola (:mod:`ipromp_pin.promp.posterior`). On the synthetic hand-overs this
lands closer to the exact continuous MAP (a 1000-candidate grid) at 10 % and 20 % observed than a
50-candidate grid with a parabola does (``benchmarks/inference.py``, phase section).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..exceptions import ModelError
from .basis import GaussianBasis
from .compiled import kernels
from .distribution import TaskModel
from .latent_blocks import LatentBlock, latent_blocks
from .observation import ObservationPart

LOG_2PI = float(np.log(2.0 * np.pi))

PAIR_LANES = 8
"""The (task, candidate) pair arrays are padded to a multiple of this many lanes (whole vector loops)."""

FUSE_SPAN = 1.25
"""The ``Z`` products of all tasks and blocks are one matrix product per part when the tasks' candidate
windows together span at most this many windows (the product's rows are the unique candidates of the
span: rows a task does not use are computed and left) ..."""

FUSE_BYTES = 1e6
"""... and when that product's result stays below this size (about the L2 cache): beyond it one product
per task and block is as fast and needs less memory."""

LANE_GROUP_BYTES = 256e3
"""Blocks of equal rank share one set of pair arrays while its packed ``Q`` stays below this size
(about half the L2 cache of the machines measured): beyond it, separate factorisations are faster."""


@dataclass
class PartStats:
    """Sufficient statistics of one observation part for every unique phase candidate.

    Attributes:
        dims: (D_m,) observed dims of the part.
        n: Number of samples.
        ke: Number of leading basis functions used.
        gram: (ke, ke, U) ``B^T B`` per unique candidate (candidate index last; may hold more
            than ``ke`` basis functions, only the first ``ke`` are used; only the lower triangle is
            read, and a stream fills only that).
        proj: (ke, U, D_m) ``B^T y``.
        sq: (D_m,) ``y^T y`` per dim.
    """

    dims: np.ndarray
    n: int
    ke: int
    gram: np.ndarray
    proj: np.ndarray
    sq: np.ndarray


class InferenceEngine:
    """Exact batched likelihood of an observation for every task and phase candidate.

    Everything that depends only on the model is precomputed here, per independent block of
    observed dims (:class:`LatentBlock`; a fully coupled model has one). The per-candidate
    quantities that depend only on the candidate's phase (basis matrix, ``X = nu I + G``, its
    inverse and log-determinant) are computed once per unique candidate and shared by all
    blocks and by all tasks whose grids contain the candidate. The log likelihood is the sum of
    the blocks' log likelihoods.

    Args:
        basis: Model basis.
        models: Task models (all with the same number of candidates).
        n_obs: Number of observed dims D_o (the first dims of every model).
        t_norm: Nominal duration in [s].
        nu: Noise ratio.
        z_budget_bytes: Largest size of the precomputed ``Z`` tensors of a block.

    Attributes:
        alphas: (T, C) every task's phase candidates; ``log_prior`` (T, C) their log prior weights.
        alpha_unique: (U,) the distinct candidates of all tasks (one lattice), ``inv_duration`` (U,)
            their ``1 / (alpha T_norm)`` in [1/s]; ``starts`` (T,) the index of each task's first
            candidate among them (a task's candidates are consecutive).
        blocks: The independent blocks of observed dims (:class:`LatentBlock`).
        lane_groups: Indices of the blocks of each rank: their per-pair arrays are laid side by side
            (:meth:`lane_arrays`) and factorised in one call.
        fuse_rows: ``(first, end)`` unique candidates of the one ``Z`` product per part that serves
            every task and block (:data:`FUSE_SPAN`, :data:`FUSE_BYTES`), or None (one per task).
    """

    def __init__(
        self,
        basis: GaussianBasis,
        models: list[TaskModel],
        n_obs: int,
        t_norm: float,
        nu: float,
        z_budget_bytes: float = 64e6,
    ) -> None:
        self.basis = basis
        self.t_norm = float(t_norm)
        self.nu = float(nu)
        self.n_obs = int(n_obs)
        grids = [m.alpha_grid for m in models]
        if len({g.size for g in grids}) != 1:
            raise ValueError("all tasks need the same number of phase candidates")
        self.alphas = np.stack(grids)
        self.log_prior = np.stack([m.alpha_log_prior for m in models])
        self.alpha_unique, inverse = np.unique(self.alphas, return_inverse=True)
        cand_index = inverse.reshape(self.alphas.shape)
        self.inv_duration = 1.0 / (self.alpha_unique * self.t_norm)
        self._inv_duration_max = float(self.inv_duration.max())
        # every task's candidates are consecutive lattice points, hence consecutive unique candidates
        self.starts = np.ascontiguousarray(cand_index[:, 0], dtype=np.int64)
        if not np.array_equal(cand_index, self.starts[:, None] + np.arange(self.alphas.shape[1])):
            raise ValueError("every task's phase candidates must be consecutive points of one lattice")
        mu = np.stack([m.mean[:n_obs] for m in models])  # (T, D, K)
        delta = np.stack([m.diag[:n_obs] for m in models])  # (T, D)
        self.blocks = [
            LatentBlock(models, dims, cols, mu, delta, z_budget_bytes)
            for dims, cols in latent_blocks(models, self.n_obs)
        ]
        # blocks of equal rank share their arrays side by side (one factorisation call over more
        # lanes) while the packed Q of the group stays cache-sized: indices of the blocks of a group
        self.lane_groups: list[list[int]] = []
        for r in sorted({b.rank for b in self.blocks}):
            per_block = self.n_pair * (r * (r + 1) // 2) * 8
            size = max(1, int(LANE_GROUP_BYTES // per_block))
            same = [i for i, b in enumerate(self.blocks) if b.rank == r]
            self.lane_groups += [same[j : j + size] for j in range(0, len(same), size)]
        first = int(self.starts.min())
        span = int(self.starts.max()) - first + self.alphas.shape[1]
        fused_bytes = span * len(models) * sum(b.ia.size for b in self.blocks) * 8
        fuse = span <= FUSE_SPAN * self.alphas.shape[1] and fused_bytes <= FUSE_BYTES
        self.fuse_rows = (first, first + span) if fuse else None
        self._fused: dict[bytes, tuple[np.ndarray, list[int]]] = {}

    @property
    def rank(self) -> int:
        """Total number of latent dims of the blocks."""
        return sum(b.rank for b in self.blocks)

    @property
    def use_z(self) -> bool:
        """Whether every block uses its precomputed ``Z`` tensors (settable, for tests)."""
        return all(b.use_z for b in self.blocks)

    @use_z.setter
    def use_z(self, value: bool) -> None:
        for b in self.blocks:
            b.use_z = bool(value)

    def part_stats(self, part: ObservationPart, alphas: np.ndarray | None = None) -> PartStats:
        """Statistics of an observation part for the unique candidates (default: the model's)."""
        if alphas is None:
            inv_dur, inv_max = self.inv_duration, self._inv_duration_max
        else:
            inv_dur = 1.0 / (np.asarray(alphas, dtype=float) * self.t_norm)
            inv_max = float(inv_dur.max())
        ke = self.basis.support_count(float(part.t[-1]) * inv_max)
        b = self.basis
        pair_step, overlap = b.gram_factors()
        gram, proj, sq = kernels().part_stats(
            np.ascontiguousarray(part.t, dtype=float), inv_dur, b.centres, b.width, b.step_factor, pair_step,
            overlap, ke, np.ascontiguousarray(part.y, dtype=float),
        )  # fmt: skip
        return PartStats(part.dims, part.t.size, ke, gram, proj, sq)

    def x_inverse(self, gram: np.ndarray, nu: float, ke: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """``X^-1`` (U, ke, ke) and ``log|X|`` (U,) of ``X = nu I + gram[:ke, :ke]``, ``gram`` (K', K', U)."""
        xinv, _, logdet, _ = self.x_factors(gram, float(nu), gram.shape[0] if ke is None else int(ke))
        return np.moveaxis(xinv, 2, 0), logdet

    def x_factors(self, gram: np.ndarray, nu: float, ke: int) -> tuple[np.ndarray, ...]:
        """``X^-1``, ``L^-1`` (ke, ke, U), ``log|X|`` (U,) (candidate index last) and the packed
        ``I - nu X^-1`` (U, ke(ke+1)/2) (see ``kernels.x_inverse``)."""
        gram = np.ascontiguousarray(gram, dtype=float)
        n_u = gram.shape[2]
        xinv = np.empty((ke, ke, n_u))
        linv = np.empty_like(xinv)
        coef = np.empty((n_u, ke * (ke + 1) // 2))
        logdet = kernels().x_inverse(gram, ke, nu, xinv, linv, coef)
        if not math.isfinite(float(logdet.sum())):
            raise ModelError("X = nu I + B^T B is not numerically positive definite")
        return xinv, linv, logdet, coef

    def log_likelihood(self, stats: list[PartStats], t_last: float, nu: float | None = None) -> np.ndarray:
        """Log likelihood (T, C) per (task, candidate) from part statistics (compiled kernels); -inf
        where the observation would extend past the end of the motion.

        Per part and block, with ``h_d = B^T y_d + nu mu_d`` the data terms reduce to
        ``e_d^T e_d - b_d^T X^-1 b_d = y_d^T y_d + nu ||mu_d||^2 - h_d^T X^-1 h_d`` and
        ``X^-1 b_d = X^-1 h_d - mu_d``; ``X^-1`` comes from one Cholesky factorisation per
        unique candidate (shared by the blocks), ``P`` from one product with ``Z`` per task, and
        ``log|Q|``, ``a^T Q^-1 a`` from one Cholesky factorisation per (task, candidate).

        Args:
            stats: Part statistics for the unique candidates (``gram`` and ``proj`` may hold more
                than ``ke`` basis functions, only the first ``ke`` are used).
            t_last: Time of the last observed sample in [s].
            nu: Noise ratio (default the engine's).
        """
        nu = self.nu if nu is None else float(nu)
        factors = [self.x_factors(st.gram, nu, st.ke) for st in stats]
        return self.finish_groups(self.group_terms(stats, factors, nu), t_last)

    def group_terms(self, stats: list[PartStats], factors: list[tuple], nu: float) -> list[tuple]:
        """Per lane group (:attr:`lane_groups`), the terms of every block and (task, candidate) pair
        (:meth:`lane_arrays`, filled by :meth:`block_terms`), from part statistics and their
        ``X`` factors (:meth:`x_factors`). ``P`` comes from one product per part for all tasks and
        blocks (:meth:`fused_z`) when the tasks' candidate windows overlap enough, else from one
        product per task and block."""
        kern = kernels()
        fused = self.fuse_rows is not None and self.use_z
        mode = kern.P_BY_CALLER if fused else (kern.P_FROM_Z if self.use_z else kern.P_FROM_W)
        out = []
        for group in self.lane_groups:
            arrays = self.lane_arrays(group)
            for lane0, b in zip(self.lane_starts(group), group, strict=True):
                self.block_terms(self.blocks[b], stats, factors, nu, *arrays, lane0, mode)
            out.append(arrays)
        if fused:
            assert self.fuse_rows is not None  # fused implies it
            u0, u1 = self.fuse_rows
            n_c = self.alphas.shape[1]
            for st, (_, _, _, coef) in zip(stats, factors, strict=True):
                zcat, cols = self.fused_z(st.dims, st.ke)
                pz = np.dot(coef[u0:u1], zcat[: st.ke * (st.ke + 1) // 2])
                for group, (_, _, pq) in zip(self.lane_groups, out, strict=True):
                    for lane0, b in zip(self.lane_starts(group), group, strict=True):
                        if cols[b] >= 0:
                            npk = self.blocks[b].ia.size
                            kern.add_fused_p(pz, self.starts, u0, n_c, cols[b], npk, lane0, pq)
        return out

    def reserve_z(self, stats: list[PartStats]) -> None:
        """Build at once the ``Z`` rows that the parts ``stats`` will read (:meth:`fused_z`), so that
        observations of growing length (a held-out demo's prefixes) share one product."""
        if self.fuse_rows is None or not self.use_z:
            return
        need: dict[bytes, tuple[np.ndarray, int]] = {}
        for st in stats:
            key = st.dims.tobytes()
            need[key] = (st.dims, max(st.ke, need.get(key, (st.dims, 0))[1]))
        for dims, ke in need.values():
            self.fused_z(dims, ke)

    def fused_z(self, dims: np.ndarray, ke: int | None = None) -> tuple[np.ndarray, list[int]]:
        """The ``Z`` tensors of every block and task side by side for a part observing ``dims``
        (cached): (K'(K'+1)/2, sum_b T r_b(r_b+1)/2), block ``b``'s task ``t`` in the columns
        ``cols[b] + t r_b(r_b+1)/2 ..``, and ``cols`` (-1 for a block the part does not observe).

        ``K' >= ke`` rows of basis pairs: the first call with ``ke`` active basis functions builds
        only their rows (a short observation, such as the cross-validations' held-out ones, reads
        no more); a later call needing more builds all ``K``."""
        key = dims.tobytes()
        out = self._fused.get(key)
        n_basis = self.basis.n_basis
        need = n_basis if ke is None else min(int(ke), n_basis)
        if out is None or out[0].shape[0] < need * (need + 1) // 2:
            rows = n_basis if out is not None and need > n_basis // 2 else need
            self._fused.pop(key, None)  # a smaller earlier product is released first
            out = None
            n_task = self.alphas.shape[0]
            cols, col = [], 0
            for b in self.blocks:
                cols.append(col if b.select(dims)[0].size else -1)
                col += b.ia.size * n_task if cols[-1] >= 0 else 0
            # every block's Z written straight into its columns (task t's at cols[b] + t r(r+1)/2)
            zcat = np.empty((rows * (rows + 1) // 2, col))
            for b, c0 in zip(self.blocks, cols, strict=True):
                if c0 >= 0:
                    view = zcat[:, c0 : c0 + b.ia.size * n_task].reshape(zcat.shape[0], n_task, b.ia.size)
                    b.z_tensor(
                        b.select(dims)[1],
                        n_basis=None if rows == n_basis else rows,
                        out=view.transpose(1, 0, 2),
                    )
            out = self._fused[key] = (zcat, cols)
        return out

    def finish_groups(self, terms: list[tuple], t_last: float) -> np.ndarray:
        """Log likelihood (T, C) from the lane groups' terms (:meth:`group_terms`): the sum of the
        blocks' (``kernels.finish_soa``)."""
        finish = kernels().finish_soa
        loglik = np.empty(self.alphas.shape)
        for j, group_terms in enumerate(terms):
            self.finish_group(j, group_terms, float(t_last), loglik, finish)
        return loglik

    def finish_group(
        self, j: int, terms: tuple, t_last: float, loglik: np.ndarray, finish: Callable | None = None
    ) -> None:
        """Lane group ``j``'s log likelihood from its terms (:meth:`group_terms`), written into
        ``loglik`` (T, C) for ``j = 0`` and added to it after (``kernels.finish_soa``, or ``finish``)."""
        total, a, pq = terms
        group = self.lane_groups[j]
        fn = kernels().finish_soa if finish is None else finish
        unpack = self.blocks[group[0]].unpack
        if not fn(pq, a, total, unpack, self.alphas, self.t_norm, t_last, loglik, j > 0, len(group)):
            raise ModelError("Q = I + P is not numerically positive definite")

    @property
    def n_pair(self) -> int:
        """Lanes per block: the T C (task, candidate) pairs padded to whole vector loops."""
        n_task, n_cand = self.alphas.shape
        return -(-n_task * n_cand // PAIR_LANES) * PAIR_LANES

    def lane_arrays(self, group: list[int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Zeroed terms of a lane group (:attr:`lane_groups`): the scalar terms (G P',), ``a``
        (r, G P') and packed ``P`` (r(r+1)/2, G P'), block ``j`` of the group in lanes
        ``j P' .. (j + 1) P'``. Lanes of a block no part observes stay zero (``Q = I``): their log
        likelihood is 0."""
        block = self.blocks[group[0]]
        n = len(group) * self.n_pair
        return np.zeros(n), np.zeros((block.rank, n)), np.zeros((block.ia.size, n))

    def lane_starts(self, group: list[int]) -> range:
        """First lane of each block of a lane group."""
        return range(0, len(group) * self.n_pair, self.n_pair)

    def block_terms(
        self,
        block: LatentBlock,
        stats: list[PartStats],
        factors: list[tuple],
        nu: float,
        total: np.ndarray,
        a: np.ndarray,
        pq: np.ndarray,
        lane0: int,
        p_mode: int,
    ) -> None:
        """Add one block's terms of every (task, candidate) pair (task-major, innermost) to the lanes
        from ``lane0`` of ``total``, ``a`` and ``pq`` (see :meth:`lane_arrays`); ``P`` as ``p_mode``
        says (``kernels.part_terms``)."""
        kern = kernels()
        n_cand = self.alphas.shape[1]
        for st, (xinv, linv, logdet, coef) in zip(stats, factors, strict=True):
            inputs = block.part_inputs(st.dims, with_z=p_mode == kern.P_FROM_Z)
            if inputs is None:
                continue
            pos, c, z = inputs
            kern.part_terms(
                xinv, linv, logdet, coef, st.proj, st.sq, pos, st.n, st.ke, nu, self.starts, n_cand,
                c["mu_k"], c["mu_rows"], c["inv_delta"], c["mu2"], c["log_delta"], c["w_k"], c["w_1"], z,
                block.unpack, p_mode, lane0, total, a, pq,
            )  # fmt: skip


@dataclass
class PartState:
    """What :class:`IncrementalTerms` keeps of one observation part: its observed dims (D_m,) and,
    per unique candidate, ``X^-1`` (ke, ke, U) and ``log|X|`` (U,) of ``X = nu I + B^T B`` over the
    part's samples."""

    dims: np.ndarray
    xinv: np.ndarray
    logdet: np.ndarray


class IncrementalTerms:
    """Log likelihood of a growing observation, updated sample by sample (streaming).

    Holds per observation part (:class:`PartState`: channels sharing their presence history; one
    part with every observed dim while no sample missed a group) ``X^-1`` and ``log|X|`` per unique
    candidate (shared by the blocks) and, per lane group of blocks and (task, candidate), the terms
    of :meth:`InferenceEngine.log_likelihood` (``P``, ``a`` and the scalar terms), which add up
    over the parts. :meth:`reset` computes them from part statistics; :meth:`add` adds one sample
    to the parts that received it with the same active basis functions exactly (per part a
    Sherman-Morrison update of its ``X^-1``, then one compiled call per lane group adding the rank-D
    update of ``P`` of the part's dims: ``kernels.stream_group``); ``log|Q|`` and ``a^T Q^-1 a``
    are recomputed from ``Q`` once per sample; :meth:`regroup` follows a part that splits when a
    sample misses some of its groups (the part that missed it keeps its ``X``).

    Args:
        engine: The model's inference engine.
    """

    def __init__(self, engine: InferenceEngine) -> None:
        self.engine = engine
        self._kern = kernels()
        self.ke = -1
        self.parts: list[PartState] = []
        self.terms: list[tuple] = []
        self._unpack = [engine.blocks[group[0]].unpack for group in engine.lane_groups]
        # per part dims: per lane group the W_d and nu mu_d of its blocks' dims (K, M) and the model
        # arguments of kernels.stream_group that follow w_t, or None (the part has none of its dims)
        self._model: dict[bytes, list[tuple[np.ndarray, tuple] | None]] = {}
        # per part dims, the current ke and terms: per lane group the arguments of kernels.stream_group
        # from w_t (wcat[:ke].T, C-contiguous: the faster product) to t_norm, or None
        self._w_t: dict[bytes, list[tuple | None]] = {}

    def _group_inputs(self, dims: np.ndarray) -> list[tuple[np.ndarray, tuple] | None]:
        """Per lane group, the model arrays of ``kernels.stream_group`` for a part observing ``dims``
        (cached)."""
        key = dims.tobytes()
        out = self._model.get(key)
        if out is None:
            e = self.engine
            out = []
            for group in e.lane_groups:
                blocks = [e.blocks[b] for b in group]
                local = [b.select(dims)[1] for b in blocks]
                if not any(loc.size for loc in local):
                    out.append(None)
                    continue
                arrays = [b.arrays(loc) for b, loc in zip(blocks, local, strict=True)]
                n_basis = arrays[0]["mu_k"].shape[1]
                # nu mu_d as (basis, dim, task) columns after every block's W_d
                mu_cols = np.concatenate([c["mu_k"].transpose(1, 2, 0) for c in arrays], axis=1) * e.nu
                w_cols = [c["w_s"] for c in arrays]
                wcat = np.concatenate([*w_cols, mu_cols.reshape(n_basis, -1)], axis=1)
                dims_g = [b.dims[loc] for b, loc in zip(blocks, local, strict=True)]
                fixed = (
                    np.concatenate(dims_g).astype(np.int64),
                    np.cumsum([0] + [loc.size for loc in local]).astype(np.int64),
                    np.cumsum([0] + [w.shape[1] for w in w_cols]).astype(np.int64),
                    e.nu,
                    e.starts,
                    e.alphas.shape[1],
                    np.ascontiguousarray(np.concatenate([c["inv_delta"] for c in arrays], axis=1)),
                    np.ascontiguousarray(np.stack([c["log_delta"] for c in arrays])),
                    blocks[0].ia,
                    blocks[0].ib,
                )
                out.append((np.ascontiguousarray(wcat), fixed))
            self._model[key] = out
        return out

    def _inputs(self, dims: np.ndarray) -> list[tuple | None]:
        """Per lane group, the arguments of ``kernels.stream_group`` for a part observing ``dims`` from
        ``w_t`` (the first ``ke`` basis rows, transposed) to ``t_norm`` (the model's, the group's terms
        and unpacking), or None (the part has none of the group's dims)."""
        key = dims.tobytes()
        out = self._w_t.get(key)
        if out is None:
            e = self.engine
            out = [
                None
                if m is None
                else (np.ascontiguousarray(m[0][: self.ke].T), *m[1], *terms, unpack, e.alphas, e.t_norm)
                for m, terms, unpack in zip(self._group_inputs(dims), self.terms, self._unpack, strict=True)
            ]
            self._w_t[key] = out
        return out

    def reset(self, stats: PartStats | list[PartStats], t_last: float) -> np.ndarray:
        """Terms from part statistics ``stats`` (one per part, all with the same ``ke``; a part
        without samples yet, ``n = 0``, starts from ``X = nu I`` and adds no term) -> log
        likelihood (T, C)."""
        e = self.engine
        stats = [stats] if isinstance(stats, PartStats) else list(stats)
        ke = stats[0].ke
        if any(st.ke != ke for st in stats):
            raise ValueError("the parts of the incremental terms need the same number of basis functions")
        used = [st for st in stats if st.n > 0]
        factors = [e.x_factors(st.gram, e.nu, ke) for st in used]
        by_id = {id(st): f for st, f in zip(used, factors, strict=True)}
        n_u = e.alpha_unique.size
        self.parts = []
        for st in stats:
            f = by_id.get(id(st))
            if f is None:  # no sample yet: X = nu I
                xinv = np.zeros((ke, ke, n_u))
                xinv[np.arange(ke), np.arange(ke)] = 1.0 / e.nu
                self.parts.append(PartState(st.dims, xinv, np.full(n_u, ke * math.log(e.nu))))
            else:
                self.parts.append(PartState(st.dims, f[0], f[2]))
        self.terms = e.group_terms(used, factors, e.nu)
        self.ke = ke
        self._w_t = {}
        return e.finish_groups(self.terms, t_last)

    def regroup(self, parts: list[tuple[int, np.ndarray]]) -> None:
        """The parts after a sample that some part's groups missed: per new part, the index of the
        part it comes from (its ``X`` so far; copied when two new parts come from one) and its dims."""
        used: set[int] = set()
        new = []
        for i, dims in parts:
            old = self.parts[i]
            if i in used:
                new.append(PartState(dims, old.xinv.copy(), old.logdet.copy()))
            else:
                new.append(PartState(dims, old.xinv, old.logdet))
                used.add(i)
        self.parts = new

    def add(
        self,
        phi: np.ndarray,
        y: np.ndarray,
        proj: np.ndarray,
        t_last: float,
        receivers: list[int] | None = None,
    ) -> np.ndarray:
        """Add one sample: basis values ``phi`` (K, U), scaled values ``y`` (D,) (0 where missing),
        ``proj`` (K, U, D) already including it, to the parts ``receivers`` (indices in
        :attr:`parts`; default all) -> log likelihood (T, C)."""
        kern = self._kern
        e = self.engine
        loglik = np.empty(e.alphas.shape)
        t_last = float(t_last)
        order = list(range(len(self.parts))) if receivers is None else receivers
        if not order:  # no part received it: the terms are as they were
            return self.finish(t_last)
        last = len(order) - 1
        for n, i in enumerate(order):
            part = self.parts[i]
            g, s, ok = kern.sherman_morrison(part.xinv, part.logdet, phi)
            if not ok:
                self.ke = -1  # partly updated: rebuilt by the next reset
                raise ModelError("X = nu I + B^T B is not numerically positive definite")
            finish = n == last
            for j, inputs in enumerate(self._inputs(part.dims)):
                if inputs is None:
                    if finish:  # no dim of this part here: the terms are as they were
                        try:
                            e.finish_group(j, self.terms[j], t_last, loglik, kern.finish_soa)
                        except ModelError:
                            self.ke = -1
                            raise
                    continue
                if not kern.stream_group(g, s, y, proj, *inputs, t_last, loglik, j > 0, finish):
                    self.ke = -1
                    raise ModelError("Q = I + P is not numerically positive definite")
        return loglik

    def finish(self, t_last: float) -> np.ndarray:
        """Log likelihood (T, C) of the terms as they are (:meth:`InferenceEngine.finish_groups`)."""
        try:
            return self.engine.finish_groups(self.terms, t_last)
        except ModelError:
            self.ke = -1
            raise
