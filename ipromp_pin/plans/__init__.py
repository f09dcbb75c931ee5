"""Plans: a hand-over planned from a recording a user brings, end to end, once or for thousands.

- :mod:`.handover`: :func:`~.handover.plan` (a trained model and an observation -> a
  :class:`~.handover.HandoverPlan`: the recognition, the checked and timed motion and its retreat,
  scored against the recording when it has its future);
- :mod:`.files`: a plan's files written together (:func:`~.files.write_plan`);
- :mod:`.batch`: every recording of a list planned (one sub-folder each, a summary), on local worker
  processes or a Dask cluster;
- :mod:`.warnings`: one-line warnings where a user is likely to be fooled.
"""

from .handover import HandoverPlan, human_as_observed, plan

__all__ = ["HandoverPlan", "human_as_observed", "plan"]
