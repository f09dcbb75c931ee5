"""Which frames of a recording's tracked skeleton the body model reads: the skeleton maps of ``[human]``.

The body model (:mod:`ipromp_pin.human.body`) places its capsules between 13 joints
(:data:`BODY_JOINTS`), named internally by the OpenNI frames of ``handover_20171128``
(``/head_1`` ... ``/right_knee_1``, :func:`body_frame`), whose ``left_*`` / ``right_*`` are the
tracker's *mirrored* labels (the ``/left_*`` frames lie on the person's right side; ``docs/safety.md``).
A skeleton map says, for a recording from any tracker, which of its frames is each joint:

* its keys are the body joints in the recording's *own* left/right labels, its values one frame name
  or a list of frame names whose mean is the joint (a tracker without a neck frame: the mean of the
  two shoulders);
* ``mirrored`` says whether those labels are mirrored like OpenNI's (``true``) or anatomical, the
  person's own left and right (``false``: Azure Kinect, MediaPipe, most motion capture); an anatomical
  map's ``left_*`` joints feed the body model's ``right_*`` parts, so a body part is the same side of
  the person whatever the tracker.

Shipped maps (:data:`SKELETONS`, chosen by ``[human] skeleton``): ``openni`` (the default, the frames
of ``handover_20171128``) and ``azure_kinect`` (Azure Kinect Body Tracking, ``k4abt_joint_id_t``, 32
joints, of which 13 are read). ``[human.skeleton_map]`` replaces single joints of the chosen map.
"""

from __future__ import annotations

from dataclasses import dataclass

BODY_JOINTS: tuple[str, ...] = (
    "head",
    "neck",
    "torso",
    "left_shoulder",
    "right_shoulder",
    "left_elbow",
    "right_elbow",
    "left_hand",
    "right_hand",
    "left_hip",
    "right_hip",
    "left_knee",
    "right_knee",
)
"""The joints of the body model, in OpenNI's mirrored left/right labels."""

MAP_KEYS: tuple[str, ...] = (*BODY_JOINTS, "mirrored")
"""Keys of a ``[human.skeleton_map]`` table."""


def body_frame(joint: str) -> str:
    """The body model's frame name of ``joint`` (``"left_hand"`` -> ``"/left_hand_1"``, OpenNI's)."""
    return f"/{joint}_1"


def other_side(joint: str) -> str:
    """``joint`` of the other side (``left_hand`` <-> ``right_hand``; ``head`` unchanged)."""
    for a, b in (("left_", "right_"), ("right_", "left_")):
        if joint.startswith(a):
            return b + joint[len(a) :]
    return joint


@dataclass(frozen=True)
class SkeletonMap:
    """A recording's frame names for the body joints (see the module docstring).

    Attributes:
        name: The map's name (a shipped map's, or ``"<shipped>+[human.skeleton_map]"``).
        frames: Joint (in the recording's own labels) -> its frame names (the joint is their mean).
        mirrored: Whether the recording's left/right labels are mirrored like OpenNI's.
    """

    name: str
    frames: dict[str, tuple[str, ...]]
    mirrored: bool

    def body_frames(self) -> dict[str, tuple[str, ...]]:
        """The body model's frame (``/left_hand_1`` ...) -> the recording's frames it is the mean of."""
        return {
            body_frame(joint if self.mirrored else other_side(joint)): names
            for joint, names in self.frames.items()
        }


def _azure(joint: str) -> str:
    """The frame of a ``k4abt_joint_id_t`` joint: ``/`` and its name in lower case."""
    return "/" + joint.lower()


SKELETONS: dict[str, SkeletonMap] = {
    "openni": SkeletonMap("openni", {j: (body_frame(j),) for j in BODY_JOINTS}, mirrored=True),
    "azure_kinect": SkeletonMap(
        "azure_kinect",
        {
            "head": (_azure("HEAD"),),
            "neck": (_azure("NECK"),),
            "torso": (_azure("SPINE_NAVEL"),),
            "left_shoulder": (_azure("SHOULDER_LEFT"),),
            "right_shoulder": (_azure("SHOULDER_RIGHT"),),
            "left_elbow": (_azure("ELBOW_LEFT"),),
            "right_elbow": (_azure("ELBOW_RIGHT"),),
            "left_hand": (_azure("HAND_LEFT"),),
            "right_hand": (_azure("HAND_RIGHT"),),
            "left_hip": (_azure("HIP_LEFT"),),
            "right_hip": (_azure("HIP_RIGHT"),),
            "left_knee": (_azure("KNEE_LEFT"),),
            "right_knee": (_azure("KNEE_RIGHT"),),
        },
        mirrored=False,
    ),
}
"""The shipped skeleton maps. ``openni``: the OpenNI/NiTE frames of ``handover_20171128``
(``/<joint>_1``, the first tracked user; mirrored labels). ``azure_kinect``: Azure Kinect Body
Tracking SDK joints (``k4abt_joint_id_t``: learn.microsoft.com/azure/kinect-dk/body-joints), each as the
frame ``/<joint name in lower case>`` (``K4ABT_JOINT_SHOULDER_LEFT`` -> ``/shoulder_left``);
anatomical labels; the torso is ``SPINE_NAVEL``, the hand ``HAND_*`` (between the wrist and the
fingertips, like OpenNI's hand)."""
