"""Train/test splits of a dataset, per task, in the manner of scikit-learn's splitters: the paper's
protocol (the first ``n_train`` demos train, the next ``n_test`` test) and random splits."""

from __future__ import annotations

from collections.abc import Iterator, Mapping

import numpy as np

from ..data import Dataset, Demo
from ..exceptions import DataError
from .config import EvaluationConfig

Indices = dict[str, tuple[list[int], list[int]]]
"""Task -> (train demo indices, test demo indices)."""


def check_task_size(dataset: Dataset, task: str, n_train: int) -> int:
    """The number of demos of ``task``; a :class:`DataError` when fewer than ``n_train`` + 1."""
    n = len(dataset.demos[task])
    if n < n_train + 1:
        raise DataError(
            dataset.root, task, f"{n} demos, the protocol needs {n_train} to train and 1+ to test"
        )
    return n


def check_dataset_size(counts: Mapping[str, int], config: EvaluationConfig, source: object = None) -> None:
    """Check, before any model is fitted, that every task has enough demos for ``config``.

    Every cell needs ``n_train`` training demos and at least one test demo per task; the paper
    protocol's largest cell trains on 20 (21 demos per task). Raises a :class:`DataError` naming
    the smallest task and the settings that fit it (``--protocol splits`` with a smaller
    ``--n-train``).

    Args:
        counts: Task -> number of demos.
        config: The evaluation settings.
        source: The dataset (folder) named in the error.
    """
    if config.protocol == "folds":
        check_fold_sizes(counts, config, source)
        return
    need = max(n for n, _ in config.grid) + 1
    task, have = min(counts.items(), key=lambda kv: kv[1])
    if have >= need:
        return
    fits = [n for n in sorted({n for n, _ in config.grid} | {5, 10, 15}) if n < have] or [have - 1]
    raise DataError(
        source,
        None,
        f"too small for the {config.protocol} protocol: task '{task}' has {have} demos, cells up to "
        f"n_train={need - 1} need {need} per task (n_train to train, 1+ to test); use --protocol splits "
        f"--grid full --n-train {' '.join(str(n) for n in fits)}",
    )


def check_fold_sizes(counts: Mapping[str, int], config: EvaluationConfig, source: object = None) -> None:
    """The ``folds`` protocol's sizes: every task has at least ``n_folds`` demos (a fold each) and,
    outside its largest fold, the grid's largest ``n_train`` to train on (a :class:`DataError`
    naming the task otherwise)."""
    n_train = max(n for n, _ in config.grid)
    for task, have in counts.items():
        others = have - -(-have // config.n_folds)
        if have < config.n_folds or others < n_train:
            raise DataError(
                source,
                task,
                f"{have} demos: {config.n_folds} folds leave {max(others, 0)} outside a fold to train on, "
                f"the cells train on {n_train} (use fewer folds or a smaller --n-train)",
            )


def fold_indices(dataset: Dataset, n_train: int, n_folds: int, fold: int, seed: int) -> Indices:
    """Per task, its demos in ``n_folds`` folds of a random permutation (seeded by ``seed``, the same
    for every fold and training size): fold ``fold`` tests, the first ``n_train`` of the other
    folds' demos (in permutation order) train."""
    rng = np.random.default_rng(seed)
    out = {}
    for task in dataset.tasks:
        perm = rng.permutation(len(dataset.demos[task]))
        parts = np.array_split(perm, n_folds)
        rest = np.concatenate([p for k, p in enumerate(parts) if k != fold])
        out[task] = (rest[:n_train].tolist(), parts[fold].tolist())
    return out


def paper_indices(dataset: Dataset, n_train: int, n_test: int) -> Indices:
    """Per task, the first ``n_train`` demo indices train, the next ``n_test`` test."""
    out = {}
    for task in dataset.tasks:
        n = check_task_size(dataset, task, n_train)
        out[task] = (list(range(n_train)), list(range(n_train, min(n, n_train + n_test))))
    return out


def random_indices(dataset: Dataset, n_train: int, n_test: int, rng: np.random.Generator) -> Indices:
    """Per task, a random permutation: its first ``n_train`` indices train, up to ``n_test`` more test."""
    out = {}
    for task in dataset.tasks:
        idx = rng.permutation(check_task_size(dataset, task, n_train)).tolist()
        out[task] = (idx[:n_train], idx[n_train : n_train + n_test])
    return out


def take(dataset: Dataset, indices: Indices) -> tuple[list[Demo], list[Demo]]:
    """The (train, test) demos of ``indices``, task by task."""
    train = [dataset.demos[t][i] for t, (tr, _) in indices.items() for i in tr]
    test = [dataset.demos[t][i] for t, (_, te) in indices.items() for i in te]
    return train, test


def split_paper(dataset: Dataset, n_train: int, n_test: int) -> tuple[list[Demo], list[Demo]]:
    """First ``n_train`` demos of each task train, the next ``n_test`` test."""
    return take(dataset, paper_indices(dataset, n_train, n_test))


def split_random(
    dataset: Dataset, n_train: int, n_test: int, rng: np.random.Generator
) -> tuple[list[Demo], list[Demo]]:
    """A random split per task: ``n_train`` demos train, up to ``n_test`` of the others test."""
    return take(dataset, random_indices(dataset, n_train, n_test, rng))


class PaperSplit:
    """The paper's protocol: one split per training size (the first demos train).

    Args:
        n_test: Test demos per task.
    """

    n_splits = 1

    def __init__(self, n_test: int) -> None:
        self.n_test = n_test

    def split(self, dataset: Dataset, n_train: int) -> Indices:
        """The indices of the split for ``n_train`` training demos per task."""
        return paper_indices(dataset, n_train, self.n_test)


class RandomSplits:
    """Repeated random splits, drawn from one generator seeded once (the draws follow the calls).

    Args:
        n_test: Test demos per task.
        n_splits: Repeats.
        seed: Seed of the generator.
    """

    def __init__(self, n_test: int, n_splits: int, seed: int) -> None:
        self.n_test = n_test
        self.n_splits = n_splits
        self.rng_ = np.random.default_rng(seed)

    def split(self, dataset: Dataset, n_train: int) -> Indices:
        """The indices of the next random split for ``n_train`` training demos per task."""
        return random_indices(dataset, n_train, self.n_test, self.rng_)


def splitter(config: EvaluationConfig) -> PaperSplit | RandomSplits:
    """The splitter of ``config.protocol`` (``paper`` or ``splits``)."""
    config.check_protocol()
    if config.protocol == "paper":
        return PaperSplit(config.n_test)
    return RandomSplits(config.n_test, config.n_splits, config.seed)


def iter_splits(dataset: Dataset, config: EvaluationConfig) -> Iterator[tuple[int, int, Indices]]:
    """(repeat, n_train, indices) of every split of ``config``: per repeat, the training sizes of
    the grid from the largest down (the order that fixes the random draws for a seed); for the
    ``folds`` protocol the repeat is the fold (:func:`fold_indices`)."""
    n_train_values = sorted({n for n, _ in config.grid}, reverse=True)
    if config.protocol == "folds":
        for fold in config.fold_indices():
            for n_train in n_train_values:
                yield fold, n_train, fold_indices(dataset, n_train, config.n_folds, fold, config.seed)
        return
    split = splitter(config)
    for rep in range(config.repeats):
        for n_train in n_train_values:
            yield rep, n_train, split.split(dataset, n_train)
