"""Planning: the robot's part of a hand-over planned from an observation, once or in the closed loop.

- :mod:`.one_shot`: one observation -> recognise and predict, time, check, re-time until safe
  (``plan`` -> ``PlanResult``);
- :mod:`.retreat`: the segment after the hand-over, to the task's retreat target, timed and checked
  like the approach (``plan_retreat`` -> ``RetreatResult``);
- :mod:`.closed_loop`: the closed-loop planner: streaming re-plans re-targeted from the commanded
  state, checked before they are committed (``ClosedLoopPlanner``, ``replay_demo``);
- :mod:`.timers`: how each of them times a motion for the one re-time-until-safe loop of
  :mod:`ipromp_pin.safety`;
- :mod:`.transfer`: a model of another robot executed on this arm, retargeted through the gripper;
- :mod:`.goal`: a prediction conditioned on a goal hand-over pose through inverse kinematics.

The planners are thin users of the model (:mod:`ipromp_pin.promp`), the checks
(:mod:`ipromp_pin.safety`) and the timing (:mod:`ipromp_pin.motion`); they write no file (that is
:mod:`ipromp_pin.outputs`) and score nothing (that is :mod:`ipromp_pin.evaluation.scoring`).
"""
