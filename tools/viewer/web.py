"""The operator's page over HTTP: static assets from the package and the latest state.

Every browser pulls at its own pace and always gets the newest state: ``/api/state?after=V``
waits (up to ``LONG_POLL_S``) until the state is newer than version ``V`` and returns it.
With ``&image=S`` the reply also carries the newest camera image (``jpeg``, base64) when it
is not image ``S``, so the page needs one request per refresh, not two. ``/api/image.jpg``
returns the newest camera image on its own, ``/api/map`` the robot's static map (its walls as
runs of cells; the state names its version). Nothing is queued per browser, so a slow
browser skips states instead of falling behind. The server is the standard
library's threading HTTP server, bound to one address; the page needs no internet.
"""

from __future__ import annotations

import base64
import json
import logging
import threading
import time
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources
from typing import Any
from urllib.parse import parse_qs, urlsplit

__all__ = ["LONG_POLL_S", "LatestState", "WebServer"]

log = logging.getLogger(__name__)

LONG_POLL_S = 10.0
_TYPES = {".html": "text/html; charset=utf-8", ".js": "text/javascript; charset=utf-8",
          ".css": "text/css; charset=utf-8", ".svg": "image/svg+xml"}


class LatestState:
    """The newest page state (JSON) and camera image (JPEG), with a version to wait on."""

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self.version = 0
        self._state = b"{}"
        self._image: bytes | None = None
        self._image_seq: int | None = None
        self._image_b64: bytes = b""
        #: monotonic s of the last request from a browser (state or image): someone watches
        self.watched_at = 0.0
        self.closed = False
        self._map = b"null"

    def set_state(self, state: dict[str, Any]) -> None:
        with self._cond:
            self.version += 1
            state["version"] = self.version
            self._state = json.dumps(state, separators=(",", ":")).encode()
            self._cond.notify_all()

    def set_image(self, jpeg: bytes, seq: int | None = None) -> None:
        """The newest camera image; ``seq`` is the frame's sequence number, named in the state."""
        b64 = base64.b64encode(jpeg)
        with self._cond:
            self._image, self._image_seq, self._image_b64 = jpeg, seq, b64

    def set_map(self, static_map: dict[str, Any]) -> None:
        """The robot's static map as the page draws it (``/api/map``); the state names its version."""
        body = json.dumps(static_map, separators=(",", ":")).encode()
        with self._cond:
            self._map = body

    def static_map(self) -> bytes:
        with self._cond:
            return self._map

    def image(self) -> bytes | None:
        self.watched_at = time.monotonic()
        with self._cond:
            return self._image

    def wait_state(self, after: int, timeout: float, have_image: int | None = None) -> bytes:
        """The state once its version is above ``after`` (or at ``timeout``, or on close).

        With ``have_image`` (the seq of the image the browser shows), the newest image is
        added as ``"jpeg"`` (base64) when it is another one.
        """
        self.watched_at = time.monotonic()
        with self._cond:
            self._cond.wait_for(lambda: self.version > after or self.closed, timeout)
            state, seq, b64 = self._state, self._image_seq, self._image_b64
        if have_image is None or seq is None or seq == have_image or not b64 or not state.endswith(b"}"):
            return state
        sep = b"," if len(state) > 2 else b""
        return state[:-1] + sep + b'"jpeg":"' + b64 + b'"}'

    def close(self) -> None:
        with self._cond:
            self.closed = True
            self._cond.notify_all()


def _asset(name: str) -> bytes | None:
    if not name or "/" in name or name.startswith("."):
        return None
    path = resources.files("tools.viewer").joinpath("static", name)
    return path.read_bytes() if path.is_file() else None


class _Handler(BaseHTTPRequestHandler):
    server: _Server
    protocol_version = "HTTP/1.1"

    def log_message(self, format: str, *args: Any) -> None:  # noqa: A002 - the base class's name
        log.debug("%s " + format, self.address_string(), *args)

    def _send(self, status: HTTPStatus, body: bytes, content_type: str) -> None:
        self.send_response(status)
        self.send_header("Content-Type", content_type)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(body)

    def do_HEAD(self) -> None:  # noqa: N802 - http.server's naming
        self.do_GET()

    def do_GET(self) -> None:  # noqa: N802 - http.server's naming
        url = urlsplit(self.path)
        state = self.server.state
        if url.path == "/api/state":
            query = parse_qs(url.query)
            try:
                after = int(query.get("after", ["0"])[0])
                have_image = int(query["image"][0]) if "image" in query else None
            except ValueError:
                self._send(HTTPStatus.BAD_REQUEST, b"after and image must be integers", "text/plain")
                return
            self._send(HTTPStatus.OK, state.wait_state(after, LONG_POLL_S, have_image), "application/json")
        elif url.path == "/api/map":
            self._send(HTTPStatus.OK, state.static_map(), "application/json")
        elif url.path == "/api/image.jpg":
            jpeg = state.image()
            if jpeg is None:
                self._send(HTTPStatus.NO_CONTENT, b"", "text/plain")
            else:
                self._send(HTTPStatus.OK, jpeg, "image/jpeg")
        else:
            if url.path in ("/", "/index.html"):
                name = "index.html"
            else:
                name = url.path.removeprefix("/static/") if url.path.startswith("/static/") else ""
            body = _asset(name)
            if body is None:
                self._send(HTTPStatus.NOT_FOUND, b"not found", "text/plain")
            else:
                suffix = name[name.rfind("."):]
                self._send(HTTPStatus.OK, body, _TYPES.get(suffix, "application/octet-stream"))


class _Server(ThreadingHTTPServer):
    daemon_threads = True
    allow_reuse_address = True

    def __init__(self, address: tuple[str, int], state: LatestState) -> None:
        self.state = state
        super().__init__(address, _Handler)


class WebServer:
    """The page's HTTP server, bound at construction (a busy port fails at once), served
    from a background thread after :meth:`start`."""

    def __init__(self, host: str, port: int, state: LatestState) -> None:
        self.state = state
        try:
            self._server = _Server((host, port), state)
        except OSError as exc:
            raise ValueError(f"cannot serve the page on {host}:{port}: {exc.strerror or exc}") from exc
        self._thread: threading.Thread | None = None

    @property
    def url(self) -> str:
        host, port = self._server.server_address[:2]
        return f"http://{host}:{port}/"

    def start(self) -> None:
        self._thread = threading.Thread(target=self._server.serve_forever, name="viewer-http", daemon=True)
        self._thread.start()

    def close(self) -> None:
        self.state.close()
        if self._thread is not None:
            self._server.shutdown()
            self._thread.join(timeout=5.0)
        self._server.server_close()
