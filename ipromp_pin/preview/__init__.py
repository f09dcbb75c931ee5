"""3-D preview of a recognised hand-over: Baxter playing its predicted trajectory next to the human.

The preview is a `meshcat <https://github.com/meshcat-dev/meshcat-python>`_ scene built with
Pinocchio's :class:`pinocchio.visualize.MeshcatVisualizer`:

- the robot's visual meshes (decimated with ``fast_simplification`` so that an offline page stays
  small), playing the time-parameterised arm trajectory in real time as a meshcat animation (the
  viewer's "Open Controls > Animations" folder has play / pause / reset and a time scrubber);
- the human hand path (observed part green, the rest grey), an animated hand marker when the hand
  times are known, and the hand-over point (gold sphere);
- the human body the checks judged as translucent capsules moving with it (tracked skin-coloured,
  an assumed human grey-blue), the pair of ``human_clearance``'s measure (the closest pair outside
  the hand) as a rod coloured by its separation state (green free, yellow within S_p, orange
  speed-limited, red violation), the report's smallest clearance as a label, and a panel with the
  report's figures (the verdicts'), the checks' measure at the current time and the states along
  the time axis;
- the predicted end-effector path (blue tube) with its uncertainty (translucent tube of radius
  2 sigma, and thin sampled paths), and the recorded robot path (purple) when it is known;
- the task's object in the gripper while the robot holds it, and a panel with every joint's torque
  usage at the current time, at the samples the joint-torque check evaluated (bars coloured by
  usage, each joint's peak marked, the payload held, the report's peak);
- the recognised task on a text plane above the robot, and an HTML panel with the posterior of
  every task, the observation window and the feasibility checks; failing parts are coloured on
  the robot (a link in collision red, a joint near its limit orange).

Two outputs:

- :func:`write_html` writes ONE self-contained HTML file (viewer script, meshes and panel inline,
  no network, no server);
- :class:`LivePreview` serves the same scene on ``127.0.0.1`` only (the web server of
  ``meshcat.Visualizer()`` listens on every interface, so this package runs its own tornado
  server and never starts meshcat's) and can be updated while a streaming recognition progresses.

Everything the preview shows comes in a :class:`PreviewContent`: plain arrays plus the Pinocchio
model handles, so that the preview does not depend on the recognition or planning internals.
All positions are in [m] in the robot's base frame, times in [s] on the human's clock (t = 0 at
the start of the human's motion); the animation ends at the page's last time
(:attr:`PreviewContent.end_s`) and never runs past it.

Modules, each depending only on those above it:

- :mod:`~ipromp_pin.preview.reported`: :class:`ReportedFigure` (a check's figure as the report gives
  it, which a panel states);
- :mod:`~ipromp_pin.preview.body`: :class:`BodyTrack` (the human body's capsules over time) and
  :class:`SeparationTrack` (the checks' separation measure, its pair and the separation state per
  control sample, and the report's figures);
- :mod:`~ipromp_pin.preview.torques`: :class:`~.torques.TorqueTrack` (every joint's torque usage at
  the joint-torque check's samples, and its figures) and :class:`~.torques.HeldObject` (the task's
  object in the gripper, and when held);
- :mod:`~ipromp_pin.preview.content`: :class:`PreviewContent`, :class:`FeasibilityCheck`, validation;
- :mod:`~ipromp_pin.preview.meshes`: decimation of the robot's meshes, tube and sphere meshes;
- :mod:`~ipromp_pin.preview.recorder`: :class:`SceneRecorder`, the meshcat window that records the scene;
- :mod:`~ipromp_pin.preview.body_scene`: drawing the body's capsules and the closest-pair rod;
- :mod:`~ipromp_pin.preview.object_scene`: drawing the held object in the gripper while held;
- :mod:`~ipromp_pin.preview.scene`: drawing a content into a meshcat scene, the HTML panel's state;
- :mod:`~ipromp_pin.preview.page`: the HTML page (scripts and CSS in ``static/``);
- :mod:`~ipromp_pin.preview.server`: the live server on the loopback interface.
"""

from .body import SEPARATION_STATES, BodyTrack, SeparationTrack
from .content import FeasibilityCheck, PreviewContent
from .meshes import DEFAULT_MAX_TRIANGLES, count_triangles, simplify_visual_model, sphere_mesh, tube_mesh
from .page import render_html, write_html
from .recorder import SceneRecorder
from .reported import ReportedFigure
from .scene import (
    CAMERA_FOV_DEG,
    COLOR_COLLISION,
    COLOR_EE_BAND,
    COLOR_EE_MEAN,
    COLOR_EE_TRUTH,
    COLOR_HAND_OBSERVED,
    COLOR_HAND_REST,
    COLOR_HANDOVER,
    COLOR_NEAR_LIMIT,
    camera_view,
    overlay_state,
)
from .server import LivePreview, serve_preview

__all__ = [
    "SEPARATION_STATES",
    "BodyTrack",
    "CAMERA_FOV_DEG",
    "COLOR_COLLISION",
    "COLOR_EE_BAND",
    "COLOR_EE_MEAN",
    "COLOR_EE_TRUTH",
    "COLOR_HANDOVER",
    "COLOR_HAND_OBSERVED",
    "COLOR_HAND_REST",
    "COLOR_NEAR_LIMIT",
    "DEFAULT_MAX_TRIANGLES",
    "FeasibilityCheck",
    "LivePreview",
    "PreviewContent",
    "ReportedFigure",
    "SceneRecorder",
    "SeparationTrack",
    "camera_view",
    "count_triangles",
    "overlay_state",
    "render_html",
    "serve_preview",
    "simplify_visual_model",
    "sphere_mesh",
    "tube_mesh",
    "write_html",
]
