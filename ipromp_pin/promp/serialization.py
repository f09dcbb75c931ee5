"""Versioned, pickle-free model files: the estimator's parameters and its fitted state.

A model file is a single ``.npz`` archive (``numpy.savez``) read back with
``allow_pickle=False``. It holds

* ``header``: a JSON string with ``format`` (:data:`FORMAT_NAME`),
  ``format_version`` (:data:`FORMAT_VERSION`), the package version, the
  constructor parameters, task names, channel groups and names, and the fitted
  scalars (``T_norm`` in [s], noise ratio, CV scores, observed groups coupled to
  the robot and their CV scores, per-task phase prior and the robot's shrinkage
  intensity) and, since format version 2, ``trained_on``: one object per
  training demo with its ``task``, ``name``, ``source`` and ``sha256`` (content
  digest, :mod:`ipromp_pin.promp.provenance`);
* plain float arrays: the channel scaling (``scaler_offset``, ``scaler_scale``,
  ``scaler_log_shift``: NaN for linear channels),
  ``task_log_prior``, ``residual_var`` and, per task index ``i``,
  ``task{i}_mean`` (D, K), ``task{i}_diag`` (D,), ``task{i}_factor`` (D, K, r),
  ``task{i}_alpha_grid``, ``task{i}_alpha_log_prior``, ``task{i}_train_weights``
  (N, D, K), ``task{i}_train_alpha`` (N,), ``task{i}_shrinkage`` (D,);
* (version 2) the header's ``temperature``, ``condition_noise_ratio`` and ``head`` (the number R of
  its regressions, or null), and with a head its arrays ``head_ratios`` (R,), ``head_coef``
  (R, T, 3 D_o + T), ``head_intercept`` (R, T), ``head_feature_mean`` and ``head_feature_scale``
  (R, 3 D_o + T), ``head_c`` (R,) and ``head_cv_log_loss`` (R, number of candidates);
* (version 3) the head's ``head_kind`` (R,) (0 logistic regression, 1 LDA) and ``head_generative``
  (R,) (1 where the generative posterior is a feature); the header's ``handover`` (null, or the
  numbers R, M and F of its fractions, outputs and feature dims, and its trust factor) and
  ``handover_cv_scores`` (trust factor or ``"off"`` -> CV error), and with a hand-over regression its
  arrays ``handover_ratios`` (R,), ``handover_dims`` (F,) (observed dims, as floats),
  ``handover_readout`` (T, M, J), ``handover_coef`` (R, T, M, 2 F), ``handover_intercept`` (R, T, M)
  and ``handover_residual_cov`` (R, M, M) (:mod:`~ipromp_pin.promp.handover`);
* (version 4) the header's ``handover`` gains ``neighbours`` (the number N of rows of the
  k-nearest-neighbour estimates, or null when every fraction uses the ridge regression), and with N
  the arrays ``handover_kind`` (R,) (0 ridge, 1 k-nearest neighbours), ``handover_neighbour_x``
  (R, T, N, 2 F), ``handover_neighbour_y`` (R, T, N, M), ``handover_neighbour_count``,
  ``handover_neighbour_k``, ``handover_neighbour_distance`` (R, T), ``handover_neighbour_mean`` and
  ``handover_neighbour_scale`` (R, T, 2 F);
* (version 5) the header's ``orientation`` (null, or ``{"trust": s}``) and ``orientation_cv_scores``
  (trust factor or ``"off"`` -> CV error in [deg]), and with an orientation estimate its arrays
  ``orientation_position_readout`` and ``orientation_rotation_readout`` (T, 3, J),
  ``orientation_target`` (T, 3) and ``orientation_noise_cov`` (T, 3, 3)
  (:mod:`~ipromp_pin.promp.handover_orientation`);
* (version 6) the parameter ``novelty_alpha`` and the header's ``novelty`` (null, or ``{"alpha": a,
  "ratios": R, "features": F, "calibration": n, "shrinkage": s}``), and with a novelty detector its
  arrays ``novelty_ratios`` (R,), ``novelty_columns`` (F,), ``novelty_mean`` (T, R, F),
  ``novelty_chol`` (T, R, F, F), ``novelty_calibration`` and ``novelty_calibration_group`` (n,) and
  ``novelty_cv_auroc`` (number of candidates) (:mod:`~ipromp_pin.promp.novelty`);
* (version 7) the header's ``added_tasks``: the tasks added after the fit
  (:func:`~ipromp_pin.promp.new_task.add_task`), the last ones of ``tasks``; the head's, the hand-over
  regression's and the orientation estimate's task axis then holds the fitted tasks only; and the
  header's ``human_fit``: null (not measured), or the JSON object of the training
  demos' body-model self-check and registration calibration (:mod:`ipromp_pin.human.fit`), at most
  :data:`MAX_HUMAN_FIT_BYTES` long;
* (version 8) the header's ``human_forecast``: null (none), or the JSON object of the handing arm's
  forecast calibration (:mod:`ipromp_pin.human.forecast`), at most :data:`MAX_HUMAN_FIT_BYTES` long.

Files of format version 1 (no ``trained_on``) load with ``trained_on`` None
(unknown); files of format version 2 load with an all-logistic head and no hand-over regression;
files of format version 3 with an all-ridge hand-over regression; files of format version 4 and
older without an orientation estimate (as they predicted); files of format version 5 and older
without a novelty detector (every observation some task explains is known, as they predicted);
files of format version 6 and older with no body-model self-check (``human_fit`` None: not measured);
files of format version 7 and older with no forecast of the handing arm (``human_forecast`` None).
Files written before the coupling was introduced (no ``coupling`` parameter, no
``task{i}_shrinkage``) load as fully coupled models with one shrinkage intensity;
the covariance is entirely in ``diag`` and ``factor``, so older readers also load
newer files and predict the same.

Floats are stored exactly (binary arrays; JSON floats use Python's
round-tripping repr), so a loaded model gives bitwise identical predictions. A
file of a newer format version, a truncated or corrupt file, or a file that is
not a model raises :class:`~ipromp_pin.exceptions.ModelFileError`.

Checks. A model is checked (:func:`~ipromp_pin.promp.validation.check_fitted`: finite numbers,
positive variances, consistent shapes) before it is written and after it is read. Reading first
inspects the archive's directory and each array's ``.npy`` header, without loading any data: a
member that is not one of the arrays above, an array that is not float64 or whose shape does not
fit the header's channels, tasks and basis, a header above :data:`MAX_HEADER_BYTES`, or a member
that expands to more than :data:`MAX_EXPANSION` times its stored size is refused at once (a
0.9 MB file cannot make the reader allocate 800 MB). The file is written atomically (a temporary
file renamed into place): a failed save leaves an earlier file of that name intact.
"""

from __future__ import annotations

import json
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from .. import atomic
from ..exceptions import IPrompPinError, ModelError, ModelFileError
from ..version import __version__
from .basis import GaussianBasis
from .distribution import ChannelScaler, TaskModel
from .fitted import FittedModel
from .handover import NEIGHBOUR_ARRAYS, HandoverRegression
from .handover_orientation import OrientationEstimate
from .head import RecognitionHead
from .layout import ChannelLayout
from .novelty import novelty_arrays, novelty_from_arrays, novelty_meta, novelty_shapes
from .provenance import DemoRecord
from .validation import check_fitted

FORMAT_NAME = "ipromp_pin.IProMP"
"""Value of the header's ``format`` field."""

FORMAT_VERSION = 8
"""Current (and highest readable) format version. Version 2 added ``trained_on`` (the training demos),
the likelihood temperature, the conditioning noise ratio and the recognition head (``head_*``
arrays); version 3 the head's model families and features and the hand-over regression
(``handover_*`` arrays); version 4 the hand-over's k-nearest-neighbour estimates
(``handover_kind``, ``handover_neighbour_*``); version 5 the hand-over orientation estimate
(``orientation_*``); version 6 the novelty detector (``novelty_*``); version 7 the tasks added after
the fit (``added_tasks``) and the header's ``human_fit`` (the body-model self-check); version 8 the
header's ``human_forecast`` (the handing arm's forecast calibration). Version-1 files
load with no record of their training demos, temperature 1, the conditioning noise ratio equal to the
noise ratio and no head; version-2 files with an all-logistic head and no hand-over regression (as they
predicted); version-3 files with an all-ridge hand-over regression (as they predicted); files before
version 6 with no novelty detector; files before version 7 with no body-model self-check; files
before version 8 with no forecast of the handing arm."""

_HEAD_ARRAYS = ("ratios", "coef", "intercept", "feature_mean", "feature_scale", "c", "cv_log_loss")
_HEAD_V3_ARRAYS = ("kind", "generative")
_HANDOVER_ARRAYS = ("ratios", "readout", "coef", "intercept", "residual_cov")
_ORIENTATION_ARRAYS = ("position_readout", "rotation_readout", "target", "noise_cov")

_TASK_ARRAYS = ("mean", "diag", "factor", "alpha_grid", "alpha_log_prior", "train_weights", "train_alpha")
_GLOBAL_ARRAYS = ("scaler_offset", "scaler_scale", "scaler_log_shift", "task_log_prior", "residual_var")
_HEADER_KEYS = {
    "format", "format_version", "package_version", "params", "tasks", "groups", "channel_names",
    "duration_nominal_s", "noise_ratio", "cv_scores", "coupled_groups", "coupling_cv_scores", "task_scalars",
    "trained_on", "temperature", "condition_noise_ratio", "condition_cv_scores", "head", "handover",
    "handover_cv_scores", "orientation", "orientation_cv_scores", "novelty", "added_tasks", "human_fit",
    "human_forecast",
}  # fmt: skip
_PARAM_KEYS = {
    "observe", "n_basis", "width", "ridge", "margin", "blas_threads", "n_alpha", "alpha_width", "noise",
    "n_points", "task_prior", "robot_group", "log_groups", "pooling", "coupling", "temperature",
    "condition_noise", "head", "handover", "novelty_alpha",
}  # fmt: skip

MAX_HEAD_REGRESSIONS = 100
"""Largest number of regressions (observed fractions) of a recognition head a model file may declare."""

MAX_HANDOVER_SIZE = 10_000
"""Largest number of fractions, outputs or feature dims of a hand-over regression a model file may
declare."""

MAX_HEADER_BYTES = 1_000_000
"""Largest header (the JSON member) a model file may have, in bytes."""

MAX_EXPANSION = 20.0
"""Largest ratio of an archive member's size to its stored (compressed) size: float arrays compress
little (``write_model`` stores them uncompressed), a member of zeros a thousandfold."""

MAX_HUMAN_FIT_BYTES = 100_000
"""Largest JSON text of a model file's ``human_fit`` or ``human_forecast`` entry, in bytes."""

MAX_DEMOS_PER_TASK = 100_000
"""Largest number of training demos (or phase candidates) of a task a model file may declare."""


def _header_params(params: dict) -> dict:
    """The estimator parameters as JSON values (lists for sequences, floats for numbers)."""
    coupling = params["coupling"]
    noise = params["noise"]
    return {
        "observe": list(params["observe"]),
        "n_basis": int(params["n_basis"]),
        "width": None if params["width"] is None else float(params["width"]),
        "ridge": float(params["ridge"]),
        "margin": float(params["margin"]),
        "blas_threads": params["blas_threads"],
        "n_alpha": int(params["n_alpha"]),
        "alpha_width": float(params["alpha_width"]),
        "noise": noise if isinstance(noise, str) else float(noise),
        "temperature": _number_or_text(params["temperature"]),
        "condition_noise": _number_or_text(params["condition_noise"]),
        "head": bool(params["head"]),
        "handover": bool(params["handover"]),
        "novelty_alpha": None if params.get("novelty_alpha") is None else float(params["novelty_alpha"]),
        "n_points": int(params["n_points"]),
        "task_prior": None if params["task_prior"] is None else dict(params["task_prior"]),
        "robot_group": params["robot_group"],
        "log_groups": list(params["log_groups"]),
        "pooling": float(params["pooling"]),
        "coupling": coupling if isinstance(coupling, str) else list(coupling),
    }


def _number_or_text(value: object) -> float | str:
    return value if isinstance(value, str) else float(value)  # type: ignore[arg-type]


def _handover_meta(ho: HandoverRegression | None) -> dict | None:
    """The hand-over regression's header field (its sizes and trust; None: none)."""
    if ho is None:
        return None
    neighbours = None
    if ho.kind is not None:
        assert ho.neighbour_x is not None  # present with kind (validate_fitted)
        neighbours = int(ho.neighbour_x.shape[2])
    return {
        "ratios": int(ho.ratios.size),
        "outputs": int(ho.readout.shape[1]),
        "features": int(ho.dims.size),
        "trust": float(ho.trust),
        "neighbours": neighbours,
    }


def write_model(params: dict, fitted: FittedModel, path: str | Path) -> None:
    """Write an estimator's parameters (``IProMP.get_params()``) and fitted state to ``path`` (``.npz``),
    atomically (an earlier file is replaced only by a complete new one).

    ``params["observe"]`` is written as the fitted layout's observed groups (a list).

    Raises:
        ModelError: the fitted state fails :func:`~ipromp_pin.promp.validation.check_fitted`.
        OutputError: the file cannot be written.
    """
    check_fitted(fitted)
    layout = fitted.layout
    ho = fitted.handover
    robot_lo = layout.slices[layout.robot_group][0]
    header = {
        "format": FORMAT_NAME,
        "format_version": FORMAT_VERSION,
        "package_version": __version__,
        "params": _header_params({**params, "observe": layout.observe}),
        "tasks": list(fitted.tasks),
        "groups": list(layout.groups),
        "channel_names": {g: list(v) for g, v in layout.channel_names.items()},
        "duration_nominal_s": float(fitted.duration_nominal_s),
        "noise_ratio": float(fitted.noise_ratio),
        "cv_scores": [[float(k), float(v)] for k, v in fitted.noise_cv_scores.items()],
        "coupled_groups": list(fitted.coupled_groups),
        "coupling_cv_scores": [[k, float(v)] for k, v in fitted.coupling_cv_scores.items()],
        "temperature": float(fitted.temperature),
        "condition_noise_ratio": float(fitted.nu_condition),
        "condition_cv_scores": [[float(k), float(v)] for k, v in fitted.condition_cv_scores.items()],
        "head": None if fitted.head is None else {"regressions": int(fitted.head.ratios.size)},
        "handover": _handover_meta(ho),
        "handover_cv_scores": [
            ["off" if not np.isfinite(k) else float(k), float(v)]
            for k, v in fitted.handover_cv_scores.items()
        ],
        "orientation": None if fitted.orientation is None else {"trust": float(fitted.orientation.trust)},
        "orientation_cv_scores": [
            ["off" if not np.isfinite(k) else float(k), float(v)]
            for k, v in fitted.orientation_cv_scores.items()
        ],
        "task_scalars": [
            {
                # the robot's intensity, as a scalar for readers of files without task{i}_shrinkage
                "shrinkage": float(m.shrinkage[robot_lo]),
                "alpha_mu": float(m.alpha_mu),
                "alpha_sigma": float(m.alpha_sigma),
            }
            for m in fitted.task_models()
        ],
        "trained_on": None if fitted.trained_on is None else [r.to_json() for r in fitted.trained_on],
        "novelty": None if fitted.novelty is None else novelty_meta(fitted.novelty),
        "added_tasks": list(fitted.added_tasks),
        "human_fit": None if fitted.human_fit is None else dict(fitted.human_fit),
        "human_forecast": None if fitted.human_forecast is None else dict(fitted.human_forecast),
    }
    arrays: dict[str, Any] = {  # np.savez's keyword arguments (all arrays)
        "header": np.array(json.dumps(header)),
        "scaler_offset": fitted.scaler.offset,
        "scaler_scale": fitted.scaler.scale,
        "scaler_log_shift": fitted.scaler.shift,
        "task_log_prior": fitted.task_log_prior,
        "residual_var": fitted.residual_var,
    }
    if fitted.head is not None:
        head = fitted.head
        for name in _HEAD_ARRAYS:
            arrays[f"head_{name}"] = np.asarray(getattr(head, name), dtype=float)
        n = head.ratios.size
        arrays["head_kind"] = np.zeros(n) if head.kind is None else np.asarray(head.kind, dtype=float)
        arrays["head_generative"] = (
            np.ones(n) if head.generative is None else np.asarray(head.generative, float)
        )
    if ho is not None:
        for name in _HANDOVER_ARRAYS:
            arrays[f"handover_{name}"] = np.asarray(getattr(ho, name), dtype=float)
        arrays["handover_dims"] = np.asarray(ho.dims, dtype=float)
        if ho.kind is not None:
            for name in NEIGHBOUR_ARRAYS:
                arrays[f"handover_{name}"] = np.asarray(getattr(ho, name), dtype=float)
    if fitted.orientation is not None:
        for name in _ORIENTATION_ARRAYS:
            arrays[f"orientation_{name}"] = np.asarray(getattr(fitted.orientation, name), dtype=float)
    arrays.update(novelty_arrays(fitted.novelty))
    for i, m in enumerate(fitted.task_models()):
        for name in _TASK_ARRAYS:
            arrays[f"task{i}_{name}"] = np.asarray(getattr(m, name), dtype=float)
        arrays[f"task{i}_shrinkage"] = np.asarray(m.shrinkage, dtype=float)
    with atomic.replacing(path) as tmp, open(tmp, "wb") as fh:
        np.savez(fh, **arrays)


def read_model(path: str | Path) -> tuple[dict, FittedModel]:
    """Read a model file written by :func:`write_model` -> the estimator parameters and fitted state.

    Raises:
        ModelFileError: missing, truncated or corrupt file, not a model, a newer format version,
            an unknown, oversized or inconsistent array, or a state that fails
            :func:`~ipromp_pin.promp.validation.check_fitted`.
    """
    path = Path(path)
    if path.is_dir():
        raise ModelFileError(f"{path}: is a folder, not a model file")
    if not path.is_file():
        raise ModelFileError(f"{path}: model file not found")
    try:
        with zipfile.ZipFile(path) as zf:
            members = {info.filename: info for info in zf.infolist()}
            if "header.npy" not in members:
                raise ModelFileError(f"{path}: not an ipromp_pin model file (no header)")
            if members["header.npy"].file_size > MAX_HEADER_BYTES:
                raise ModelFileError(
                    f"{path}: model header of {members['header.npy'].file_size} bytes is too large"
                )
            header_array = _read_member(zf, members["header.npy"], path)
            if header_array.dtype.kind != "U" or header_array.shape != ():
                raise ModelFileError(f"{path}: not an ipromp_pin model file (header is not a string)")
            header = json.loads(str(header_array[()]))
            _check_header(path, header)
            expected = _expected_shapes(path, header)
            _check_members(path, members, expected)
            arrays = {
                name[: -len(".npy")]: _read_member(zf, info, path, expected[name[: -len(".npy")]])
                for name, info in members.items()
                if name != "header.npy"
            }
    except ModelFileError:
        raise
    except RecursionError:
        raise ModelFileError(f"{path}: not a usable model file (its header is nested too deeply)") from None
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile, json.JSONDecodeError) as exc:
        raise ModelFileError(f"{path}: not a readable model file ({type(exc).__name__}: {exc})") from exc
    try:
        return _params(header), check_fitted(_fitted(header, arrays))
    except ModelError as exc:
        raise ModelFileError(f"{path}: corrupt model file ({exc})") from exc
    except (KeyError, TypeError, ValueError, IndexError, AttributeError, IPrompPinError) as exc:
        raise ModelFileError(f"{path}: corrupt model file ({type(exc).__name__}: {exc})") from exc


def _npy_header(fh) -> tuple[tuple[int, ...], np.dtype, int]:
    """Shape, dtype and header length of an ``.npy`` stream (reads only its header)."""
    version = np.lib.format.read_magic(fh)
    if version == (1, 0):
        shape, fortran, dtype = np.lib.format.read_array_header_1_0(fh)
    elif version == (2, 0):
        shape, fortran, dtype = np.lib.format.read_array_header_2_0(fh)
    else:
        raise ValueError(f"unsupported .npy version {version}")
    if fortran and len(shape) > 1:
        raise ValueError("Fortran-ordered arrays are not written by ipromp_pin")
    return tuple(shape), dtype, fh.tell()


def _read_member(
    zf: zipfile.ZipFile, info: zipfile.ZipInfo, path: Path, shape: tuple[int | None, ...] | None = None
) -> np.ndarray:
    """Load one ``.npy`` member (no pickles). Its declared size must match its stored size and, for
    an array, its dtype must be float64 and its shape ``shape`` (None: any length up to
    :data:`MAX_DEMOS_PER_TASK`), all checked before any data is read."""
    if info.file_size > MAX_EXPANSION * info.compress_size + 65536:
        raise ModelFileError(
            f"{path}: array '{info.filename}' expands {info.file_size / max(info.compress_size, 1):.0f}-fold "
            "(not a model written by ipromp_pin)"
        )
    with zf.open(info) as fh:
        got, dtype, header_len = _npy_header(fh)
        if dtype.hasobject:
            raise ModelFileError(f"{path}: array '{info.filename}' holds Python objects")
        if shape is not None:
            if dtype != np.dtype("<f8"):
                raise ModelFileError(f"{path}: array '{info.filename}' holds {dtype}, not float64 numbers")
            fits = len(got) == len(shape) and all(
                (w is None and 0 <= n <= MAX_DEMOS_PER_TASK) or w == n
                for w, n in zip(shape, got, strict=True)
            )
            if not fits:
                want = "(" + ", ".join("N" if w is None else str(w) for w in shape) + ")"
                raise ModelFileError(f"{path}: array '{info.filename}' has shape {got}, expected {want}")
        nbytes = int(np.prod(got, dtype=np.int64)) * dtype.itemsize
        if header_len + nbytes != info.file_size:
            raise ModelFileError(f"{path}: array '{info.filename}' is truncated or has trailing data")
        data = fh.read(nbytes)
    return np.frombuffer(data, dtype=dtype).reshape(got).copy()


def _expected_shapes(path: Path, header: dict) -> dict[str, tuple[int | None, ...]]:
    """Member name -> expected shape (None: a length checked later) of every array of the header's model."""
    unknown = set(header) - _HEADER_KEYS
    if unknown:
        raise ModelFileError(f"{path}: unknown header fields {sorted(unknown)}")
    params = header["params"]
    if not isinstance(params, dict) or set(params) - _PARAM_KEYS:
        extra = sorted(set(params) - _PARAM_KEYS) if isinstance(params, dict) else params
        raise ModelFileError(f"{path}: unknown model parameters {extra}")
    names = header["channel_names"]
    groups = header["groups"]
    if not isinstance(names, dict) or not isinstance(groups, list):
        raise ModelFileError(f"{path}: header fields 'groups' and 'channel_names' are malformed")
    d = sum(len(names[g]) for g in groups)
    k = params["n_basis"]
    tasks = header["tasks"]
    if not isinstance(k, int) or isinstance(k, bool) or not 2 <= k <= 10_000:
        raise ModelFileError(f"{path}: n_basis must be an integer in [2, 10000], got {k!r}")
    if not isinstance(tasks, list) or not tasks:
        raise ModelFileError(f"{path}: header field 'tasks' must be a non-empty list")
    shapes: dict[str, tuple[int | None, ...]] = {
        "scaler_offset": (d,),
        "scaler_scale": (d,),
        "scaler_log_shift": (d,),
        "task_log_prior": (len(tasks),),
        "residual_var": (d,),
    }
    for i in range(len(tasks)):
        shapes.update(
            {
                f"task{i}_mean": (d, k),
                f"task{i}_diag": (d,),
                f"task{i}_factor": (d, k, None),
                f"task{i}_alpha_grid": (None,),
                f"task{i}_alpha_log_prior": (None,),
                f"task{i}_train_weights": (None, d, k),
                f"task{i}_train_alpha": (None,),
                f"task{i}_shrinkage": (d,),
            }
        )
    n_fit = len(tasks) - len(_added_tasks(path, header))  # the head's and hand-over estimates' tasks
    head = header.get("head")
    if head is not None:
        n_feat = 3 * sum(len(names[g]) for g in groups[:-1]) + n_fit
        shapes.update(_head_shapes(path, head, n_fit, n_feat))
    ho = header.get("handover")
    if ho is not None:
        shapes.update(_handover_shapes(path, ho, n_fit, names, groups))
    if header.get("novelty") is not None:
        try:
            shapes.update(novelty_shapes(header["novelty"], len(tasks), n_obs_dims(names, groups)))
        except ValueError as exc:
            raise ModelFileError(f"{path}: header field 'novelty': {exc}") from None
    orientation = header.get("orientation")
    if orientation is not None:
        if not isinstance(orientation, dict) or set(orientation) != {"trust"}:
            raise ModelFileError(f"{path}: header field 'orientation' must be null or {{\"trust\": s}}")
        nj, t = len(names[groups[-1]]), n_fit
        shapes.update(
            {
                "orientation_position_readout": (t, 3, nj),
                "orientation_rotation_readout": (t, 3, nj),
                "orientation_target": (t, 3),
                "orientation_noise_cov": (t, 3, 3),
            }
        )
    return shapes


def _added_tasks(path: Path, header: dict) -> list[str]:
    """The header's tasks added after the fit (none before version 7): the last of its tasks."""
    added, tasks = header.get("added_tasks", []), header["tasks"]
    if (
        not isinstance(added, list)
        or len(added) >= len(tasks)
        or (added and added != tasks[len(tasks) - len(added) :])
    ):
        raise ModelFileError(f"{path}: header field 'added_tasks' must list the last of its tasks")
    return added


def _head_shapes(path: Path, head: object, t: int, n_feat: int) -> dict[str, tuple[int | None, ...]]:
    """Expected shapes of the recognition head's arrays (header field ``head``; ``t`` tasks,
    ``n_feat`` features)."""
    n = head.get("regressions") if isinstance(head, dict) else None
    if not isinstance(n, int) or isinstance(n, bool) or not 1 <= n <= MAX_HEAD_REGRESSIONS:
        raise ModelFileError(f"{path}: header field 'head' must give 1-{MAX_HEAD_REGRESSIONS} regressions")
    shapes: dict[str, tuple[int | None, ...]] = {
        "head_ratios": (n,),
        "head_coef": (n, t, n_feat),
        "head_intercept": (n, t),
        "head_feature_mean": (n, n_feat),
        "head_feature_scale": (n, n_feat),
        "head_c": (n,),
        "head_cv_log_loss": (n, None),
    }
    shapes.update({"head_kind": (n,), "head_generative": (n,)})  # since version 3
    return shapes


def _handover_shapes(
    path: Path, ho: object, t: int, names: dict, groups: list
) -> dict[str, tuple[int | None, ...]]:
    """Expected shapes of the hand-over regression's arrays (header field ``handover``; ``t`` tasks,
    the robot's joints are the channels of the last group)."""
    table: dict = ho if isinstance(ho, dict) else {}
    sizes: list[Any] = [table.get(key) for key in ("ratios", "outputs", "features")]
    if not all(isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= MAX_HANDOVER_SIZE for v in sizes):
        raise ModelFileError(
            f"{path}: header field 'handover' must give 1-{MAX_HANDOVER_SIZE} ratios, outputs, features"
        )
    r, m, f = (int(v) for v in sizes)
    nj = len(names[groups[-1]])
    shapes: dict[str, tuple[int | None, ...]] = {
        "handover_ratios": (r,),
        "handover_dims": (f,),
        "handover_readout": (t, m, nj),
        "handover_coef": (r, t, m, 2 * f),
        "handover_intercept": (r, t, m),
        "handover_residual_cov": (r, m, m),
    }
    n = table.get("neighbours")  # since version 4
    if n is not None:
        if not isinstance(n, int) or isinstance(n, bool) or not 1 <= n <= MAX_HANDOVER_SIZE:
            raise ModelFileError(
                f"{path}: header field 'handover' must give 1-{MAX_HANDOVER_SIZE} neighbours or null"
            )
        shapes.update(
            {
                "handover_kind": (r,),
                "handover_neighbour_x": (r, t, n, 2 * f),
                "handover_neighbour_y": (r, t, n, m),
                "handover_neighbour_count": (r, t),
                "handover_neighbour_mean": (r, t, 2 * f),
                "handover_neighbour_scale": (r, t, 2 * f),
                "handover_neighbour_k": (r, t),
                "handover_neighbour_distance": (r, t),
            }
        )
    return shapes


def _check_members(path: Path, members: dict[str, zipfile.ZipInfo], expected: dict) -> None:
    """Refuse unknown members and arrays whose declared dtype or shape do not fit (headers only)."""
    for name, info in members.items():
        if name == "header.npy":
            continue
        key = name[: -len(".npy")] if name.endswith(".npy") else None
        if key not in expected:
            raise ModelFileError(f"{path}: unknown array '{name}' ({info.file_size} bytes) in the model file")
    for key in expected:
        # absent from files written before the coupling, and before version 3
        optional = key.endswith("_shrinkage") or key in ("head_kind", "head_generative")
        if f"{key}.npy" not in members and not optional:
            raise ModelFileError(f"{path}: corrupt model file (array '{key}' is missing)")
    return None


def _check_header(path: Path, header: object) -> None:
    if not isinstance(header, dict) or header.get("format") != FORMAT_NAME:
        raise ModelFileError(f"{path}: not an ipromp_pin model file (format is not '{FORMAT_NAME}')")
    version = header.get("format_version")
    if not isinstance(version, int):
        raise ModelFileError(f"{path}: model file has no valid format_version")
    if version > FORMAT_VERSION:
        raise ModelFileError(
            f"{path}: model file format version {version} is newer than this ipromp_pin reads "
            f"({FORMAT_VERSION}); upgrade ipromp_pin"
        )
    if version < 1:
        raise ModelFileError(f"{path}: invalid format_version {version}")


def _params(header: dict) -> dict:
    """The estimator parameters of a header (files before the coupling: ``coupling="all"``; version-1
    files: temperature 1, the conditioning with the recognition's noise ratio, no head)."""
    p = header["params"]
    names = (
        "observe", "n_basis", "width", "ridge", "margin", "blas_threads", "n_alpha", "alpha_width", "noise",
        "n_points", "task_prior", "robot_group", "log_groups", "pooling",
    )  # fmt: skip
    return {
        **{name: p[name] for name in names},
        "coupling": p.get("coupling", "all"),
        "temperature": p.get("temperature", 1.0),
        "condition_noise": p.get("condition_noise", "same"),
        "head": bool(p.get("head", False)),
        "handover": bool(p.get("handover", False)),
        "novelty_alpha": p.get("novelty_alpha"),  # None before version 6
    }


def _fitted(header: dict, arrays: dict[str, np.ndarray]) -> FittedModel:
    """The fitted state of a header and its arrays (shapes checked)."""
    p = header["params"]
    groups = list(header["groups"])
    observe = list(p["observe"])
    if groups != [*observe, p["robot_group"]]:
        raise ValueError(f"groups {groups} are not the observed groups then the robot group")
    layout = ChannelLayout(tuple(observe), p["robot_group"], {g: header["channel_names"][g] for g in groups})
    basis = GaussianBasis(p["n_basis"], p["width"], p["ridge"], p["margin"])
    scaler = ChannelScaler(
        offset=arrays["scaler_offset"], scale=arrays["scaler_scale"], log_shift=arrays["scaler_log_shift"]
    )
    tasks = tuple(header["tasks"])
    added = tuple(header.get("added_tasks", ()))  # none before version 7
    coupled = tuple(header.get("coupled_groups", observe))
    if any(g not in observe for g in coupled):
        raise ValueError(f"coupled groups {list(coupled)} are not observed groups")
    n_dims, k = layout.n_dims, basis.n_basis
    models = {}
    for i, t in enumerate(tasks):
        sc = header["task_scalars"][i]
        a = {name: arrays[f"task{i}_{name}"] for name in _TASK_ARRAYS}
        shrinkage = arrays.get(f"task{i}_shrinkage")
        if shrinkage is None:  # files without per-dim intensities: one block
            shrinkage = np.full(n_dims, float(sc["shrinkage"]))
        if (
            a["mean"].shape != (n_dims, k)
            or a["diag"].shape != (n_dims,)
            or a["factor"].shape[:2] != (n_dims, k)
            or shrinkage.shape != (n_dims,)
        ):
            raise ValueError(f"arrays of task '{t}' have inconsistent shapes")
        models[t] = TaskModel(
            task=t,
            shrinkage=shrinkage,
            alpha_mu=float(sc["alpha_mu"]),
            alpha_sigma=float(sc["alpha_sigma"]),
            **a,
        )
    task_log_prior = arrays["task_log_prior"]
    if scaler.offset.shape != (n_dims,) or task_log_prior.shape != (len(tasks),):
        raise ValueError("scaling or task prior arrays have inconsistent shapes")
    return FittedModel(
        layout=layout,
        basis=basis,
        scaler=scaler,
        tasks=tasks,
        models=models,
        duration_nominal_s=float(header["duration_nominal_s"]),
        task_log_prior=task_log_prior,
        noise_ratio=float(header["noise_ratio"]),
        coupled_groups=coupled,
        residual_var=arrays["residual_var"],
        noise_cv_scores={float(k): float(v) for k, v in header["cv_scores"]},
        coupling_cv_scores={str(k): float(v) for k, v in header.get("coupling_cv_scores", [])},
        temperature=float(header.get("temperature", 1.0)),
        condition_noise_ratio=header.get("condition_noise_ratio"),
        condition_cv_scores={float(k): float(v) for k, v in header.get("condition_cv_scores", [])},
        trained_on=_trained_on(header),
        head=_head(header.get("head"), arrays, layout.n_obs_dims, len(tasks) - len(added)),
        handover=_handover(header.get("handover"), arrays),
        orientation=_orientation(header.get("orientation"), arrays),
        novelty=novelty_from_arrays(header.get("novelty"), arrays),
        added_tasks=added,
        human_fit=_json_record(header, "human_fit"),
        human_forecast=_json_record(header, "human_forecast"),
        orientation_cv_scores={
            (np.inf if k == "off" else float(k)): float(v) for k, v in header.get("orientation_cv_scores", [])
        },
        handover_cv_scores={
            (np.inf if k == "off" else float(k)): float(v) for k, v in header.get("handover_cv_scores", [])
        },
    )


def _head(
    meta: dict | None, arrays: dict[str, np.ndarray], n_obs: int, n_tasks: int
) -> RecognitionHead | None:
    """The recognition head of a file (None when it has none), shapes checked."""
    if meta is None:
        return None
    a = {name: arrays[f"head_{name}"] for name in _HEAD_ARRAYS}
    n_feat = 3 * n_obs + n_tasks
    n = int(meta["regressions"])
    if (
        a["ratios"].shape != (n,)
        or a["coef"].shape != (n, n_tasks, n_feat)
        or a["intercept"].shape != (n, n_tasks)
        or a["feature_mean"].shape != (n, n_feat)
        or a["feature_scale"].shape != (n, n_feat)
        or a["c"].shape != (n,)
    ):
        raise ValueError("recognition head arrays have inconsistent shapes")
    # absent before version 3
    extra: dict[str, Any] = {name: arrays.get(f"head_{name}") for name in _HEAD_V3_ARRAYS}
    return RecognitionHead(**a, **extra)


def _handover(meta: dict | None, arrays: dict[str, np.ndarray]) -> HandoverRegression | None:
    """The hand-over regression of a file (None when it has none)."""
    if meta is None:
        return None
    dims = arrays["handover_dims"]
    if not np.all(np.isfinite(dims)) or np.any(dims != np.round(dims)) or np.any(dims < 0):
        raise ValueError("handover_dims must hold non-negative integers")
    neighbour: dict[str, Any] = {name: arrays.get(f"handover_{name}") for name in NEIGHBOUR_ARRAYS}
    return HandoverRegression(
        **{name: arrays[f"handover_{name}"] for name in _HANDOVER_ARRAYS},
        **neighbour,  # absent before version 4
        dims=dims.astype(np.int64),
        trust=float(meta["trust"]),
    )


def _orientation(meta: dict | None, arrays: dict[str, np.ndarray]) -> OrientationEstimate | None:
    """The hand-over orientation estimate of a file (None when it has none: format version 4 and
    older, or a model fitted without the gripper's rotations)."""
    if meta is None:
        return None
    return OrientationEstimate(
        **{name: arrays[f"orientation_{name}"] for name in _ORIENTATION_ARRAYS}, trust=float(meta["trust"])
    )


def _json_record(header: dict, key: str) -> dict | None:
    """The header's JSON object ``key`` (``human_fit``, ``human_forecast``; None: absent, e.g. a file
    of a format version before it)."""
    record = header.get(key)
    if record is None:
        return None
    if not isinstance(record, dict) or len(json.dumps(record)) > MAX_HUMAN_FIT_BYTES:
        raise ValueError(f"{key} is not a JSON object of at most MAX_HUMAN_FIT_BYTES")
    return record


def _trained_on(header: dict) -> tuple[DemoRecord, ...] | None:
    """The training demos of a header (None for format version 1, which does not record them)."""
    if header["format_version"] < 2 or header.get("trained_on") is None:
        return None
    return tuple(DemoRecord.from_json(r) for r in header["trained_on"])


def n_obs_dims(names: dict, groups: list) -> int:
    """Number of observed dims of a header's channels (every group but the last, the robot's)."""
    return sum(len(names[g]) for g in groups[:-1])
