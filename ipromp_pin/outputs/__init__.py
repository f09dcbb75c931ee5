"""What the commands write: trajectory files, bags, reports, figures and preview content.

- :mod:`.files`: the one table of output files (name, report key, whether a robot executes it, which
  commands write it).
- :mod:`.staging`: the one staging of a trajectory that passed, failed or failed but was allowed, and
  of the run's reports, into an :class:`ipromp_pin.atomic.OutputSet`.
- :mod:`.trajectory_files`: ``trajectory.csv`` and ``trajectory.json`` (ROS 2 or ROS 1
  JointTrajectory), written and read back.
- :mod:`.rosbag`: the run as a rosbag2 folder (MCAP) and a ROS 1 bag, standard message types.
- :mod:`.report`: the run's ``report.json`` / ``report.txt``; :mod:`.replay_report`: the replay's
  ``replans.json``, ``report.json`` and ``report.txt``.
- :mod:`.plots`: matplotlib figures (PNG, Agg canvas: the user's backend is left alone);
  :mod:`.figures`: the run's figures from its plan.
- :mod:`.preview_content`: what the preview pages show of a plan or a replay (:mod:`.human_preview`:
  the body and the separation; :mod:`.torque_preview`: the joints' torque usage and the held object).
"""
