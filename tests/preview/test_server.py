"""The live preview server (ipromp_pin.preview.server): local Host names only, quiet websocket disconnects."""

from __future__ import annotations

import http.client
import logging
import socket
import time

import numpy as np
import pytest

from ipromp_pin.robot import load_robot


@pytest.fixture(scope="module")
def live():
    from ipromp_pin.preview import LivePreview, PreviewContent

    robot = load_robot("baxter_left")
    q = np.tile([0.0, -0.5, 0.0, 1.0, 0.0, 0.5, 0.0], (5, 1))
    content = PreviewContent(
        model=robot.model, visual_model=None, collision_model=robot.collision_model, t_s=np.arange(5) * 0.1,
        q=q, joint_names=robot.joint_names, q_full=robot.full_configuration(q[0]), ee_mean=np.zeros((5, 3)),
        task="a", tasks=["a", "b"], posterior=np.array([0.5, 0.5]),
    )  # fmt: skip
    server = LivePreview(content, port=0)
    yield server
    server.close()


@pytest.mark.parametrize(
    ("host", "allowed"),
    [
        ("localhost", True),
        ("127.0.0.1", True),
        ("LOCALHOST:{port}", True),
        ("127.0.0.1:{port}", True),
        ("evil.example.com", False),
        ("attacker.test:{port}", False),
        ("127.0.0.1.nip.io:{port}", False),
        ("localhost.evil.com", False),
        ("", False),
    ],
)
def test_live_preview_answers_local_host_names_only(live, host, allowed):
    for path in ("/", "/ws"):
        conn = http.client.HTTPConnection("127.0.0.1", live.port, timeout=5)
        conn.putrequest("GET", path, skip_host=True)
        conn.putheader("Host", host.format(port=live.port))
        conn.endheaders()
        status = conn.getresponse().status
        conn.close()
        if path == "/":
            assert (status == 200) == allowed, (host, status)
        else:  # a plain GET of the websocket: refused by the Host check, else by the missing upgrade
            assert status == 403 if not allowed else status == 400


def test_abrupt_websocket_disconnects_are_quiet(live, capfd, caplog):
    caplog.set_level(logging.DEBUG)
    for _ in range(5):
        s = socket.create_connection(("127.0.0.1", live.port))
        s.sendall(
            (
                f"GET /ws HTTP/1.1\r\nHost: 127.0.0.1:{live.port}\r\nUpgrade: websocket\r\n"
                "Connection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
                "Sec-WebSocket-Version: 13\r\n\r\n"
            ).encode()
        )
        s.recv(10)
        s.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, b"\x01\x00\x00\x00\x00\x00\x00\x00")
        s.close()  # a reset in the middle of the scene transfer
    time.sleep(0.3)
    for p in (0.3, 0.6, 0.9):
        live.update_posterior(np.array([p, 1 - p]))
    time.sleep(0.5)
    err = capfd.readouterr().err + "\n".join(r.getMessage() + str(r.exc_info or "") for r in caplog.records)
    assert "Traceback" not in err and "WebSocketClosedError" not in err and "StreamClosedError" not in err
    assert live.n_clients == 0


def test_a_page_is_waited_for_until_it_has_the_whole_scene(live):
    import asyncio

    import tornado.websocket
    import umsgpack

    from ipromp_pin.preview import LivePreview

    server = LivePreview(live.content, port=0)
    try:
        assert not server.wait_for_page(0.2)  # nobody connected yet

        async def read_scene() -> int:
            ws = await tornado.websocket.websocket_connect(f"ws://127.0.0.1:{server.port}/ws")
            n = 0
            while True:
                msg = await ws.read_message()
                assert msg is not None
                n += 1
                if umsgpack.unpackb(msg).get("type") == "ipromp_synced":
                    ws.close()
                    return n

        n = asyncio.run(read_scene())
        assert n == len(server.commands()) + 1 and server.wait_for_page(5.0)
    finally:
        server.close()


def test_closing_with_messages_still_queued_leaves_no_write_unawaited(live, caplog):
    import asyncio
    import gc
    import threading
    import warnings

    import tornado.websocket

    from ipromp_pin.preview import LivePreview

    server = LivePreview(live.content, port=0)
    connected, done = threading.Event(), threading.Event()

    async def stay_connected() -> None:  # a page that connects and then just stays there
        ws = await tornado.websocket.websocket_connect(f"ws://127.0.0.1:{server.port}/ws")
        connected.set()
        while not done.is_set():
            await asyncio.sleep(0.01)
        ws.close()

    page = threading.Thread(target=asyncio.run, args=(stay_connected(),), daemon=True)
    page.start()
    try:
        assert connected.wait(10.0) and server.wait_for_page(10.0)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            for _ in range(50):  # updates queued on the server's loop, then the server closed at once
                server._forward(b"\x80")
            server.close()
            gc.collect()
        unawaited = [str(w.message) for w in caught if "never awaited" in str(w.message)]
        assert not unawaited, unawaited
        assert "Task was destroyed but it is pending" not in caplog.text
    finally:
        done.set()
        server.close()
        page.join(10.0)
