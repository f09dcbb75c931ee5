"""Versioned, pickle-free model files: the estimator's parameters and its fitted state.

A model file is a single ``.npz`` archive (``numpy.savez``) read back with
``allow_pickle=False``. It holds

* ``header``: a JSON string with ``format`` (:data:`FORMAT_NAME`),
  ``format_version`` (:data:`FORMAT_VERSION`), the package version, the
  constructor parameters, task names, channel groups and names, and the fitted
  scalars (``T_norm`` in [s], noise ratio, CV scores, observed groups coupled to
  the robot and their CV scores, per-task phase prior and the robot's shrinkage
  intensity);
* plain float arrays: the channel scaling (``scaler_offset``, ``scaler_scale``,
  ``scaler_log_shift``: NaN for linear channels),
  ``task_log_prior``, ``residual_var`` and, per task index ``i``,
  ``task{i}_mean`` (D, K), ``task{i}_diag`` (D,), ``task{i}_factor`` (D, K, r),
  ``task{i}_alpha_grid``, ``task{i}_alpha_log_prior``, ``task{i}_train_weights``
  (N, D, K), ``task{i}_train_alpha`` (N,), ``task{i}_shrinkage`` (D,);
* (version 2) the header's ``temperature``, ``condition_noise_ratio`` and ``head`` (the number R of
  its regressions, or null), and with a head its arrays ``head_ratios`` (R,), ``head_coef``
  (R, T, 3 D_o + T), ``head_intercept`` (R, T), ``head_feature_mean`` and ``head_feature_scale``
  (R, 3 D_o + T), ``head_c`` (R,) and ``head_cv_log_loss`` (R, number of candidate C).

Files written before the coupling was introduced (no ``coupling`` parameter, no
``task{i}_shrinkage``) load as fully coupled models with one shrinkage intensity;
the covariance is entirely in ``diag`` and ``factor``, so older readers also load
newer files and predict the same.

Floats are stored exactly (binary arrays; JSON floats use Python's
round-tripping repr), so a loaded model gives bitwise identical predictions. A
file of a newer format version, a truncated or corrupt file, or a file that is
not a model raises :class:`~ipromp_pin.exceptions.ModelFileError`.
"""

from __future__ import annotations

import json
import zipfile
from pathlib import Path

import numpy as np

from ..exceptions import IPrompPinError, ModelFileError
from ..version import __version__
from .basis import GaussianBasis
from .distribution import ChannelScaler, TaskModel
from .fitted import FittedModel
from .head import RecognitionHead
from .layout import ChannelLayout

FORMAT_NAME = "ipromp_pin.IProMP"
"""Value of the header's ``format`` field."""

FORMAT_VERSION = 2
"""Current (and highest readable) format version. Version 2 added the likelihood temperature, the
conditioning noise ratio and the recognition head (``head_*`` arrays); version-1 files load with
temperature 1, the conditioning noise ratio equal to the noise ratio and no head (as they predicted)."""

_HEAD_ARRAYS = ("ratios", "coef", "intercept", "feature_mean", "feature_scale", "c", "cv_log_loss")

_TASK_ARRAYS = ("mean", "diag", "factor", "alpha_grid", "alpha_log_prior", "train_weights", "train_alpha")


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
        "n_points": int(params["n_points"]),
        "task_prior": None if params["task_prior"] is None else dict(params["task_prior"]),
        "robot_group": params["robot_group"],
        "log_groups": list(params["log_groups"]),
        "pooling": float(params["pooling"]),
        "coupling": coupling if isinstance(coupling, str) else list(coupling),
    }


def _number_or_text(value: object) -> float | str:
    return value if isinstance(value, str) else float(value)  # type: ignore[arg-type]


def write_model(params: dict, fitted: FittedModel, path: str | Path) -> None:
    """Write an estimator's parameters (``IProMP.get_params()``) and fitted state to ``path`` (``.npz``).

    ``params["observe"]`` is written as the fitted layout's observed groups (a list).
    """
    layout = fitted.layout
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
        "task_scalars": [
            {
                # the robot's intensity, as a scalar for readers of files without task{i}_shrinkage
                "shrinkage": float(m.shrinkage[robot_lo]),
                "alpha_mu": float(m.alpha_mu),
                "alpha_sigma": float(m.alpha_sigma),
            }
            for m in fitted.task_models()
        ],
    }
    arrays = {
        "header": np.array(json.dumps(header)),
        "scaler_offset": fitted.scaler.offset,
        "scaler_scale": fitted.scaler.scale,
        "scaler_log_shift": fitted.scaler.log_shift,
        "task_log_prior": fitted.task_log_prior,
        "residual_var": fitted.residual_var,
    }
    if fitted.head is not None:
        for name in _HEAD_ARRAYS:
            arrays[f"head_{name}"] = np.asarray(getattr(fitted.head, name), dtype=float)
    for i, m in enumerate(fitted.task_models()):
        for name in _TASK_ARRAYS:
            arrays[f"task{i}_{name}"] = np.asarray(getattr(m, name), dtype=float)
        arrays[f"task{i}_shrinkage"] = np.asarray(m.shrinkage, dtype=float)
    path = Path(path)
    with open(path, "wb") as fh:
        np.savez(fh, **arrays)


def read_model(path: str | Path) -> tuple[dict, FittedModel]:
    """Read a model file written by :func:`write_model` -> the estimator parameters and fitted state.

    Raises:
        ModelFileError: missing, truncated or corrupt file, not a model, or a newer format version.
    """
    path = Path(path)
    if not path.is_file():
        raise ModelFileError(f"{path}: model file not found")
    try:
        with np.load(path, allow_pickle=False) as npz:
            if "header" not in npz.files:
                raise ModelFileError(f"{path}: not an ipromp_pin model file (no header)")
            header = json.loads(str(npz["header"][()]))
            _check_header(path, header)
            arrays = {name: np.array(npz[name]) for name in npz.files if name != "header"}
    except ModelFileError:
        raise
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile, json.JSONDecodeError) as exc:
        raise ModelFileError(f"{path}: not a readable model file ({type(exc).__name__}: {exc})") from exc
    try:
        return _params(header), _fitted(header, arrays)
    except (KeyError, TypeError, ValueError, IndexError, AttributeError, IPrompPinError) as exc:
        raise ModelFileError(f"{path}: corrupt model file ({type(exc).__name__}: {exc})") from exc


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
        head=_head(header.get("head"), arrays, layout.n_obs_dims, len(tasks)),
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
    return RecognitionHead(**a)
