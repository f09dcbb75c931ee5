"""Small random interaction problems for the model tests (fast enough for the direct reference)."""

from __future__ import annotations

import numpy as np

from ipromp_pin.data import ROBOT, Dataset, Demo


def random_dataset(
    seed: int,
    n_tasks: int = 3,
    n_demos: int = 8,
    dims: dict[str, int] | None = None,
    n_joints: int = 3,
    rate_hz: float = 25.0,
    missing_group: str | None = None,
    coupling: float = 1.0,
) -> Dataset:
    """Random smooth demos: each task has its own mean curves; each demo has a random amplitude
    ``s`` that scales both the human channels and (with ``coupling``) the robot's deviation, a
    random duration in [1.6, 2.6] s and white sensor noise.

    Args:
        seed: Random seed.
        n_tasks, n_demos: Tasks and demos per task.
        dims: Human group -> number of channels (default {"a": 2, "b": 3}).
        n_joints: Robot joints.
        rate_hz: Sampling rate in [Hz].
        missing_group: If given, this group loses a few samples per demo (flagged missing).
        coupling: How strongly the robot's deviation follows the human amplitude.
    """
    rng = np.random.default_rng(seed)
    dims = {"a": 2, "b": 3} if dims is None else dims
    demos: dict[str, list[Demo]] = {}
    for k in range(n_tasks):
        task = f"task{k}"
        freq = {g: rng.uniform(0.5, 1.5, d) for g, d in dims.items()}
        phase0 = {g: rng.uniform(0, 2 * np.pi, d) for g, d in dims.items()}
        level = {g: rng.normal(0, 1.0, d) for g, d in dims.items()}
        q0 = rng.normal(0, 0.3, n_joints)
        q1 = rng.normal(0, 0.8, n_joints)
        q_dev = rng.normal(0, 0.3, n_joints)
        out = demos[task] = []
        for i in range(n_demos):
            duration = rng.uniform(1.6, 2.6)
            t = np.arange(0.0, duration + 1e-9, 1.0 / rate_hz)
            z = t / t[-1]
            s = rng.normal(0.0, 1.0)
            groups, names, missing = {}, {}, {}
            for g, d in dims.items():
                curve = level[g] + np.sin(2 * np.pi * freq[g] * z[:, None] + phase0[g])
                curve = curve * (1.0 + 0.3 * s) + rng.normal(0, 0.05, (t.size, d))
                groups[g] = curve
                names[g] = tuple(f"{g}{j}" for j in range(d))
            if missing_group is not None:
                mask = np.zeros(t.size, dtype=bool)
                mask[rng.choice(np.arange(1, t.size - 1), size=max(1, t.size // 10), replace=False)] = True
                groups[missing_group] = np.where(mask[:, None], np.nan, groups[missing_group])
                missing[missing_group] = mask
            smooth = z**3 * (10 - 15 * z + 6 * z**2)
            q = q0 + smooth[:, None] * (q1 + coupling * s * q_dev + rng.normal(0, 0.02, n_joints))
            groups[ROBOT] = q + rng.normal(0, 0.002, q.shape)
            names[ROBOT] = tuple(f"j{j}" for j in range(n_joints))
            out.append(
                Demo(
                    task=task,
                    name=f"{task}_{i}",
                    source=f"random({seed})/{task}/{i}",
                    t=t,
                    groups=groups,
                    channel_names=names,
                    missing=missing,
                )
            )
    return Dataset(root=f"random({seed})", demos=demos)


def split(dataset: Dataset, n_train: int) -> tuple[Dataset, dict[str, list[Demo]]]:
    """First ``n_train`` demos of every task for training, the rest for testing."""
    train = Dataset(dataset.root, {t: d[:n_train] for t, d in dataset.demos.items()})
    test = {t: d[n_train:] for t, d in dataset.demos.items()}
    return train, test
