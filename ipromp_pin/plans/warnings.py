"""Warnings where a user is likely to be fooled by a model: one line each, on standard error.

* a saved model whose tasks or channels do not match the dataset it is used on (it will still
  "recognise" one of its own tasks, often with a posterior near 1);
* a demo to observe that was in the model's training set (the result is then no test of the
  model), or a model file that does not record its training set;
* a model with a single task (every observation is recognised as it, at posterior 1);
* an observation far outside everything the model was trained on, in the model's own scaled units
  (EMG in other units, another sensor): it is still "recognised", often at posterior 1;
* a task the data or the model has but the objects file lacks: its plans carry no payload and have
  no retreat (said otherwise only inside the joint-torque check's reason).

The checks are pure functions returning messages; :func:`warn_stderr` prints one the way the
command line does (``warning: ...``, no traceback).
"""

from __future__ import annotations

import sys
from collections.abc import Iterable

from ..data import Dataset, Demo
from ..promp import IProMP
from ..promp.inputs import range_warnings as observed_range_warnings
from ..promp.provenance import find_in_training
from ..robot.objects import ObjectTable


def warn_stderr(message: str) -> None:
    """Print ``warning: <message>`` as one line on standard error."""
    print(f"warning: {message}", file=sys.stderr, flush=True)


def range_warnings(model: IProMP, observation: Demo) -> list[str]:
    """A warning per observed group of ``observation`` that lies far outside the training data
    (:data:`~ipromp_pin.promp.inputs.RANGE_WARNING_SD`), naming the group and how far out it is."""
    return observed_range_warnings(model.fitted_, observation)


def single_task_warning(model: IProMP) -> str | None:
    """A warning when the model knows one task only."""
    if len(model.tasks_) == 1:
        return (
            f"the model has a single task ('{model.tasks_[0]}'): every observation is recognised as it "
            "with posterior 1.00; train on several tasks for a meaningful recognition"
        )
    return None


def dataset_mismatch_warnings(model: IProMP, dataset: Dataset, model_name: str = "the model") -> list[str]:
    """Warnings when a (loaded) model's tasks or channels differ from the dataset's.

    Args:
        model: A fitted model.
        dataset: The dataset it is used on.
        model_name: How to name the model in the messages (e.g. its file).
    """
    out = []
    model_tasks, data_tasks = list(model.tasks_), list(dataset.tasks)
    if set(model_tasks) != set(data_tasks):
        only_data = [t for t in data_tasks if t not in model_tasks]
        only_model = [t for t in model_tasks if t not in data_tasks]
        out.append(
            f"{model_name} was trained on tasks {', '.join(model_tasks)}, the dataset has "
            f"{', '.join(data_tasks)}"
            + (f" ({', '.join(only_data)} cannot be recognised)" if only_data else "")
            + (f" ({', '.join(only_model)} not in the dataset)" if only_model and not only_data else "")
        )
    demos = dataset.all_demos()
    for group in model.groups_:
        have = next((d.channel_names[group] for d in demos if group in d.channel_names), None)
        want = tuple(model.channel_names_[group])
        if have is not None and tuple(have) != want:
            out.append(
                f"{model_name}'s channels of group '{group}' ({', '.join(want)}) differ from the dataset's "
                f"({', '.join(have)})"
            )
    return out


def held_out_warning(
    model: IProMP,
    demo: Demo,
    model_name: str = "the model",
    hint: str = "choose another --demo, or train without it",
) -> str | None:
    """A warning when ``demo`` was in the model's training set (``hint``: what to do about it), or when
    that cannot be checked."""
    label = f"{demo.task}/{demo.name}" if demo.task else demo.name
    records = model.trained_on_
    if records is None:
        return (
            f"{model_name} does not record its training demos (model file format version 1): cannot check "
            f"that {label} was held out of training"
        )
    if find_in_training(records, demo) is not None:
        return (
            f"{label} was in {model_name}'s training set: the recognition and prediction are not a test on "
            f"unseen data ({hint})"
        )
    return None


def loaded_model_warnings(model: IProMP, dataset: Dataset, demo: Demo, model_name: str) -> list[str]:
    """Every warning about a loaded model used on ``dataset`` to observe ``demo``."""
    out = dataset_mismatch_warnings(model, dataset, model_name)
    for w in (held_out_warning(model, demo, model_name), single_task_warning(model)):
        if w is not None:
            out.append(w)
    return out


def missing_object_warnings(tasks: Iterable[str], objects: ObjectTable) -> list[str]:
    """A warning per task of ``tasks`` (the data's or the model's) without an entry in ``objects``."""
    return [
        f"task '{task}' has no entry in {objects.path}: no payload and no retreat for its plans (the "
        "joint torques of an empty gripper)"
        for task in tasks
        if objects.for_task(task) is None
    ]
