"""evaluation: one protocol runner, scorers plugged into it.

- ``config.py``: :class:`EvaluationConfig`, the paper's grid and accuracies.
- ``splits.py``: train/test splits (paper protocol, random splits) and the dataset-size check.
- ``jobs.py``: one job per model fit; the worker pool (state given by its initializer).
- ``protocol.py``: :func:`run_protocol`, the runner every evaluation uses.
- ``cells.py``: :class:`Cell`, :class:`ClosedLoopCell` and the aggregation of trials into them.
- ``tables.py``: Markdown and JSON tables, writing them.
- ``scorers/``: one scorer per file (one-shot, closed loop, baselines) behind ``Scorer``.
- ``baselines/``: the scikit-learn baselines, one per file behind a registry.
- ``evaluate.py``, ``closed_loop.py``: the one-shot and closed-loop entry points.
- ``arm_plans.py``: the plans on the executing arm (another arm retargeted from the recordings' robot,
  ``evaluate --robot NAME``), scored and re-evaluated; ``arm_tables.py``: their Markdown.
- ``independent.py``: a trajectory re-evaluated from the arm's URDF, independently of the checks.
"""
