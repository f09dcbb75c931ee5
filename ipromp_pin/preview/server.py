"""Live preview server: the preview served on the loopback interface, updatable while a recognition streams.

The web server of ``meshcat.Visualizer()`` listens on every interface, so this module runs its own
tornado server on ``127.0.0.1`` (or another loopback address) only, and never starts meshcat's. The
page (:func:`~ipromp_pin.preview.page.live_page`) connects to the websocket ``/ws``; a new page
receives the whole recorded scene followed by an ``ipromp_synced`` message with the number of
commands, then every new command as the scene is updated.

Safety. Requests whose ``Host`` header is not a loopback name (``localhost``, ``127.0.0.1``, the
address served on) are refused with 403: a page of another site that makes its own name resolve to
127.0.0.1 (DNS rebinding) cannot read the preview or open its websocket. A browser that goes away
abruptly (a closed tab, a killed connection) is dropped quietly, without a traceback.
"""

from __future__ import annotations

import asyncio
import ipaddress
import threading
import time
from collections.abc import Sequence
from typing import Any

import numpy as np
import tornado.httpserver
import tornado.ioloop
import tornado.iostream
import tornado.netutil
import tornado.web
import tornado.websocket

from .content import FeasibilityCheck, PreviewContent, finite_array, preview_error
from .meshes import DEFAULT_MAX_TRIANGLES
from .page import live_page
from .recorder import SceneRecorder, packb
from .scene import RobotView, build_scene, update_scene

__all__ = ["LivePreview", "serve_preview"]

ALLOWED_HOST_NAMES = ("localhost", "127.0.0.1")
"""``Host`` header names the live server answers (besides the loopback address it listens on)."""


def host_allowed(host_header: str, served_host: str) -> bool:
    """Whether a request's ``Host`` header (``name`` or ``name:port``, IPv6 in brackets) names this
    machine: ``localhost``, ``127.0.0.1`` or the loopback address ``served_host``."""
    h = host_header.strip().lower()
    if h.startswith("["):
        name = h[1 : h.find("]")] if "]" in h else h
    else:
        name = h.rsplit(":", 1)[0] if h.count(":") == 1 else h
    return bool(name) and (name in ALLOWED_HOST_NAMES or name == served_host.lower())


def _check_port(port: object) -> int:
    if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
        raise preview_error("port", f"must be 0 (any free port) or in 1-65535, got {port!r}")
    return port


def _check_loopback(host: str) -> str:
    """Normalised loopback IP address of ``host`` (``"localhost"`` is ``127.0.0.1``).

    Raises:
        DataError: ``host`` is not an IP address, or not a loopback one.
    """
    name = "127.0.0.1" if host == "localhost" else host
    try:
        address = ipaddress.ip_address(name)
    except ValueError as exc:
        raise preview_error("host", f"'{host}' is not an IP address") from exc
    if not address.is_loopback:
        raise preview_error("host", f"the live preview only listens on a loopback address, not '{host}'")
    return str(address)


class LivePreview:
    """Preview served on the loopback interface, updatable while a recognition streams.

    Example::

        with LivePreview(content, port=7000) as live:
            print(live.url)
            live.update_posterior(posterior, task="handover_cup")

    Attributes:
        url: Address of the page, ``http://127.0.0.1:<port>/``.
        host: Loopback address the server listens on.
        port: Port the server listens on.
        content: Content currently shown.
        fps: Frames per second of the scene's animation.
    """

    def __init__(
        self,
        content: PreviewContent,
        *,
        host: str = "127.0.0.1",
        port: int = 7000,
        max_triangles: int = DEFAULT_MAX_TRIANGLES,
        fps: float = 30.0,
        port_attempts: int = 50,
    ) -> None:
        self.host = _check_loopback(host)
        self.content = content
        self.fps = float(fps)
        self._recorder = SceneRecorder()
        self._robot = RobotView(content, max_triangles)
        build_scene(self._recorder, content, robot=self._robot, fps=self.fps)
        self._clients: set = set()
        self._writes: set = set()  # the writes to the pages not done yet (futures of the server's loop)
        self._connected = threading.Event()  # set once a page has received the whole scene
        self._loop: tornado.ioloop.IOLoop | None = None
        self._server: tornado.httpserver.HTTPServer | None = None
        self._thread: threading.Thread | None = None
        self._sockets = self._bind(_check_port(port), port_attempts)
        self.port = int(self._sockets[0].getsockname()[1])
        self.url = (
            f"http://{self.host}:{self.port}/"
            if ":" not in self.host
            else f"http://[{self.host}]:{self.port}/"
        )
        self._start()

    # -- server ---------------------------------------------------------------------------------
    def _bind(self, port: int, attempts: int) -> list:
        if port == 0:
            return tornado.netutil.bind_sockets(0, address=self.host)
        last: OSError | None = None
        for candidate in range(port, min(port + max(1, attempts), 65536)):
            try:
                return tornado.netutil.bind_sockets(candidate, address=self.host)
            except OSError as exc:
                last = exc
        raise preview_error("port", f"no free port in [{port}, {port + attempts}) on {self.host}: {last}")

    def _start(self) -> None:
        preview = self
        page = live_page(self.content.title).encode("utf-8")

        def refuse_foreign_host(handler: tornado.web.RequestHandler) -> None:
            if not host_allowed(handler.request.host or "", preview.host):
                handler.set_status(403)
                handler.finish("403: the live preview answers only requests for localhost or 127.0.0.1\n")

        class PageHandler(tornado.web.RequestHandler):
            def prepare(self) -> None:
                refuse_foreign_host(self)

            def get(self) -> None:
                self.set_header("Content-Type", "text/html; charset=utf-8")
                self.set_header("Cache-Control", "no-store")
                self.write(page)

        class NoIconHandler(tornado.web.RequestHandler):
            def prepare(self) -> None:
                refuse_foreign_host(self)

            def get(self) -> None:
                self.set_status(204)

        class SocketHandler(tornado.websocket.WebSocketHandler):
            def prepare(self) -> None:
                refuse_foreign_host(self)

            def open(self) -> None:
                preview._on_open(self)

            def on_close(self) -> None:
                preview._clients.discard(self)

            def on_message(self, message: Any) -> None:  # the viewer only sends image captures
                pass

        ready = threading.Event()

        def run() -> None:
            aio = asyncio.new_event_loop()
            asyncio.set_event_loop(aio)
            self._loop = loop = tornado.ioloop.IOLoop.current()
            app = tornado.web.Application(
                [(r"/", PageHandler), (r"/favicon.ico", NoIconHandler), (r"/ws", SocketHandler)],
                log_function=lambda handler: None,  # no access log lines on the console
            )
            self._server = server = tornado.httpserver.HTTPServer(app)
            server.add_sockets(self._sockets)
            ready.set()
            loop.start()
            # writes queued when the loop stopped (updates sent as the server closed) are cancelled
            # and run to their end: none is left pending, or never started, when the loop closes
            writes = [w for w in preview._writes if not w.done()]
            for w in writes:
                w.cancel()
            if writes:
                aio.run_until_complete(asyncio.gather(*writes, return_exceptions=True))
            loop.close(all_fds=True)

        self._thread = threading.Thread(target=run, name=f"ipromp-preview-{self.port}", daemon=True)
        self._thread.start()
        ready.wait()
        self._recorder.listener = self._forward

    def _on_open(self, socket: Any) -> None:
        with self._recorder.lock:
            commands = self._recorder.commands()
            self._clients.add(socket)
        for data in commands:
            if not self._send(socket, data):
                return
        if self._send(socket, packb({"type": "ipromp_synced", "count": len(commands)})):
            self._connected.set()

    def _send(self, socket: Any, data: bytes) -> bool:
        """Send ``data`` to one page; a page that went away is dropped quietly (no traceback, now or
        when the write completes). Returns whether the page is still connected."""
        try:
            future = socket.write_message(data, binary=True)
        except (tornado.websocket.WebSocketClosedError, tornado.iostream.StreamClosedError):
            self._clients.discard(socket)
            return False
        self._writes.add(future)
        future.add_done_callback(lambda f, s=socket: self._sent(f, s))
        return True

    def _sent(self, future: Any, socket: Any) -> None:
        self._writes.discard(future)
        if not future.cancelled() and future.exception() is not None:
            self._clients.discard(socket)

    def _forward(self, data: bytes) -> None:
        if self._loop is not None:
            self._loop.add_callback(self._broadcast, data)

    def _broadcast(self, data: bytes) -> None:
        for socket in list(self._clients):
            self._send(socket, data)

    @property
    def running(self) -> bool:
        """Whether the server thread is running."""
        return self._thread is not None and self._thread.is_alive()

    def wait_for_page(self, timeout_s: float | None = None) -> bool:
        """Block until a browser page has connected and been sent the whole scene (``timeout_s`` [s]:
        at most that long; None: as long as it takes); returns whether one has."""
        return self._connected.wait(timeout_s)

    @property
    def n_clients(self) -> int:
        """Number of connected browser pages."""
        return len(self._clients)

    def commands(self) -> list[bytes]:
        """Every msgpack-encoded command that rebuilds the current scene (what a new page receives)."""
        return self._recorder.commands()

    def close(self, timeout_s: float = 5.0) -> None:
        """Stop the server, close every connection and the listening socket (idempotent)."""
        if self._thread is None:
            return
        loop, server = self._loop, self._server
        self._recorder.listener = None
        if loop is None or server is None:  # the server thread never started
            return

        def stop() -> None:
            for socket in list(self._clients):
                socket.close()
            self._clients.clear()
            server.stop()
            loop.stop()

        loop.add_callback(stop)
        self._thread.join(timeout_s)
        self._thread = None

    def __enter__(self) -> LivePreview:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- updates --------------------------------------------------------------------------------
    def show(self, content: PreviewContent) -> None:
        """Show new content (same robot model): redraws everything but the robot meshes' geometry."""
        self.content = content
        build_scene(self._recorder, content, robot=self._robot, fps=self.fps)

    def _redraw(
        self,
        content: PreviewContent,
        *,
        human: bool = False,
        prediction: bool = False,
        label: bool = False,
        animation: bool = False,
        paint: bool = False,
    ) -> None:
        self.content = content
        update_scene(
            self._recorder,
            content,
            robot=self._robot,
            fps=self.fps,
            human=human,
            prediction=prediction,
            label=label,
            animation=animation,
            paint=paint,
        )

    def update_posterior(
        self, posterior: np.ndarray, *, task: str | None = None, tasks: Sequence[str] | None = None
    ) -> None:
        """New task posterior (K,); ``task`` defaults to the most probable one."""
        tasks = tuple(self.content.tasks if tasks is None else tasks)
        posterior = finite_array(posterior, "posterior", 1)
        if task is None and len(tasks) == posterior.size:
            task = tasks[int(np.argmax(posterior))]
        content = self.content.replace(posterior=posterior, tasks=tasks, task=task or "")
        self._redraw(content, label=True)

    def update_observation(
        self,
        observed_until_s: float,
        *,
        hand_path: np.ndarray | None = None,
        hand_t_s: np.ndarray | None = None,
        hand_observed_index: int | None = None,
    ) -> None:
        """New end of the observed window in [s] (and optionally a new/extended hand path)."""
        changes: dict[str, Any] = {
            "observed_until_s": observed_until_s,
            "hand_observed_index": hand_observed_index,
        }
        if hand_path is not None:
            changes.update(hand_path=hand_path, hand_t_s=hand_t_s)
        self._redraw(self.content.replace(**changes), human=True, animation=hand_path is not None)

    def update_prediction(
        self,
        t_s: np.ndarray,
        q: np.ndarray,
        *,
        ee_mean: np.ndarray | None = None,
        ee_samples: np.ndarray | None = None,
        ee_std: np.ndarray | None = None,
        handover_point: np.ndarray | None = None,
    ) -> None:
        """New predicted robot trajectory (N,) [s], (N, J) [rad] and end-effector path (M, 3) [m]."""
        content = self.content.replace(
            t_s=t_s,
            q=q,
            ee_mean=ee_mean,
            ee_samples=ee_samples,
            ee_std=ee_std,
            handover_point=self.content.handover_point if handover_point is None else handover_point,
        )
        self._redraw(content, prediction=True, animation=True, human=True)

    def update_feasibility(
        self,
        feasibility: Sequence[FeasibilityCheck | tuple],
        *,
        collision_links: Sequence[str] = (),
        near_limit_joints: Sequence[str] = (),
    ) -> None:
        """New feasibility results; recolours the robot's failing links."""
        content = self.content.replace(
            feasibility=feasibility, collision_links=collision_links, near_limit_joints=near_limit_joints
        )
        self._redraw(content, paint=True)


def serve_preview(
    content: PreviewContent,
    *,
    port: int = 7000,
    max_triangles: int = DEFAULT_MAX_TRIANGLES,
    duration_s: float | None = None,
    print_fn: Any = print,
) -> None:
    """Serve ``content`` on 127.0.0.1 and print the URL; blocks until Ctrl-C (or ``duration_s``)."""
    with LivePreview(content, port=port, max_triangles=max_triangles) as live:
        print_fn(f"Preview at {live.url} (Ctrl-C to stop)")
        try:
            if duration_s is None:
                while True:
                    time.sleep(1.0)
            else:
                time.sleep(duration_s)
        except KeyboardInterrupt:
            pass
