"""Helpers of the tests of what the previews show of the human: a demo with a tracked skeleton."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ipromp_pin.data import Demo
from ipromp_pin.human import SKELETON_PREFIX, HumanMotion
from ipromp_pin.robot.human_settings import HumanSettings


def leaning_skeleton(settings: HumanSettings, demo: Demo, lean_m: float = 0.12) -> Demo:
    """``demo`` with a tracked skeleton (``skeleton:<frame>`` extras, as the readers write them): the
    assumed standing human of ``settings`` (a robot's ``[human]``; its arm as assumed, a plausible
    skeleton), its body but the handing hand leaning ``lean_m`` [m] toward the robot's base over the
    recording."""
    h = HumanMotion.assumed_human(settings, demo.t)
    toward = -np.asarray(settings.placement.torso_m, dtype=float) * np.array([1.0, 1.0, 0.0])
    toward /= np.linalg.norm(toward)
    s = (demo.t - demo.t[0]) / (demo.t[-1] - demo.t[0])
    extras = dict(demo.extras)
    for j, frame in enumerate(h.frames):
        p = h.positions_m[:, j]
        extras[SKELETON_PREFIX + frame] = p if frame == "/left_hand_1" else p + lean_m * s[:, None] * toward
    return Demo(
        demo.task, demo.name, demo.source, demo.t, demo.groups, demo.channel_names, demo.missing, extras
    )


def write_leaning_dataset(folder: Path, settings: HumanSettings) -> list[str]:
    """Two synthetic tasks of 6 demos (seed 5), each with a tracked skeleton leaning toward the robot
    (:func:`leaning_skeleton`), written as native demos into ``folder/<task>/``; the task names."""
    from ipromp_pin.readers.native import write_demo
    from ipromp_pin.readers.synthetic import make_synthetic_dataset

    ds = make_synthetic_dataset(n_tasks=2, n_demos=6, seed=5)
    for task, demos in ds.demos.items():
        for d in demos:
            write_demo(leaning_skeleton(settings, d), folder / task / f"{d.name}.npz")
    return list(ds.tasks)
