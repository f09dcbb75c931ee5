"""``ipromp-pin preview PIPELINE``: the planned hand-over as a self-contained page, or live on
127.0.0.1 while it streams.

:func:`run_preview` sets up the command (:func:`~ipromp_pin.app.session.prepare_session`), plans the
hand-over (:func:`~ipromp_pin.app.session.plan_session`) and writes the page (:func:`write_preview`),
or serves it on 127.0.0.1 while the observed samples stream into the model's streaming estimator.
The modules that compute are imported when it runs, so that ``--help`` answers at once.
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path
from typing import TYPE_CHECKING

from .arguments import add_pipeline_overrides, bounded, pipeline_config, port

if TYPE_CHECKING:
    import multiprocessing as mp

    from ..data import Demo
    from ..human import HumanMotion
    from ..planning.one_shot import LogFn, PlanResult
    from ..planning.retreat import RetreatResult
    from ..preview import LivePreview
    from ..promp import IProMP
    from ..robot import Robot
    from ..robot.objects import ObjectTable
    from .config import PipelineConfig


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``preview`` command to ``subparsers``."""
    p = subparsers.add_parser(
        "preview", help="meshcat preview: live on 127.0.0.1, or a self-contained HTML file"
    )
    add_pipeline_overrides(p)
    p.add_argument("--html", type=Path, help="write a self-contained HTML file instead of serving live")
    p.add_argument(
        "--port", type=port, default=7000, help="live server port on 127.0.0.1, 1-65535 (default %(default)s)"
    )
    p.add_argument(
        "--speed",
        type=bounded(float, 0.0, 1e6, open_low=True),
        default=1.0,
        help="live streaming speed factor, > 0 (default %(default)g: real time)",
    )
    p.add_argument(
        "--no-wait",
        action="store_true",
        help="live: stream at once (without waiting for a browser to connect) and exit when done",
    )
    p.add_argument(
        "--no-retreat", action="store_true", help="do not plan and show the retreat after the hand-over"
    )
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    """Serve the preview live, or write it as an HTML file."""
    from .. import atomic

    if args.html is not None:
        atomic.check_output_file(args.html, "preview page")
    run_preview(
        pipeline_config(args), html=args.html, port=args.port, speed=args.speed, wait=not args.no_wait
    )
    return 0


def run_preview(
    cfg: PipelineConfig,
    *,
    html: Path | None = None,
    port: int = 7000,
    speed: float = 1.0,
    wait: bool = True,
    log: LogFn | None = None,
    wait_for_page: bool | None = None,
    page_timeout_s: float | None = None,
) -> Path | None:
    """``ipromp-pin preview``: a self-contained HTML file, or a live page on 127.0.0.1.

    Live mode streams the observed samples of the chosen demo one by one into the model's
    streaming estimator (at ``speed`` times real time), updating the task posterior and the
    observation window on the page, then shows the planned trajectory and its checks. The stream
    starts once a browser page has connected (``wait_for_page``, default ``wait``; at most
    ``page_timeout_s`` [s], None: as long as it takes); ``wait``: then serve until Ctrl-C.

    Returns:
        The HTML file written, or ``None`` in live mode.
    """
    import numpy as np

    from ..exceptions import PipelineError
    from ..outputs.preview_content import preview_content
    from ..preview import LivePreview
    from ..preview.mesh_cache import preview_visual_model
    from .session import plan_session, prepare_session

    log = log or print
    if not (math.isfinite(speed) and speed > 0):
        raise PipelineError(f"preview speed must be a positive factor, got {speed}")
    session = prepare_session(cfg, log, prefetch_meshes=True)
    observation = session.observed()
    planned = plan_session(session, log)
    result, retreat = planned.approach, planned.retreat
    if html is not None:
        ctx = planned.context  # what the checks knew: the human they judged
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
    ctx = planned.context  # what the checks knew: the human they judged
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
    if wait_for_page is None:
        wait_for_page = wait
    try:
        if wait_for_page:
            # the stream is for someone to watch: it starts when a page has the scene
            log(f"[preview] live at {live.url} (127.0.0.1 only): open it in a browser; streaming starts then")
            seen = live.wait_for_page(page_timeout_s)
            said = "a browser is connected" if seen else f"no browser within {page_timeout_s} s"
            log(f"[preview] {said}: streaming {observation.n_samples} samples")
        else:
            log(f"[preview] live at {live.url} (127.0.0.1 only); streaming {observation.n_samples} samples")
        stream_observation(live, session.model, observation, speed, log)
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


def stream_observation(live: LivePreview, model: IProMP, observation: Demo, speed: float, log: LogFn) -> None:
    """Stream ``observation``'s samples into ``model``'s streaming estimator at ``speed`` times real
    time, showing the posterior and the observation window on ``live`` (every third sample and the
    last) and logging them."""
    stream = model.stream()
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
    ``human``: the human the checks judged (the body drawn, its separation measured);
    ``objects``: the tasks' objects (the recognised task's is drawn and in the torques);
    ``retreat``: animated after the hand-over."""
    from ..outputs.preview_content import preview_content
    from ..preview import write_html
    from ..preview.mesh_cache import preview_visual_model

    visual = preview_visual_model(robot, prefetch)
    content = preview_content(
        result, robot, demo, visual_model=visual, human=human, objects=objects, retreat=retreat
    )
    write_html(content, path)
    return path
