"""The hand-over: the robot's part planned from an observation, once or in the closed loop.

- :mod:`.one_shot`: the online stages of one observation: recognise and predict, time, check
  (``plan`` -> ``PlanResult``).
- :mod:`.retreat`: the segment after the hand-over, from it to the task's retreat target, timed and
  checked like the approach (``plan_retreat`` -> ``RetreatResult``).
- :mod:`.closed_loop`: the closed-loop planner: streaming re-plans re-targeted from the commanded
  state and checked before they are committed (``ClosedLoopPlanner``, ``replay_demo``).
- :mod:`.score`: what a closed-loop replay reached (hand-over error, arrival delay, limit ratios,
  collisions).
- :mod:`.goal`: a prediction conditioned on a goal hand-over pose through inverse kinematics.

Built on :mod:`ipromp_pin.promp` (the model), :mod:`ipromp_pin.robot` (the checks) and
:mod:`ipromp_pin.motion` (timing); writes no file (that is :mod:`ipromp_pin.outputs`).
"""
