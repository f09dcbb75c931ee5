"""Time-scrubbing preview of a closed-loop replay (``ipromp-pin replay``'s ``preview.html``).

Built on the offline preview (:mod:`~ipromp_pin.preview.content`, :mod:`~ipromp_pin.preview.scene`,
:mod:`~ipromp_pin.preview.page`), which it does not change: the robot plays the commanded
trajectory, beside the recorded robot's gripper path (purple), the commanded gripper path (blue) and
the human's hand path (grey) when hand positions are known. On top of it, as functions of time:

- the hand-over point (gold) moves to each re-plan's predicted hand-over position;
- the gripper path planned by the latest committed re-plan (cyan) replaces the previous one;
- the human's hand path observed so far grows (green), the hand marker moves along it;
- the task's object is drawn in the gripper while the robot holds it, and the joints' torque usage
  at the scrubbed time is a panel of bars (``static/torques.js``), when the content has them;
- the human body's capsules move with the recording and the closest robot-body pair is a rod
  coloured by its separation state (:mod:`~ipromp_pin.preview.body_scene`), when the content has a
  body and a separation; ``static/separation.js`` shows the distance at the scrubbed time and the
  states along the slider;
- the HTML panel shows, at the scrubbed time, the task posterior of the latest re-plan, the observed
  part of the human's motion, and a second panel (``static/timeline.js``) the re-plan's predicted
  hand-over time, its planned arrival and whether it was committed or refused (and why), or the
  stop or retreat it committed on an unknown observation, with a time slider. Both follow meshcat's
  animation ("Open Controls > Animations" plays it); the slider seeks it.

Everything comes in plain arrays (:class:`TimelineEvent`), like :class:`PreviewContent`.
"""

from __future__ import annotations

import html
import json
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import meshcat
import meshcat.animation
import meshcat.geometry as mg
import numpy as np

from .content import PreviewContent, finite_array, preview_error
from .meshes import DEFAULT_MAX_TRIANGLES, sphere_mesh, tube_mesh
from .page import recorded_page
from .recorder import SceneRecorder
from .scene import (
    COLOR_HAND_OBSERVED,
    COLOR_HANDOVER,
    RobotView,
    animation_times,
    build_scene,
    overlay_state,
    scene_animation,
)

__all__ = ["TimelineEvent", "render_timeline_html", "timeline_end_s", "write_timeline_html"]

_TRAIL_PIECES = 40
"""The observed hand trail is drawn in this many pieces, each shown from its time on."""

COLOR_PLAN = 0x17BECF
"""Colour of the gripper path planned by the latest committed re-plan."""


@dataclass(frozen=True)
class TimelineEvent:
    """What the closed loop knew and did at one re-plan.

    Attributes:
        t_s: Re-plan time in [s] from the motion start.
        observed_until_s: Last observed human sample in [s].
        task: Recognised task ("" if unknown).
        posterior: Posterior of every task (the content's ``tasks`` order), or empty.
        predicted_handover_s: Predicted hand-over time in [s], or None.
        handover_point: (3,) predicted hand-over gripper position in [m], or None.
        planned_path: (M, 3) gripper path of the plan in [m] (committed plans only), or None.
        arrival_s: When the plan comes to rest, in [s], or None.
        committed: Whether the plan was committed.
        reason: Why it was refused.
        action: What a committed plan does: ``""`` a re-target toward the hand-over, else its words
            (e.g. a stop or a retreat on an unknown observation).
    """

    t_s: float
    observed_until_s: float
    task: str = ""
    posterior: Sequence[float] = ()
    predicted_handover_s: float | None = None
    handover_point: np.ndarray | None = None
    planned_path: np.ndarray | None = None
    arrival_s: float | None = None
    committed: bool = False
    reason: str = ""
    action: str = ""


def _static(name: str) -> str:
    return resources.files(__package__).joinpath("static", name).read_text(encoding="utf-8")


def _check_events(content: PreviewContent, events: Sequence[TimelineEvent]) -> list[TimelineEvent]:
    out = []
    last = -np.inf
    for i, e in enumerate(events):
        if not np.isfinite(e.t_s) or e.t_s < last:
            raise preview_error(f"events[{i}].t_s", "times must be finite and non-decreasing")
        last = e.t_s
        if len(e.posterior) and len(e.posterior) != len(content.tasks):
            raise preview_error(
                f"events[{i}].posterior", f"has {len(e.posterior)} values for {len(content.tasks)} tasks"
            )
        point = (
            None
            if e.handover_point is None
            else finite_array(e.handover_point, f"events[{i}].handover_point", 1, 3)
        )
        path = (
            None
            if e.planned_path is None
            else finite_array(e.planned_path, f"events[{i}].planned_path", 2, 3)
        )
        out.append(
            TimelineEvent(
                float(e.t_s), float(e.observed_until_s), str(e.task), [float(p) for p in e.posterior],
                e.predicted_handover_s, point, path, e.arrival_s, bool(e.committed), str(e.reason),
                str(e.action),
            )
        )  # fmt: skip
    return out


def _tube(
    node: meshcat.Visualizer, points: np.ndarray, radius: float, color: int, opacity: float = 1.0
) -> None:
    vertices, faces = tube_mesh(np.asarray(points, dtype=float), radius, 6)
    material = mg.MeshPhongMaterial(color=color, opacity=opacity, transparent=opacity < 1.0)
    node.set_object(mg.TriangularMeshGeometry(vertices, faces), material)


def timeline_end_s(content: PreviewContent, events: Sequence[TimelineEvent]) -> float:
    """The page's last time in [s] on the human's clock: the content's (:attr:`PreviewContent.end_s`:
    the robot's, the hand's, the body's, ... last samples) or the last re-plan's, whichever is later.
    The animation ends there and the page states it as the duration."""
    return max(content.end_s, events[-1].t_s if events else 0.0)


def _timeline_scene(
    window: SceneRecorder, content: PreviewContent, events: list[TimelineEvent], robot: RobotView, fps: float
) -> None:
    """Add the time-dependent objects and replace the animation by one that also drives them."""
    viewer = meshcat.Visualizer(window=window)
    plans = [i for i, e in enumerate(events) if e.committed and e.planned_path is not None]
    paths = [path for e in events if e.committed and (path := e.planned_path) is not None]
    for k, path in enumerate(paths):
        _tube(viewer[f"timeline/plans/{k}"], path, 0.009, COLOR_PLAN, 0.7)
        viewer[f"timeline/plans/{k}"].set_property("visible", False)
    points = [i for i, e in enumerate(events) if e.handover_point is not None]
    if points:
        viewer["timeline/handover"].set_object(
            mg.TriangularMeshGeometry(*sphere_mesh(np.zeros(3), 0.035)),
            mg.MeshPhongMaterial(color=COLOR_HANDOVER),
        )
    trail_t: list[float] = []
    if content.hand_path is not None and content.hand_t_s is not None:
        n = content.hand_path.shape[0]
        cuts = np.unique(np.linspace(0, n - 1, _TRAIL_PIECES + 1).round().astype(int))
        for k, (a, b) in enumerate(zip(cuts[:-1], cuts[1:], strict=True)):
            _tube(viewer[f"timeline/trail/{k}"], content.hand_path[a : b + 1], 0.01, COLOR_HAND_OBSERVED)
            viewer[f"timeline/trail/{k}"].set_property("visible", False)
            trail_t.append(float(content.hand_t_s[b]))

    times, rate = animation_times(timeline_end_s(content, events), fps)
    event_t = np.array([e.t_s for e in events])
    plan_t = event_t[plans] if plans else np.zeros(0)
    point_t = event_t[points] if points else np.zeros(0)
    animation = scene_animation(viewer, robot, content, times, rate)
    shown_plan, shown_point = -2, -2
    shown_trail = 0
    for f, t in enumerate(times):
        with animation.at_frame(viewer, f) as frame:
            k_plan = int(np.searchsorted(plan_t, t + 1e-9)) - 1
            if k_plan != shown_plan or f == 0:
                for k in range(len(plans)):
                    if f == 0 or k in (k_plan, shown_plan):
                        frame[f"timeline/plans/{k}"].set_property("visible", "boolean", k == k_plan)
                shown_plan = k_plan
            k_point = int(np.searchsorted(point_t, t + 1e-9)) - 1
            if points and (k_point != shown_point or f == 0):
                T = np.eye(4)
                T[:3, 3] = events[points[max(k_point, 0)]].handover_point
                frame["timeline/handover"].set_transform(T)
                frame["timeline/handover"].set_property("visible", "boolean", k_point >= 0)
                shown_point = k_point
            observed = max([e.observed_until_s for e in events if e.t_s <= t + 1e-9], default=t)
            n_trail = int(np.searchsorted(np.array(trail_t), max(observed, t) + 1e-9)) if trail_t else 0
            if trail_t and (n_trail != shown_trail or f == 0):
                for k in range(len(trail_t)):
                    if f == 0 or shown_trail <= k < n_trail:
                        frame[f"timeline/trail/{k}"].set_property("visible", "boolean", k < n_trail)
                shown_trail = n_trail
    viewer.set_animation(animation, play=True, repetitions=1)


def render_timeline_html(
    content: PreviewContent,
    events: Sequence[TimelineEvent],
    *,
    motion_s: float | None = None,
    summary: Sequence[str] = (),
    max_triangles: int = DEFAULT_MAX_TRIANGLES,
    fps: float = 30.0,
) -> str:
    """Self-contained HTML page (no network, no server) of a closed-loop replay.

    Args:
        content: The replay as a preview: ``t_s``/``q`` the commanded trajectory, ``ee_mean`` the
            commanded gripper path, ``ee_truth`` the recorded one, ``hand_path``/``hand_t_s`` the
            human's hand, ``tasks``; its ``handover_point`` and ``observed_until_s`` are not drawn
            (the timeline draws them as they change).
        events: The re-plans, in time order.
        motion_s: Duration of the human's motion in [s] (the observed part is shown against it).
        summary: Lines shown under the timeline panel (e.g. the reached errors).
        max_triangles: Robot mesh budget.
        fps: Animation frames per second.
    """
    if fps <= 0:
        raise preview_error("fps", f"must be > 0, got {fps}")
    events = _check_events(content, events)
    base = content.replace(handover_point=None, observed_until_s=None)
    window = SceneRecorder()
    robot = RobotView(base, max_triangles)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        build_scene(window, base, robot=robot, fps=fps)
    _timeline_scene(window, base, events, robot, fps)
    overlay = overlay_state(base)
    for item in overlay["legend"]:  # the blue tube is what was commanded, not one prediction
        if item["label"] == "predicted gripper path":
            item["label"] = "commanded gripper path"
    overlay["legend"] = overlay["legend"] + [
        {"label": "predicted hand-over point", "color": f"#{COLOR_HANDOVER:06x}"},
        {"label": "plan of the latest committed re-plan", "color": f"#{COLOR_PLAN:06x}"},
    ]
    data = {
        "overlay": overlay,
        "duration_s": timeline_end_s(base, events),
        "motion_s": float(motion_s) if motion_s is not None else None,
        "summary": [str(s) for s in summary],
        "events": [
            {
                "t_s": e.t_s,
                "observed_until_s": e.observed_until_s,
                "task": e.task,
                "posterior": list(e.posterior),
                "predicted_handover_s": e.predicted_handover_s,
                "arrival_s": e.arrival_s,
                "committed": e.committed,
                "reason": e.reason,
                "action": e.action,
            }
            for e in events
        ],
    }
    text = json.dumps(data, allow_nan=False).replace("</", "<\\/")
    extra = (
        f"<style>\n{_static('timeline.css')}</style>\n"
        f'<script type="application/json" id="ipromp-timeline-data">{text}</script>\n'
    )
    return recorded_page(window, html.unescape(base.title), _static("timeline.js"), extra)


def write_timeline_html(
    content: PreviewContent,
    events: Sequence[TimelineEvent],
    path: str | Path,
    **kwargs,
) -> Path:
    """Write :func:`render_timeline_html` to ``path`` (one self-contained file); returns the path."""
    path = Path(path)
    text = render_timeline_html(content, events, **kwargs)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8")
    return path
