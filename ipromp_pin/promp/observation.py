"""Observation encoding: a partial human motion checked against the model and scaled into parts.

An observation (a :class:`~ipromp_pin.data.Demo` holding the observed groups, times in [s] from
motion start) becomes a list of :class:`ObservationPart`: the scaled values of channels that share
their sample times. Without missing samples that is one part with every observed dim; a group
with gaps gets its own part (groups with identical gaps share one).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..data import Demo
from ..exceptions import DataError, ObservationError
from ..signals.groups import group_spec
from .compiled import kernels
from .distribution import ChannelScaler
from .layout import ChannelLayout
from .sample_bounds import MAX_LOG_SCALED_MAGNITUDE, MAX_SCALED_MAGNITUDE


@dataclass
class ObservationPart:
    """Scaled samples of observed channels that share their sample times.

    Attributes:
        t: (n,) sample times in [s] from motion start.
        dims: (D_m,) indices of these channels among the model's dims.
        y: (n, D_m) scaled values.
    """

    t: np.ndarray
    dims: np.ndarray
    y: np.ndarray


QUATERNION_REFERENCE_MIN_NORM = 0.3
"""The training data's mean quaternion fixes the sign convention only when its norm is at least
this (the demos' orientations then lie on one side; a mean near 0 would mean both signs were
trained, and nothing is flipped)."""


def quaternion_references(
    layout: ChannelLayout, scaler: ChannelScaler
) -> list[tuple[str, int, int, np.ndarray]]:
    """The observed orientation groups (quaternion interpolation, not log-scaled) with their training
    mean quaternion, in the layout's channel order: (group, start, stop, mean (4,)). An observed
    quaternion ``q`` with ``q . mean < 0`` is compared as ``-q`` (the same rotation)."""
    out = []
    for g in layout.observe:
        lo, hi = layout.slices[g]
        if group_spec(g).interpolation_kind(hi - lo) != "quaternion" or np.any(scaler.log_mask[lo:hi]):
            continue
        ref = np.asarray(scaler.offset[lo:hi], dtype=float)
        if np.linalg.norm(ref) >= QUATERNION_REFERENCE_MIN_NORM:
            out.append((g, lo, hi, ref))
    return out


class ObservationEncoder:
    """Checks observations against a model's channels and scales them (:class:`ChannelScaler`).

    Args:
        layout: The model's channel layout.
        scaler: The model's channel scaling (all dims).
        longest_s: Longest plausible motion in [s]: a longer observation is refused.

    Attributes:
        dims: (D_o,) the observed dims, groups in ``observe`` order (a full observed sample).
        log_idx: Positions in a full sample of the log-scaled dims.
        log_shift: Their shifts ``c`` (see :class:`ChannelScaler`).
        offset, scale: (D_o,) offsets and scales of a full sample's dims.
    """

    def __init__(self, layout: ChannelLayout, scaler: ChannelScaler, longest_s: float) -> None:
        self.layout = layout
        self.scaler = scaler
        self.longest_s = float(longest_s)
        # observed groups come first, in observe order: a full sample's dims are 0 .. D_o - 1
        self.dims = layout.dims(layout.observe)
        self.log_idx = np.flatnonzero(scaler.log_mask[: layout.n_obs_dims])
        self.log_shift = scaler.shift[self.log_idx]
        self.offset = scaler.offset[self.dims]
        self.scale = scaler.scale[self.dims]
        self.quaternions = quaternion_references(layout, scaler)

    def align_signs(self, obs: Demo) -> Demo:
        """``obs`` with every quaternion sample of an observed orientation group in the hemisphere of
        the training data (:func:`quaternion_references`): ``q`` and ``-q`` are one rotation, and
        the model compares components, so the sign the model was trained with is used."""
        groups = None
        for g, lo, hi, ref in self.quaternions:
            v = obs.groups.get(g)
            if v is None or v.shape[1] != hi - lo:
                continue
            with np.errstate(invalid="ignore"):
                flip = v @ ref < 0.0
            if np.any(flip):
                groups = dict(obs.groups) if groups is None else groups
                groups[g] = np.where(flip[:, None], -v, v)
        return obs if groups is None else dataclasses.replace(obs, groups=groups)

    def align_rows(self, raw: np.ndarray) -> None:
        """Flip, in place, the quaternions of full raw samples ``raw`` (n, D_o) that are not in the
        training data's hemisphere (:meth:`align_signs` for the concatenated samples)."""
        for _, lo, hi, ref in self.quaternions:
            q = raw[:, lo:hi]
            with np.errstate(invalid="ignore"):
                flip = q @ ref < 0.0
            if np.any(flip):
                q[flip] = -q[flip]

    def align_sample(self, y: np.ndarray) -> None:
        """Flip, in place, the quaternions of a full raw sample ``y`` (D_o,) that are not in the
        training data's hemisphere (:meth:`align_signs` for one sample)."""
        for _, lo, hi, ref in self.quaternions:
            q = y[lo:hi]
            if float(q @ ref) < 0.0:
                y[lo:hi] = -q

    def scale_samples(self, raw: np.ndarray) -> tuple[np.ndarray, bool]:
        """Scaled values (n, D_o) of raw full samples ``raw`` (n, D_o) in original units (as
        ``ChannelScaler.transform``) and whether every raw value is finite."""
        raw = np.ascontiguousarray(raw, dtype=float)
        out = np.empty(raw.shape)
        finite = kernels().scale_samples(raw, self.log_idx, self.log_shift, self.offset, self.scale, out)
        return out, bool(finite)

    def scale_group(self, group: str, values: np.ndarray) -> np.ndarray:
        """Scaled values of one group's raw values (..., D_g)."""
        return self.scaler.transform(values, slice(*self.layout.slices[group]))

    def encode(self, obs: Demo, check_length: bool = True) -> tuple[list[ObservationPart], float]:
        """Validate and scale an observation -> its parts and the time of its last sample in [s].

        Raises:
            ObservationError: not a Demo, times before motion start, a missing observed group, a
                wrong channel count, NaN or inf values not flagged missing, fewer than 2 samples,
                or (``check_length``) longer than any task's plausible motion.
        """
        if not isinstance(obs, Demo):
            raise ObservationError(None, "observation", f"expected a Demo, got {type(obs).__name__}")
        src, t, layout = obs.source, obs.t, self.layout
        if t[0] < -1e-9:
            raise ObservationError(
                src, "t", f"times must start at motion start (>= 0 s), first is {t[0]:.3f} s"
            )
        gaps = False
        for g in layout.observe:
            if g not in obs.groups:
                raise ObservationError(
                    src,
                    g,
                    f"observed group missing from the observation (has: {', '.join(sorted(obs.groups))})",
                )
            lo, hi = layout.slices[g]
            n_ch = obs.groups[g].shape[1]
            if n_ch != hi - lo:
                raise ObservationError(
                    src, g, f"has {n_ch} channels, the model expects {hi - lo} {layout.channel_names[g]}"
                )
            if tuple(obs.channel_names[g]) != layout.channel_names[g]:
                obs = self._by_name(obs)
            gaps = gaps or (g in obs.missing and bool(obs.missing[g].any()))
        if not gaps:  # every group in every sample: one part with all observed dims
            raw = np.concatenate([obs.groups[g] for g in layout.observe], axis=1, dtype=float)
            self.align_rows(raw)
            y, finite = self.scale_samples(raw)
            if not finite:
                for g in layout.observe:
                    self.check_values(src, g, raw[:, slice(*layout.slices[g])])
            parts = [ObservationPart(t=t, dims=self.dims, y=y)]
        else:
            parts = self._parts_with_gaps(self.align_signs(obs))
        n_used = sum(p.t.size for p in parts)
        if t.size < 2 or n_used < 2:
            raise ObservationError(src, "t", f"an observation needs at least 2 samples, got {t.size}")
        t_last = float(t[-1])
        if check_length and t_last > self.longest_s:
            raise ObservationError(
                src,
                "t",
                f"observation lasts {t_last:.2f} s, longer than any task's plausible motion "
                f"({self.longest_s:.2f} s)",
            )
        return parts, t_last

    def check_values(self, source: object, group: str, values: np.ndarray, what: str = "samples") -> None:
        """Raise ObservationError when raw values (n, D_g) of an observed group are NaN or inf, or
        scale to more than :data:`~ipromp_pin.promp.sample_bounds.MAX_SCALED_MAGNITUDE` standard deviations
        of the training data (a value no sensor the model was trained on gives)."""
        v = np.asarray(values, dtype=float)
        if not np.all(np.isfinite(v)):
            raise ObservationError(source, group, f"NaN or inf values in {what} not flagged as missing")
        with np.errstate(all="ignore"):
            scaled = np.abs(self.scale_group(group, v))
        dims = slice(*self.layout.slices[group])
        log = self.scaler.log_mask[dims]
        bound = np.where(log, MAX_LOG_SCALED_MAGNITUDE, MAX_SCALED_MAGNITUDE)
        floor = np.where(log, -MAX_SCALED_MAGNITUDE * np.nan_to_num(self.scaler.shift[dims]), -np.inf)
        bad = ~(scaled <= bound) | (v < floor)
        if np.any(bad):
            row, col = np.argwhere(bad)[0]
            name = self.layout.channel_names[group][col]
            space = " (in log space)" if self.scaler.log_mask[dims][col] else ""
            raise ObservationError(
                source,
                f"{group}/{name}",
                f"implausible value {v[row, col]:.6g} in {what}: more than {bound[col]:g} standard "
                f"deviations of the training data{space} from its mean",
            )

    def _by_name(self, obs: Demo) -> Demo:
        """``obs`` with its observed channels in the model's order, matched by name."""
        order = {g: self.layout.channel_names[g] for g in self.layout.observe}
        try:
            return obs.with_channel_order(order)
        except DataError as exc:
            raise ObservationError(
                exc.source, exc.field, exc.problem + " (channels are matched by name)"
            ) from None

    def _parts_with_gaps(self, obs: Demo) -> list[ObservationPart]:
        """Parts of an observation with missing samples: groups with identical presence masks share
        a part (their samples and times)."""
        masks: dict[bytes, tuple[np.ndarray, list[np.ndarray], list[np.ndarray]]] = {}
        for g in self.layout.observe:
            v = obs.groups[g]
            lo, hi = self.layout.slices[g]
            valid = ~obs.missing[g] if g in obs.missing else np.ones(obs.t.size, dtype=bool)
            self.check_values(obs.source, g, v[valid])
            if not np.any(valid):
                continue
            entry = masks.setdefault(valid.tobytes(), (valid, [], []))
            entry[1].append(np.arange(lo, hi))
            entry[2].append(self.scaler.transform(v[valid], slice(lo, hi)))
        return [
            ObservationPart(t=obs.t[valid], dims=np.concatenate(dims), y=np.concatenate(ys, axis=1))
            for valid, dims, ys in masks.values()
        ]
