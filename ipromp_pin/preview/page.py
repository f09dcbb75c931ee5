"""The HTML page of a preview: meshcat's viewer script, the HTML panel, and the scene or a live link.

One page layout serves both outputs: the offline page (:func:`render_html`, :func:`write_html`)
embeds the recorded scene commands and replays them on load (no network, no server); the live page
(:func:`live_page`) connects to the preview server's websocket instead. The page's CSS and scripts
are package data in ``static/`` (``page.css``; ``overlay.js``, the HTML panel, which also handles
the ``ipromp_overlay`` and ``ipromp_synced`` messages; ``separation.js``, the robot-body
separation at the current time; ``torques.js``, the joints' torque usage at the current time;
``static_loader.js``; ``live_connect.js``),
all inlined into the page after meshcat's own viewer script.
"""

from __future__ import annotations

import base64
import functools
import html
import json
from importlib import resources
from pathlib import Path

import meshcat

from .. import atomic
from .content import PreviewContent, preview_error
from .meshes import DEFAULT_MAX_TRIANGLES
from .recorder import SceneRecorder
from .scene import RobotView, build_scene

__all__ = ["live_page", "recorded_page", "render_html", "write_html"]

_VIEWER_JS_PATH = Path(meshcat.__file__).resolve().parent / "viewer" / "dist" / "main.min.js"


@functools.cache
def _static(name: str) -> str:
    """Text of the package data file ``static/<name>``."""
    return resources.files(__package__).joinpath("static", name).read_text(encoding="utf-8")


def _viewer_js() -> str:
    source = _VIEWER_JS_PATH.read_text(encoding="utf-8")
    return source.replace("</script", "<\\/script")


def _page(title: str, body_js: str, data_script: str = "") -> str:
    """The page: ``data_script`` (HTML) before the scripts, ``body_js`` run after the panel's script."""
    return (
        '<!DOCTYPE html>\n<html>\n<head>\n<meta charset="utf-8">\n'
        f"<title>{html.escape(title)}</title>\n<style>\n{_static('page.css')}</style>\n</head>\n<body>\n"
        '<div id="meshcat-pane"></div>\n<div id="ipromp-overlay"></div>\n'
        f"{data_script}"
        f"<script>\n{_viewer_js()}\n</script>\n"
        '<script>\nvar viewer = new MeshCat.Viewer(document.getElementById("meshcat-pane"));\n\n'
        + "\n\n".join(_static(n) for n in ("overlay.js", "separation.js", "torques.js"))
        + f"\n\n{body_js}\n</script>\n</body>\n</html>\n"
    )


def live_page(title: str) -> str:
    """Page of a live preview: it connects to the websocket ``/ws`` of the server that serves it."""
    return _page(title, _static("live_connect.js"))


def render_html(
    content: PreviewContent, *, max_triangles: int = DEFAULT_MAX_TRIANGLES, fps: float = 30.0
) -> str:
    """Self-contained HTML page (viewer script, scene and panel inline; no network) of ``content``."""
    if fps <= 0:
        raise preview_error("fps", f"must be > 0, got {fps}")
    window = SceneRecorder()
    build_scene(window, content, robot=RobotView(content, max_triangles), fps=fps)
    return recorded_page(window, content.title)


def recorded_page(window: SceneRecorder, title: str, extra_js: str = "", extra_html: str = "") -> str:
    """Self-contained page that replays the scene recorded in ``window`` on load (no network).

    Args:
        window: The recorded scene.
        title: Page title.
        extra_js: Script run after the scene is loaded (e.g. another panel).
        extra_html: HTML placed before the scripts (e.g. a JSON data block, a style sheet).
    """
    encoded = [base64.b64encode(c).decode("ascii") for c in window.commands()]
    data = f'<script type="application/json" id="ipromp-scene">{json.dumps(encoded)}</script>\n'
    body = _static("static_loader.js") + ("\n" + extra_js if extra_js else "")
    return _page(title, body, data + extra_html)


def write_html(
    content: PreviewContent,
    path: str | Path,
    *,
    max_triangles: int = DEFAULT_MAX_TRIANGLES,
    fps: float = 30.0,
) -> Path:
    """Write the offline preview of ``content`` as ONE self-contained HTML file; returns its path.

    The page needs no server and no network: open it in any browser with WebGL. With the default
    ``max_triangles`` Baxter's page is about 3.7 MB (1.4 MB gzipped).
    """
    path = Path(path)
    text = render_html(content, max_triangles=max_triangles, fps=fps)
    return atomic.write_text(path, text)  # a temporary file renamed into place
