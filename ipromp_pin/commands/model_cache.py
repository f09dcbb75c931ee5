"""On-disk cache of trained models, so that a second run on the same demos does not train again.

Training chooses its settings by cross-validation (a few seconds on the built-in demos, most of a
warm ``ipromp-pin run``) and gives the same model every time for the same inputs: fitting is
deterministic. :func:`fit_cached` keeps the trained model, as the model file :meth:`IProMP.save`
writes (versioned, pickle-free), in :func:`~ipromp_pin.cache.cache_dir` (``models/``), keyed by a
SHA-256 over everything the fit reads:

* the cache layout version, the package version, the model file format version and the source of
  the ``ipromp_pin.promp`` package (an edited estimator never reads a model trained by another);
* the estimator's parameters (:meth:`IProMP.get_params`);
* every training demo: task, name, time stamps, channel groups with their names and missing masks,
  duration;
* the forward kinematics given to ``fit`` (a callable cannot be hashed: its outputs at the demos'
  final configurations and at fixed probe configurations are).

A missing, unreadable, corrupt or stale entry is a miss (the model is trained and the entry
rewritten); a read-only cache folder only means nothing is written. At most :data:`MAX_ENTRIES`
models are kept (the least recently used are removed).
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from ..cache import cache_dir
from ..data import Demo
from ..exceptions import IPrompPinError
from ..promp import IProMP
from ..promp.serialization import FORMAT_VERSION
from ..version import __version__

__all__ = ["CACHE_VERSION", "MAX_ENTRIES", "fit_cached", "training_key"]

CACHE_VERSION = 1
"""Version of the cache's key and layout (part of the key)."""

MAX_ENTRIES = 16
"""Trained models kept in the cache; older ones (by last use) are removed."""

_PROBE_SEED = 20171128
_N_PROBES = 8
_PROMP_DIR = Path(__file__).resolve().parent.parent / "promp"


def _source_digest() -> bytes:
    """SHA-256 over the ``ipromp_pin.promp`` package's Python sources (name and content)."""
    h = hashlib.sha256()
    for path in sorted(_PROMP_DIR.glob("*.py")):
        h.update(path.name.encode())
        h.update(path.read_bytes())
    return h.digest()


def _update_array(h: hashlib._Hash, a: np.ndarray) -> None:
    a = np.ascontiguousarray(a)
    h.update(f"{a.dtype.str}{a.shape}".encode())
    h.update(a.tobytes())


def _fk_fingerprint(
    fk: Callable[[np.ndarray], np.ndarray], demos: Sequence[Demo], robot_group: str
) -> np.ndarray | None:
    """The forward kinematics' outputs at the demos' final robot configurations and at fixed probes,
    or None when it cannot be evaluated there (then the fit is not cached)."""
    finals = [d.groups[robot_group][-1] for d in demos if robot_group in d.groups]
    if not finals:
        return None
    q = np.asarray(finals, dtype=float)
    probes = np.random.default_rng(_PROBE_SEED).uniform(-1.5, 1.5, (_N_PROBES, q.shape[1]))
    try:
        out = np.asarray(fk(np.vstack([q, probes])), dtype=float)
    except Exception:  # noqa: BLE001 - any failure only means "do not cache"; fit reports it itself
        return None
    return out if np.all(np.isfinite(out)) else None


def training_key(
    model: IProMP, demos: Sequence[Demo], fk: Callable[[np.ndarray], np.ndarray] | None = None
) -> str | None:
    """The cache key (hex SHA-256) of ``model.fit(demos, fk=fk)``, or None when it cannot be cached."""
    params = model.get_params()
    h = hashlib.sha256()
    header = {
        "cache": CACHE_VERSION,
        "package": __version__,
        "format": FORMAT_VERSION,
        "params": {k: repr(v) for k, v in sorted(params.items())},
    }
    h.update(json.dumps(header, sort_keys=True).encode())
    h.update(_source_digest())
    for d in demos:
        h.update(json.dumps([d.task, d.name, d.duration_s, sorted(d.groups)]).encode())
        _update_array(h, d.t)
        for g in sorted(d.groups):
            h.update(json.dumps([g, list(d.channel_names.get(g, ()))]).encode())
            _update_array(h, d.groups[g])
            if g in d.missing:
                _update_array(h, d.missing[g])
    if fk is not None:
        fingerprint = _fk_fingerprint(fk, demos, str(params["robot_group"]))
        if fingerprint is None:
            return None
        _update_array(h, np.round(fingerprint, 12))
    return h.hexdigest()


def _prune(folder: Path, keep: int) -> None:
    """Remove all but the ``keep`` most recently used model files of ``folder`` (errors ignored)."""
    try:
        entries = sorted(folder.glob("*.npz"), key=lambda p: p.stat().st_mtime, reverse=True)
        for path in entries[keep:]:
            path.unlink()
    except OSError:
        pass


def fit_cached(
    model: IProMP,
    demos: Sequence[Demo],
    fk: Callable[[np.ndarray], np.ndarray] | None = None,
    folder: Path | None = None,
) -> tuple[IProMP, Path | None]:
    """``model.fit(demos, fk=fk)``, or the identical model trained earlier and kept in the cache.

    Args:
        model: An unfitted estimator (its parameters are part of the key).
        demos: The training demos.
        fk: Forward kinematics given to ``fit`` (joint angles (n, J) in [rad] -> positions (n, 3) in
            [m]), or None.
        folder: The cache folder (default ``cache_dir("models")``).

    Returns:
        The fitted model and the cache file it was read from (None when it was trained here).
    """
    folder = cache_dir("models") if folder is None else folder
    key = training_key(model, demos, fk)
    path = None if key is None else folder / f"{key}.npz"
    if path is not None and path.is_file():
        try:
            cached = IProMP.load(path)
        except (IPrompPinError, OSError, ValueError, KeyError):
            cached = None
        if cached is not None and cached.get_params().keys() == model.get_params().keys():
            try:
                os.utime(path)  # last use, for pruning
            except OSError:
                pass
            return cached, path
    model.fit(list(demos), fk=fk)
    if path is not None:
        try:
            folder.mkdir(parents=True, exist_ok=True)
            model.save(path)  # atomic: readers never see a partial file
        except (IPrompPinError, OSError):
            return model, None  # a cache that cannot be written is not used
        _prune(folder, MAX_ENTRIES)
    return model, None
