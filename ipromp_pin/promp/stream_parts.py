"""A stream's running sufficient statistics per presence pattern (:class:`PresencePatterns`).

Channel groups with identical presence histories share one pattern: its samples' ``B^T B`` for every
phase candidate, its count and its last time. ``B^T y`` and ``y^T y`` are kept per observed dim (a
missing sample adds 0), so a pattern's part reads its dims of them. The
:class:`~ipromp_pin.promp.streaming.StreamingEstimator` owns one.
"""

from __future__ import annotations

from types import ModuleType

import numpy as np

from .basis import GaussianBasis
from .layout import ChannelLayout
from .likelihood import IncrementalTerms, PartStats


class PresencePatterns:
    """The running statistics of a stream's presence patterns.

    Args:
        layout: The model's channel layout (the observed groups and their dims).
        basis: The model's basis.
        n_candidates: Number of unique phase candidates U.
        kern: The kernels module (``add_sample``, ``basis_rows``).

    Attributes:
        patterns: Per presence pattern ``[groups, gram (K, K, U), n, last time [s]]``; the first is
            every observed group until some sample misses one.
        proj: (K, U, D_o) ``B^T y`` of every observed dim.
        sq: (D_o,) ``y^T y`` of every observed dim.
        receivers: The patterns that received the latest sample.
    """

    def __init__(
        self, layout: ChannelLayout, basis: GaussianBasis, n_candidates: int, kern: ModuleType
    ) -> None:
        k, n_obs = basis.n_basis, layout.n_obs_dims
        self.layout, self.basis, self._kern = layout, basis, kern
        self.patterns: list[list] = [[list(layout.observe), np.zeros((k, k, n_candidates)), 0, 0.0]]
        self.proj = np.zeros((k, n_candidates, n_obs))
        self.sq = np.zeros(n_obs)
        self.receivers: list[int] = []
        self._no_gram = np.zeros((k, 0, n_candidates))  # placeholders of kernels.add_sample
        self._no_proj = np.zeros((k, n_candidates, 0))
        self._no_y = np.zeros(0)

    def received_by_all(self, t_s: float) -> None:
        """Count a sample at ``t_s`` [s] that the one pattern received whole (its sums were added by
        ``kernels.stream_sample``)."""
        pattern = self.patterns[0]
        pattern[2] += 1
        pattern[3] = t_s
        self.receivers = [0]

    def accumulate(
        self,
        z: np.ndarray,
        t_s: float,
        present: set[str],
        y: np.ndarray,
        incremental: IncrementalTerms | None,
    ) -> np.ndarray:
        """Add the sample at phases ``z`` (U,) and time ``t_s`` [s] (scaled values ``y`` (D,), 0 in
        missing groups) -> basis values (K, U).

        A presence pattern some of whose groups missed the sample splits in two (the groups that
        missed it keep the statistics so far); the incremental terms follow its parts
        (:meth:`IncrementalTerms.regroup`) and :attr:`receivers` says which parts got the sample."""
        kern = self._kern
        b = self.basis
        phi = kern.basis_rows(z, b.centres, b.width, b.step_factor)
        patterns: list[list] = []
        origin: list[int] = []
        receivers: list[int] = []
        for i, (groups, gram, n, t_last) in enumerate(self.patterns):
            have = [g for g in groups if g in present]
            absent = [g for g in groups if g not in present]
            if absent:
                patterns.append([absent, gram.copy() if have else gram, n, t_last])
                origin.append(i)
            if have:
                kern.add_sample(gram, self._no_proj, phi, self._no_y)
                receivers.append(len(patterns))
                patterns.append([have, gram, n + 1, t_s])
                origin.append(i)
        inc = incremental
        if len(patterns) != len(self.patterns) and inc is not None and inc.ke >= 0:
            inc.regroup([(i, self.pattern_dims(p[0])) for i, p in zip(origin, patterns, strict=True)])
        self.patterns = patterns
        self.receivers = receivers
        kern.add_sample(self._no_gram, self.proj, phi, y)
        self.sq += y * y
        return phi

    def pattern_dims(self, groups: list[str]) -> np.ndarray:
        """The observed dims (model order) of a presence pattern's groups."""
        layout = self.layout
        return layout.dims([g for g in layout.observe if g in groups])

    def stats(self, inv_dur_max: float) -> list[PartStats]:
        """Part statistics of the patterns with samples, each with the basis functions active up to
        its last time (``inv_dur_max``: the largest ``1 / duration`` of the candidates, in [1/s])."""
        return [
            self.pattern_stats(i, self.basis.support_count(p[3] * inv_dur_max))
            for i, p in enumerate(self.patterns)
            if p[2] > 0
        ]

    def pattern_stats(self, i: int, ke: int) -> PartStats:
        """Part statistics of presence pattern ``i`` with ``ke`` active basis functions."""
        groups, gram, n, _ = self.patterns[i]
        dims = self.pattern_dims(groups)
        if dims.size == self.sq.size:
            proj, sq = self.proj, self.sq
        else:
            proj, sq = np.ascontiguousarray(self.proj[:, :, dims]), self.sq[dims]
        return PartStats(dims, n, ke, gram, proj, sq)
