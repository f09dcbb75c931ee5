"""Channel groups and their signal processing.

- :mod:`.groups`: the channel-group specification (unit, interpolation, plausibility check, log
  scaling, ROS message type) and its registry: adding a sensor group is one entry plus its reader.
- :mod:`.checks`: the plausibility checks the specifications name (physical ranges, unit
  quaternions, joint angles, EMG activity).
- :mod:`.preprocess`: clocks, stream alignment, resampling, the EMG envelope, quaternion continuity.
"""
