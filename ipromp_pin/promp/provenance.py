"""What a model was trained on: one record per training demo (task, name, source, content digest).

A fitted model keeps these records (and its model file stores them, format version 2), so that a
tool can tell whether a demo it is about to observe was part of the training set: by the digest of
its content (robust to a moved dataset folder), or by its task, name and source together.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass

import numpy as np

from ..data import Demo


@dataclass(frozen=True)
class DemoRecord:
    """One training demo.

    Attributes:
        task: Task name.
        name: Demo name.
        source: File or folder it was read from (or ``synthetic(seed=S)/<task>/<index>``).
        sha256: Hex digest of its content (:func:`demo_digest`).
    """

    task: str
    name: str
    source: str
    sha256: str

    def to_json(self) -> dict[str, str]:
        """The record as a JSON object."""
        return {"task": self.task, "name": self.name, "source": self.source, "sha256": self.sha256}

    @classmethod
    def from_json(cls, value: dict) -> DemoRecord:
        """Inverse of :meth:`to_json`."""
        return cls(str(value["task"]), str(value["name"]), str(value["source"]), str(value["sha256"]))


def demo_digest(demo: Demo) -> str:
    """SHA-256 of a demo's content: its times and every channel group (name, channel names and
    values, in group order) as float64 bytes. Extras and missing-sample masks are not included
    (missing samples are NaN in the values)."""
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(demo.t, dtype="<f8").tobytes())
    for group, values in demo.groups.items():
        h.update(group.encode() + b"\0" + "\0".join(demo.channel_names[group]).encode() + b"\1")
        h.update(np.ascontiguousarray(values, dtype="<f8").tobytes())
    return h.hexdigest()


def demo_record(demo: Demo) -> DemoRecord:
    """The :class:`DemoRecord` of a demo."""
    return DemoRecord(demo.task, demo.name, str(demo.source), demo_digest(demo))


def find_in_training(records: tuple[DemoRecord, ...], demo: Demo) -> DemoRecord | None:
    """The training record that is ``demo`` (same content, or same task, name and source), or None."""
    digest = demo_digest(demo)
    for r in records:
        if r.sha256 == digest or (r.task, r.name, r.source) == (demo.task, demo.name, str(demo.source)):
            return r
    return None
