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

Each entry ``<key>.npz`` has a sidecar ``<key>.json`` holding the key it was stored under and the
SHA-256 of the model file. Before a cached model is used it is verified against what it claims
(:func:`verify_entry`): the sidecar's key is the file's name, the file's digest is the sidecar's,
its parameters are the estimator's (values, not only names) and its provenance (``trained_on``, one
record per training demo) names exactly the training demos (task, name, source). A model file
copied over an entry (trained on other demos, or by other settings) therefore fails, and is
rebuilt with one line saying why.

A missing, unreadable, corrupt, stale or unverified entry is a miss (the model is trained and the
entry rewritten); a read-only cache folder only means nothing is written. At most :data:`MAX_ENTRIES`
models are kept (the least recently used are removed).
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .. import atomic
from ..cache import cache_dir
from ..data import Demo
from ..exceptions import IPrompPinError
from ..promp import IProMP
from ..promp.serialization import FORMAT_VERSION
from ..version import __version__

if TYPE_CHECKING:
    from ..robot.human_settings import HumanSettings

__all__ = ["CACHE_VERSION", "MAX_ENTRIES", "fit_cached", "training_key", "verify_entry"]

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
    model: IProMP,
    demos: Sequence[Demo],
    fk: Callable[[np.ndarray], np.ndarray] | None = None,
    fk_rot: Callable[[np.ndarray], np.ndarray] | None = None,
    human: HumanSettings | None = None,
) -> str | None:
    """The cache key (hex SHA-256) of ``model.fit(demos, fk=fk, fk_rot=fk_rot)`` (with ``human``: and
    of the handing arm's forecast calibrated on the demos' skeletons through its skeleton map), or
    None when it cannot be cached."""
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
        if human is not None:
            for k in sorted(k for k in d.extras if k.startswith("skeleton:")):
                h.update(k.encode())
                _update_array(h, np.asarray(d.extras[k], dtype=float))
    if human is not None:
        h.update(json.dumps(["human", repr(human.skeleton)]).encode())
    for name, kinematics in (("fk", fk), ("fk_rot", fk_rot)):
        if kinematics is None:
            continue
        fingerprint = _fk_fingerprint(kinematics, demos, str(params["robot_group"]))
        if fingerprint is None:
            return None
        h.update(name.encode())
        _update_array(h, np.round(fingerprint, 12))
    return h.hexdigest()


def _prune(folder: Path, keep: int) -> None:
    """Remove all but the ``keep`` most recently used model files of ``folder`` and their sidecars
    (errors ignored)."""
    try:
        entries = sorted(folder.glob("*.npz"), key=lambda p: p.stat().st_mtime, reverse=True)
        for path in entries[keep:]:
            path.unlink()
            path.with_suffix(".json").unlink(missing_ok=True)
    except OSError:
        pass


def _file_digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _write_sidecar(path: Path, key: str) -> None:
    """Write ``<key>.json`` beside the entry: the key and the model file's SHA-256."""
    doc = {"cache": CACHE_VERSION, "key": key, "sha256": _file_digest(path)}
    atomic.write_text(path.with_suffix(".json"), json.dumps(doc))


def verify_entry(path: Path, key: str, model: IProMP, cached: IProMP, demos: Sequence[Demo]) -> str:
    """Why the cached model at ``path`` (stored under ``key``) must not be used for ``model.fit(demos)``,
    or "" when it is what it claims: its sidecar names ``key`` and the file's digest, its parameters
    are ``model``'s and its provenance is exactly ``demos`` (by task, name and source)."""
    try:
        side = json.loads(path.with_suffix(".json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return "it has no readable record of the key it was stored under"
    if not isinstance(side, dict) or side.get("key") != key:
        return "its record names another key"
    if side.get("sha256") != _file_digest(path):
        return "the file is not the one stored under its key (its digest differs)"

    def canonical(params: dict) -> str:  # tuples and lists alike (a loaded model holds lists)
        return json.dumps(params, sort_keys=True, default=repr)

    if canonical(model.get_params()) != canonical(cached.get_params()):
        return "it was trained with other settings"
    records = cached.trained_on_
    if records is None:
        return "it does not record the demos it was trained on"
    # by task, name and source: the content is bound by the key and the file digest above, and
    # hashing every demo's content again would cost about 10 ms for 60 demos
    want = {(d.task, d.name, str(d.source)) for d in demos}
    have = {(r.task, r.name, r.source) for r in records}
    if have != want:
        return "it was trained on other demos: " + demo_set_difference(have, want)
    return ""


def demo_set_difference(have: set[tuple[str, str, str]], want: set[tuple[str, str, str]]) -> str:
    """How two sets of (task, name, source) demos differ, in a few words with an example of each side."""
    parts = []
    if have - want:
        task, name, _ = sorted(have - want)[0]
        parts.append(f"{len(have - want)} of its {len(have)} are not among these (e.g. {task}/{name})")
    if want - have:
        task, name, _ = sorted(want - have)[0]
        parts.append(f"{len(want - have)} of these {len(want)} were not in its training (e.g. {task}/{name})")
    return "; ".join(parts)


def fit_cached(
    model: IProMP,
    demos: Sequence[Demo],
    fk: Callable[[np.ndarray], np.ndarray] | None = None,
    folder: Path | None = None,
    log: Callable[[str], None] | None = None,
    fk_rot: Callable[[np.ndarray], np.ndarray] | None = None,
    human: HumanSettings | None = None,
) -> tuple[IProMP, Path | None]:
    """``model.fit(demos, fk=fk, fk_rot=fk_rot)``, or the identical model trained earlier and kept
    in the cache.

    Args:
        model: An unfitted estimator (its parameters are part of the key).
        demos: The training demos.
        fk: Forward kinematics given to ``fit`` (joint angles (n, J) in [rad] -> positions (n, 3) in
            [m]), or None.
        folder: The cache folder (default ``cache_dir("models")``).
        log: Where the one line about an entry that failed its verification goes (None: nowhere).
        fk_rot: Gripper rotations given to ``fit`` (joint angles -> rotation matrices (n, 3, 3)), or
            None.
        human: The human settings with which the handing arm's forecast is calibrated after the fit
            (:func:`~ipromp_pin.planning.human_forecast.with_forecast`); None: no forecast.

    Returns:
        The fitted model and the cache file it was read from (None when it was trained here).
    """
    folder = cache_dir("models") if folder is None else folder
    key = training_key(model, demos, fk, fk_rot, human)
    path = None if key is None else folder / f"{key}.npz"
    if path is not None and key is not None and path.is_file():
        try:
            cached = IProMP.load(path)
        except (IPrompPinError, OSError, ValueError, KeyError):
            cached = None
        why = "it cannot be read" if cached is None else verify_entry(path, key, model, cached, demos)
        if cached is not None and not why:
            try:
                os.utime(path)  # last use, for pruning
            except OSError:
                pass
            return cached, path
        if log is not None:
            log(f"[model] the cached model {path} is not used ({why}): training again and replacing it")
    model.fit(list(demos), fk=fk, fk_rot=fk_rot)
    if human is not None:
        from ..planning.human_forecast import with_forecast  # the planning layer, when used

        model = with_forecast(model, demos, human)
    if path is not None and key is not None:
        try:
            folder.mkdir(parents=True, exist_ok=True)
            model.save(path)  # atomic: readers never see a partial file
            _write_sidecar(path, key)
        except (IPrompPinError, OSError):
            return model, None  # a cache that cannot be written is not used
        _prune(folder, MAX_ENTRIES)
    return model, None
