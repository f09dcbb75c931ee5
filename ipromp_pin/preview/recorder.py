"""Recording of a meshcat scene: a stand-in viewer window that keeps the commands it receives.

``meshcat.Visualizer(window=SceneRecorder())`` sends every command (set_object, set_transform,
set_property, set_animation, delete) to :meth:`SceneRecorder.send` instead of meshcat's ZMQ server.
The recorder keeps the scene tree like that server does, so that :meth:`SceneRecorder.commands`
replays the whole current scene as a list of msgpack messages (what an offline page embeds and what
a newly connected live page receives), and forwards every new command to a listener (the live
server). It also carries the HTML panel's state as one ``ipromp_overlay`` message.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from typing import Any

import msgpack
import umsgpack

__all__ = ["SceneRecorder", "packb"]


def _ext(value: object) -> msgpack.ExtType:
    if isinstance(value, umsgpack.Ext):
        return msgpack.ExtType(value.type, value.data)
    raise TypeError(f"cannot pack {type(value).__name__}")


def packb(data: Any) -> bytes:
    """``data`` as meshcat's own packing (``umsgpack.packb``) gives it, byte for byte (its typed
    arrays are ``umsgpack.Ext`` values), with the compiled ``msgpack`` (umsgpack is pure Python: the
    packing of an animation was a large part of writing a preview)."""
    return msgpack.packb(data, default=_ext, use_bin_type=True)


class _Node(dict):
    """Node of the scene tree: children by name, plus the latest packed command of each kind."""

    __slots__ = ("object", "transform", "properties", "animation")

    def __init__(self) -> None:
        super().__init__()
        self.object: bytes | None = None
        self.transform: bytes | None = None
        self.properties: dict[str, bytes] = {}
        self.animation: bytes | None = None


def _walk(node: _Node) -> Iterator[_Node]:
    """Depth-first walk of the tree, parents before children, children in insertion order."""
    yield node
    for child in node.values():
        yield from _walk(child)


class SceneRecorder:
    """Stand-in for meshcat's ``ViewerWindow``: keeps the scene tree and forwards new commands.

    ``send`` is what ``meshcat.Visualizer`` calls for every command. The tree mirrors what
    meshcat's ZMQ server keeps, so that :meth:`commands` replays the whole scene.

    Attributes:
        root: Root of the scene tree (children by path component); also holds the animation.
        overlay: Latest packed ``ipromp_overlay`` message (HTML panel state), or ``None``.
        lock: Re-entrant lock guarding the tree; hold it to read :meth:`commands` and register a
            client atomically.
        listener: Callable receiving every new packed command (and overlay), or ``None``.
    """

    def __init__(self) -> None:
        self.root = _Node()
        self.overlay: bytes | None = None
        self.lock = threading.RLock()
        self.listener: Callable[[bytes], None] | None = None

    def _find(self, path: list[str]) -> _Node:
        node = self.root
        for part in path:
            node = node.setdefault(part, _Node())
        return node

    def send(self, command: Any) -> None:
        """Record one meshcat command (an object with ``lower()``) and forward it to the listener.

        Raises:
            ValueError: A command type meshcat's server would not keep either.
        """
        data = command.lower()
        kind = data["type"]
        packed = packb(data)
        path = [p for p in str(data.get("path", "")).split("/") if p]
        with self.lock:
            if kind == "set_object":
                node = self._find(path)
                node.object = packed
                node.properties = {}
            elif kind == "set_transform":
                self._find(path).transform = packed
            elif kind == "set_property":
                # Keep the latest value of every property (a live preview re-sends them).
                self._find(path).properties[data["property"]] = packed
            elif kind == "set_animation":
                self.root.animation = packed
            elif kind == "delete":
                if path:
                    parent = self._find(path[:-1])
                    parent.pop(path[-1], None)
                else:
                    self.root = _Node()
            else:
                raise ValueError(f"unsupported meshcat command {kind!r}")
            if self.listener is not None:
                self.listener(packed)

    def set_overlay(self, state: dict[str, Any]) -> None:
        """Record the HTML panel's state (JSON-serialisable) and forward it to the listener."""
        packed = packb({"type": "ipromp_overlay", "state": state})
        with self.lock:
            self.overlay = packed
            if self.listener is not None:
                self.listener(packed)

    def commands(self) -> list[bytes]:
        """Every command needed to rebuild the current scene, in order."""
        with self.lock:
            out: list[bytes] = []
            for node in _walk(self.root):
                if node.object is not None:
                    out.append(node.object)
                out.extend(node.properties.values())
                if node.transform is not None:
                    out.append(node.transform)
            if self.root.animation is not None:
                out.append(self.root.animation)
            if self.overlay is not None:
                out.append(self.overlay)
            return out

    def get_image(self) -> None:  # pinocchio checks that the viewer can capture images
        """Not available (there is no renderer): raises :class:`NotImplementedError`."""
        raise NotImplementedError("image capture is not available in a preview")
