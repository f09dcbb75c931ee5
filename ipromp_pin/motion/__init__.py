"""Joint motion: limits, timed trajectories, their timing and their re-targeting.

- :mod:`.trajectory`: :class:`~.trajectory.JointLimits` (position in [rad], velocity [rad/s],
  acceleration [rad/s^2], jerk [rad/s^3]) and :class:`~.trajectory.Trajectory` (samples at a fixed
  control rate).
- :mod:`.timing`: a joint path timed with toppra and jerk-limited with ruckig (``time_path``).
- :mod:`.retarget`: jerk-limited re-targeting with ruckig from the current state onto a predicted
  trajectory's timeline (the closed loop's motion).
- :mod:`.limits`: limit profiles (conservative from the settings, demonstrated from training demos,
  profile files).

The package knows joints, times and limits; it imports the robot model only for its limits.
Importing it defers toppra's import of ``matplotlib.pyplot`` (:mod:`.deferred`).
"""

from .deferred import defer_pyplot

defer_pyplot()
