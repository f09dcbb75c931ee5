"""``ipromp-pin preview``: the planned hand-over as a self-contained page, or live while it streams.

:func:`run_preview` sets up the command (:func:`~ipromp_pin.commands.setup.prepare_session`), plans
the hand-over (:func:`~ipromp_pin.planning.one_shot.plan`) and writes the page
(:func:`write_preview`), or serves it on 127.0.0.1 while the observed samples stream into the
model's streaming estimator.
"""

from __future__ import annotations

import multiprocessing as mp
import time
from pathlib import Path

import numpy as np

from ..data import Demo
from ..exceptions import PipelineError
from ..human import HumanMotion
from ..outputs.preview_content import preview_content
from ..planning.one_shot import LogFn, PlanResult
from ..planning.retreat import RetreatResult
from ..preview import LivePreview, write_html
from ..robot import Robot
from ..robot.objects import ObjectTable
from .config import PipelineConfig
from .meshes import preview_visual_model
from .setup import plan_session, prepare_session


def run_preview(
    cfg: PipelineConfig,
    *,
    html: Path | None = None,
    port: int = 7000,
    speed: float = 1.0,
    wait: bool = True,
    log: LogFn = print,
) -> Path | None:
    """``ipromp-pin preview``: a self-contained HTML file, or a live page on 127.0.0.1.

    Live mode streams the observed samples of the chosen demo one by one into the model's
    streaming estimator (at ``speed`` times real time), updating the task posterior and the
    observation window on the page, then shows the planned trajectory and its checks.

    Returns:
        The HTML file written, or ``None`` in live mode.
    """
    if not (np.isfinite(speed) and speed > 0):
        raise PipelineError(f"preview speed must be a positive factor, got {speed}")
    session = prepare_session(cfg, log, prefetch_meshes=True)
    observation = session.observed()
    result, retreat = plan_session(session, log)
    if html is not None:
        ctx = session.context
        path = write_preview(
            result,
            session.robot,
            session.demo,
            html,
            session.mesh_prefetch,
            ctx.human,
            ctx.objects,
            retreat,
        )
        log(f"[preview] wrote {path} ({path.stat().st_size / 1e6:.1f} MB): open it in a browser (no server)")
        return path
    visual = preview_visual_model(session.robot, session.mesh_prefetch)
    ctx = session.context
    content = preview_content(
        result,
        session.robot,
        session.demo,
        visual_model=visual,
        human=ctx.human,
        objects=ctx.objects,
        retreat=retreat,
    )
    tasks = list(result.prediction.tasks)
    start = content.replace(posterior=np.full(len(tasks), 1.0 / len(tasks)), task="", observed_until_s=0.0)
    live = LivePreview(start, port=port)
    log(f"[preview] live at {live.url} (127.0.0.1 only); streaming {observation.n_samples} samples")
    try:
        stream = session.model.stream()
        t_wall = time.perf_counter()
        for i, t in enumerate(observation.t):
            rec = stream.update(float(t), {g: observation.groups[g][i] for g in observation.groups})
            if rec is not None and (i % 3 == 0 or i == observation.n_samples - 1):
                live.update_posterior(rec.posterior, tasks=list(rec.tasks))
                live.update_observation(float(t))
                log(
                    f"  t={t:5.2f} s  "
                    + "  ".join(f"{k} {v:.2f}" for k, v in zip(rec.tasks, rec.posterior, strict=True))
                )
            delay = t / speed - (time.perf_counter() - t_wall)
            if delay > 0:
                time.sleep(delay)
        live.show(content)
        log(f"[preview] recognised {result.prediction.task}; trajectory and checks shown")
        if wait:
            log("[preview] press Ctrl-C to stop the server")
            while True:
                time.sleep(0.5)
    except KeyboardInterrupt:
        pass
    finally:
        live.close()
    return None


def write_preview(
    result: PlanResult,
    robot: Robot,
    demo: Demo | None,
    path: Path,
    prefetch: mp.process.BaseProcess | None = None,
    human: HumanMotion | None = None,
    objects: ObjectTable | None = None,
    retreat: RetreatResult | None = None,
) -> Path:
    """Write the self-contained offline preview page (after the mesh ``prefetch`` process, if any);
    ``human``: the body drawn when ``demo`` has no tracked skeleton (e.g. the assumed human);
    ``objects``: the tasks' objects (the recognised task's is drawn and in the torques);
    ``retreat``: animated after the hand-over."""
    visual = preview_visual_model(robot, prefetch)
    content = preview_content(
        result, robot, demo, visual_model=visual, human=human, objects=objects, retreat=retreat
    )
    write_html(content, path)
    return path
