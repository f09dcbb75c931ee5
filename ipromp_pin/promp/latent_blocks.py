"""Independent blocks of observed dims: the latent structure the likelihood engine exploits.

Two observed dims belong to one block when some task's low-rank covariance factor ``F`` has a
column that is non-zero on both (directly or through other dims). Blocks are independent in every
task, so an observation's likelihood is the product of the blocks' and each block needs only its
own factor columns (:func:`latent_blocks`). A :class:`LatentBlock` holds one block's scaled factors
and the precomputed tensors of :mod:`ipromp_pin.promp.likelihood`.
"""

from __future__ import annotations

import functools

import numpy as np

from .distribution import TaskModel

PartInputs = tuple[np.ndarray, dict[str, np.ndarray], np.ndarray]
"""What :meth:`LatentBlock.part_inputs` returns: positions, model arrays and ``Z`` of a part's dims."""


def latent_blocks(models: list[TaskModel], n_obs: int) -> list[tuple[np.ndarray, list[np.ndarray]]]:
    """Independent blocks of the observed dims: dims linked by a shared factor column of any task.

    Two observed dims are in one block when some task's low-rank factor ``F`` has a column that is
    non-zero on both (directly or through other dims). The weights of different blocks are
    independent in every task, so the likelihood of an observation is the product of the blocks'
    likelihoods and each block needs only its own factor columns.

    Returns:
        Per block: its observed dims (sorted) and, per task, the factor columns non-zero on them.
    """
    parent = list(range(n_obs))

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    active = [np.any(m.factor[:n_obs] != 0.0, axis=1) for m in models]  # (D_o, r_t) per task
    seen = set()  # a column's dims are linked already when its pattern was seen (same roots)
    for act in active:
        for col in np.ascontiguousarray(act.T):
            key = col.tobytes()
            if key in seen:
                continue
            seen.add(key)
            dims = np.flatnonzero(col)
            for d in dims[1:]:
                parent[root(int(d))] = root(int(dims[0]))
    roots = np.array([root(i) for i in range(n_obs)])
    blocks = []
    for r in np.unique(roots):
        dims = np.flatnonzero(roots == r)
        cols = [np.flatnonzero(np.any(act[dims], axis=0)) for act in active]
        blocks.append((dims, cols))
    return blocks


class LatentBlock:
    """One block of observed dims with its own latent factors (see :func:`latent_blocks`).

    Holds the block's scaled factors ``W = F / sqrt(delta)`` (T, D_b, K, r_b) (tasks with fewer
    columns padded with zeros; at least one column), its packed-triangle index arrays and, when it
    fits in ``z_budget_bytes``, the tensor ``Z[(k, l), (a, b)] = sum_d W_dka W_dlb`` (symmetrised and
    packed) that turns ``P = sum_d W_d^T (I - nu X^-1) W_d`` into one matrix product per task.

    Args:
        models: Task models.
        dims: (D_b,) the block's observed dims.
        cols: Per task, its factor columns used by the block.
        mu, delta: (T, D_o, K) observed means and (T, D_o) diagonal variances of all observed dims.
        z_budget_bytes: Largest size of the precomputed ``Z`` tensors.
    """

    def __init__(
        self,
        models: list[TaskModel],
        dims: np.ndarray,
        cols: list[np.ndarray],
        mu: np.ndarray,
        delta: np.ndarray,
        z_budget_bytes: float,
    ) -> None:
        n_task = len(models)
        k = mu.shape[2]
        self.dims = np.asarray(dims, dtype=np.int64)
        self.cols = [np.asarray(c, dtype=np.int64) for c in cols]  # per task, its factor columns used
        self.rank = r = max(1, max(c.size for c in cols))
        self.mu = np.ascontiguousarray(mu[:, self.dims])  # (T, D_b, K)
        self.delta = np.ascontiguousarray(delta[:, self.dims])
        self.sqrt_delta = np.sqrt(self.delta)
        self.w = np.zeros((n_task, self.dims.size, k, r))
        for i, (m, c) in enumerate(zip(models, cols, strict=True)):
            self.w[i, :, :, : c.size] = m.factor[self.dims][:, :, c] / self.sqrt_delta[i][:, None, None]
        pl, pk = np.tril_indices(k)  # the basis pairs (k, l), k <= l, ordered by l then k
        self.pk, self.pl = pk.astype(np.int64), pl.astype(np.int64)
        ia, ib = np.triu_indices(r)
        self.ia, self.ib = ia.astype(np.int64), ib.astype(np.int64)
        unpack = np.zeros((r, r), dtype=np.int64)  # index of Q[i, j] in the packed upper triangle
        unpack[ia, ib] = np.arange(ia.size)
        unpack[ib, ia] = np.arange(ia.size)
        self.unpack = unpack
        self.use_z = n_task * self.pk.size * ia.size * 8 <= z_budget_bytes
        self.no_z = np.zeros((1, 1, 1))
        self._z: dict[bytes, np.ndarray] = {}
        self._arrays: dict[bytes, dict[str, np.ndarray]] = {}
        self._local = {int(d): i for i, d in enumerate(self.dims)}
        self._select: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}
        self._inputs: dict[tuple[bytes, bool], PartInputs | None] = {}

    def select(self, dims: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Positions in ``dims`` (observed dims of a part) of the block's dims and their block-local
        indices (cached)."""
        key = dims.tobytes()
        out = self._select.get(key)
        if out is None:
            pos = [i for i, d in enumerate(dims) if int(d) in self._local]
            local = [self._local[int(dims[i])] for i in pos]
            self._select[key] = out = (np.array(pos, dtype=np.int64), np.array(local, dtype=np.int64))
        return out

    def part_inputs(self, dims: np.ndarray, with_z: bool = True) -> PartInputs | None:
        """For a part observing the dims ``dims``: the positions of the block's dims in it, the model
        arrays (:meth:`arrays`) and ``Z`` (:meth:`z_tensor`; a placeholder without ``use_z`` or
        ``with_z``) of its dims; None when the part observes none of them (cached)."""
        with_z = with_z and self.use_z
        key = (dims.tobytes(), with_z)
        if key in self._inputs:
            return self._inputs[key]
        pos, local = self.select(dims)
        out: PartInputs | None = None
        if pos.size:
            out = (pos, self.arrays(local), self.z_tensor(local) if with_z else self.no_z)
        self._inputs[key] = out
        return out

    def z_tensor(
        self, local: np.ndarray, cache: bool = True, n_basis: int | None = None, out: np.ndarray | None = None
    ) -> np.ndarray:
        """Packed ``Z`` (T, K(K+1)/2, r(r+1)/2) of the block-local dims ``local`` (cached unless
        ``cache`` is False); with ``n_basis = k'`` only its first ``k'(k'+1)/2`` rows (the pairs of
        the first ``k'`` basis functions, what a part with ``k'`` active ones reads; not cached).
        ``out``: an array (or view) of that shape to write it into (then not cached)."""
        key = np.asarray(local, dtype=np.int64).tobytes()
        z = None if n_basis is not None or out is not None else self._z.get(key)
        if z is None:
            w = self.w[:, local] if n_basis is None else self.w[:, local, :n_basis]
            n_task, dm, k, r = w.shape
            flat = w.reshape(n_task, dm, k * r)
            z = np.empty((n_task, k * (k + 1) // 2, r * (r + 1) // 2)) if out is None else out
            for t in range(n_task):
                # the columns of W^T W of Z_CHUNK basis functions l0 <= l < l1 at a time, their rows
                # k <= l only: panel[k r + a, (l - l0) r + b] = sum_d W_dka W_dlb, so W^T W (K r, K r)
                # is never held whole. Z's rows (k, l) for k <= l of the chunk are consecutive; their
                # (k, l, a, b) entries and the mirror (l, k, a, b) = (k, l, b, a) of the rows with
                # k != l both lie in the panel (W^T W is symmetric)
                # (rank 1: one basis function at a time against every row, the matrix-vector
                # product whose rounding Z has always had)
                step = 1 if r == 1 else Z_CHUNK
                for l0 in range(0, k, step):
                    l1 = min(k, l0 + step)
                    lhs = flat[t] if r == 1 else flat[t][:, : l1 * r]
                    panel = (lhs.T @ flat[t][:, l0 * r : l1 * r]).reshape(-1)
                    direct, mirror, off = z_chunk_gather(r, l0, l1)
                    rows = np.take(panel, direct)
                    rows[off] += np.take(panel, mirror)
                    z[t, l0 * (l0 + 1) // 2 : l1 * (l1 + 1) // 2] = rows
            if cache and n_basis is None and out is None:
                self._z[key] = z
        return z

    def arrays(self, local: np.ndarray) -> dict[str, np.ndarray]:
        """Model arrays of the block-local dims ``local`` in basis-major layouts (cached).

        ``mu_k`` (T, K, D_m) task means; ``mu_rows`` (T D_m, K) the means with rows (task, dim);
        ``w_k`` (T, K D_m, r) ``W_d / sqrt(delta_d)`` with rows ordered (basis, dim), so that the
        first ``ke D_m`` rows are the first ``ke`` basis functions; ``w_1`` (T, K D_m, r) ``W_d``
        with rows (basis, dim); ``w_s`` (K, r D_m T) ``W_d`` ordered (basis, latent, dim, task);
        ``mu2`` (T, K + 1) cumulative ``sum_d ||mu_d[:k]||^2 / delta_d``; ``inv_delta`` (T, D_m);
        ``log_delta`` (T,) ``sum_d log delta_d``.
        """
        key = np.asarray(local, dtype=np.int64).tobytes()
        c = self._arrays.get(key)
        if c is None:
            mu = self.mu[:, local]  # (T, Dm, K)
            delta = self.delta[:, local]
            w = self.w[:, local]
            n_task, dm, k = mu.shape
            w_k = (w / self.sqrt_delta[:, local, None, None]).transpose(0, 2, 1, 3)
            c = {
                "mu_k": np.ascontiguousarray(mu.transpose(0, 2, 1)),
                "mu_rows": np.ascontiguousarray(mu.reshape(n_task * dm, k)),
                "w_k": np.ascontiguousarray(w_k.reshape(n_task, k * dm, self.rank)),
                "w_1": np.ascontiguousarray(w.transpose(0, 2, 1, 3).reshape(n_task, k * dm, self.rank)),
                "w_s": np.ascontiguousarray(w.transpose(2, 3, 1, 0).reshape(k, self.rank * dm * n_task)),
                "mu2": np.ascontiguousarray(
                    np.concatenate(
                        [
                            np.zeros((n_task, 1)),
                            np.cumsum(np.einsum("tdk,td->tk", mu * mu, 1.0 / delta), axis=1),
                        ],
                        axis=1,
                    )
                ),
                "inv_delta": np.ascontiguousarray(1.0 / delta),
                "log_delta": np.ascontiguousarray(np.sum(np.log(delta), axis=1)),
            }
            self._arrays[key] = c
        return c


Z_CHUNK = 4
"""Basis functions whose columns of ``W^T W`` :meth:`LatentBlock.z_tensor` computes at a time (a
panel of at most ``K r x Z_CHUNK r`` values)."""


@functools.lru_cache(maxsize=256)
def z_chunk_gather(r: int, l0: int, l1: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Flat indices into a panel ``(l1 r, (l1 - l0) r)`` of ``W^T W`` (rows ``k r + a`` of the basis
    functions ``k < l1``, columns ``(l - l0) r + b`` of those ``l0 <= l < l1``) of the packed ``Z``
    entries ``(k, l, a, b)`` (``a <= b``, ``k <= l``, rows ordered by ``l`` then ``k``), and of their
    mirrors ``(l, k, a, b)`` read at ``(k r + b, (l - l0) r + a)`` for the rows with ``k < l``, with
    the positions of those rows: (R, r(r+1)/2), (R', r(r+1)/2), (R',) for rank ``r`` (cached: the
    cross-validations build many blocks of the same shape)."""
    ia, ib = np.triu_indices(r)
    width = (l1 - l0) * r
    pl, pk = np.tril_indices(l1)  # rows (k, l), k <= l, ordered by l then k
    pk, pl = pk[pl >= l0][:, None], pl[pl >= l0][:, None] - l0
    direct = (pk * r + ia) * width + pl * r + ib
    mirror = (pk * r + ib) * width + pl * r + ia
    off = np.flatnonzero(pk[:, 0] != pl[:, 0] + l0)
    out = (direct.astype(np.int64), mirror[off].astype(np.int64), off)
    for a in out:
        a.setflags(write=False)
    return out
