"""Versioned, pickle-free model files.

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
  (N, D, K), ``task{i}_train_alpha`` (N,), ``task{i}_shrinkage`` (D,).

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
from typing import TYPE_CHECKING

import numpy as np

from .exceptions import IPrompPinError, ModelFileError
from .model import ChannelScaler, TaskModel

if TYPE_CHECKING:
    from .recognition import IProMP

FORMAT_NAME = "ipromp_pin.IProMP"
"""Value of the header's ``format`` field."""

FORMAT_VERSION = 1
"""Current (and highest readable) format version."""

_TASK_ARRAYS = ("mean", "diag", "factor", "alpha_grid", "alpha_log_prior", "train_weights", "train_alpha")


def save_model(model: IProMP, path: str | Path) -> None:
    """Write a fitted :class:`~ipromp_pin.recognition.IProMP` to ``path`` (``.npz``)."""
    from . import __version__

    header = {
        "format": FORMAT_NAME,
        "format_version": FORMAT_VERSION,
        "package_version": __version__,
        "params": {
            "observe": list(model.observe),
            "n_basis": int(model.n_basis),
            "width": None if model.width is None else float(model.width),
            "ridge": float(model.ridge),
            "margin": float(model.margin),
            "blas_threads": model.blas_threads,
            "n_alpha": int(model.n_alpha),
            "alpha_width": float(model.alpha_width),
            "noise": model.noise if isinstance(model.noise, str) else float(model.noise),
            "n_points": int(model.n_points),
            "task_prior": model.task_prior,
            "robot_group": model.robot_group,
            "log_groups": list(model.log_groups),
            "pooling": float(model.pooling),
            "coupling": model.coupling if isinstance(model.coupling, str) else list(model.coupling),
        },
        "tasks": list(model.tasks_),
        "groups": list(model.groups_),
        "channel_names": {g: list(v) for g, v in model.channel_names_.items()},
        "duration_nominal_s": float(model.duration_nominal_s_),
        "noise_ratio": float(model.noise_ratio_),
        "cv_scores": [[float(k), float(v)] for k, v in model.cv_scores_.items()],
        "coupled_groups": list(model.coupled_groups_),
        "coupling_cv_scores": [[k, float(v)] for k, v in model.coupling_cv_scores_.items()],
        "task_scalars": [
            {
                # the robot's intensity, as a scalar for readers of files without task{i}_shrinkage
                "shrinkage": float(m.shrinkage[model.group_slices_[model.robot_group][0]]),
                "alpha_mu": float(m.alpha_mu),
                "alpha_sigma": float(m.alpha_sigma),
            }
            for m in (model.models_[t] for t in model.tasks_)
        ],
    }
    arrays = {
        "header": np.array(json.dumps(header)),
        "scaler_offset": model.scaler_.offset,
        "scaler_scale": model.scaler_.scale,
        "scaler_log_shift": model.scaler_.log_shift,
        "task_log_prior": model.task_log_prior_,
        "residual_var": model.residual_var_,
    }
    for i, t in enumerate(model.tasks_):
        m = model.models_[t]
        for name in _TASK_ARRAYS:
            arrays[f"task{i}_{name}"] = np.asarray(getattr(m, name), dtype=float)
        arrays[f"task{i}_shrinkage"] = np.asarray(m.shrinkage, dtype=float)
    path = Path(path)
    with open(path, "wb") as fh:
        np.savez(fh, **arrays)


def load_model(path: str | Path) -> IProMP:
    """Read a model file written by :func:`save_model`.

    Raises:
        ModelFileError: missing, truncated or corrupt file, not a model, or a newer format version.
    """
    from .recognition import IProMP

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
        return _build(IProMP, header, arrays)
    except (KeyError, TypeError, ValueError, IndexError, IPrompPinError) as exc:
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


def _build(cls: type, header: dict, arrays: dict[str, np.ndarray]) -> IProMP:
    p = header["params"]
    model = cls(
        observe=p["observe"],
        n_basis=p["n_basis"],
        width=p["width"],
        ridge=p["ridge"],
        margin=p["margin"],
        blas_threads=p["blas_threads"],
        n_alpha=p["n_alpha"],
        alpha_width=p["alpha_width"],
        noise=p["noise"],
        n_points=p["n_points"],
        task_prior=p["task_prior"],
        robot_group=p["robot_group"],
        log_groups=p["log_groups"],
        pooling=p["pooling"],
        coupling=p.get("coupling", "all"),
    )
    from .basis import GaussianBasis

    groups = list(header["groups"])
    model.groups_ = groups
    model.channel_names_ = {g: tuple(header["channel_names"][g]) for g in groups}
    sizes = [len(model.channel_names_[g]) for g in groups]
    starts = np.concatenate([[0], np.cumsum(sizes)])
    model.group_slices_ = {g: (int(starts[i]), int(starts[i + 1])) for i, g in enumerate(groups)}
    model.n_dims_ = int(starts[-1])
    model.n_obs_dims_ = int(starts[-2])
    model.joint_names_ = model.channel_names_[model.robot_group]
    model.basis_ = GaussianBasis(model.n_basis, model.width, model.ridge, model.margin)
    model.scaler_ = ChannelScaler(
        offset=arrays["scaler_offset"], scale=arrays["scaler_scale"], log_shift=arrays["scaler_log_shift"]
    )
    model.duration_nominal_s_ = float(header["duration_nominal_s"])
    model.tasks_ = list(header["tasks"])
    model.task_log_prior_ = arrays["task_log_prior"]
    model.residual_var_ = arrays["residual_var"]
    model.noise_ratio_ = float(header["noise_ratio"])
    model.cv_scores_ = {float(k): float(v) for k, v in header["cv_scores"]}
    model.coupled_groups_ = list(header.get("coupled_groups", model.observe))
    model.coupling_cv_scores_ = {str(k): float(v) for k, v in header.get("coupling_cv_scores", [])}
    if any(g not in model.observe for g in model.coupled_groups_):
        raise ValueError(f"coupled groups {model.coupled_groups_} are not observed groups")
    models = {}
    n_dims, k = model.n_dims_, model.basis_.n_basis
    for i, t in enumerate(model.tasks_):
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
    if model.scaler_.offset.shape != (n_dims,) or model.task_log_prior_.shape != (len(model.tasks_),):
        raise ValueError("scaling or task prior arrays have inconsistent shapes")
    model.models_ = models
    model._set_noise()
    return model
