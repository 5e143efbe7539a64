"""Headless Chromium driven over the DevTools protocol, for tests and the README's screenshots.

Starts the distribution's ``chromium`` with ``--remote-debugging-port=0``, reads the port
it picked from ``DevToolsActivePort`` in its profile folder, and talks to the page target
over a WebSocket (the ``websockets`` package): evaluate JavaScript, wait for a condition,
take a PNG screenshot.
"""

from __future__ import annotations

import base64
import contextlib
import json
import os
import shutil
import signal
import subprocess
import tempfile
import time
import urllib.request
from pathlib import Path
from typing import Any, Callable

__all__ = ["Browser", "chromium_path"]

_NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")


def chromium_path() -> str | None:
    """The first Chromium-like browser on the PATH, or None."""
    for name in _NAMES:
        if (path := shutil.which(name)) is not None:
            return path
    return None


class Browser:
    """One headless Chromium with one page; use as a context manager."""

    def __init__(self, width: int = 1280, height: int = 900, timeout_s: float = 30.0) -> None:
        path = chromium_path()
        if path is None:
            raise RuntimeError("no Chromium on the PATH")
        self._profile = Path(tempfile.mkdtemp(prefix="perception-chromium-"))
        self._proc = subprocess.Popen(
            [path, "--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
             "--no-first-run", "--no-default-browser-check", "--disable-extensions",
             "--remote-debugging-address=127.0.0.1", "--remote-debugging-port=0", f"--user-data-dir={self._profile}",
             f"--window-size={width},{height}", "about:blank"],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
        self._id = 0
        self._stack = contextlib.ExitStack()
        try:
            port = self._wait_port(timeout_s)
            with urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=5) as res:
                targets = json.loads(res.read())
            page = next(t for t in targets if t.get("type") == "page")
            from websockets.sync.client import connect

            self._ws = self._stack.enter_context(
                connect(page["webSocketDebuggerUrl"], max_size=None, open_timeout=timeout_s))
            self.call("Emulation.setDeviceMetricsOverride", width=width, height=height, deviceScaleFactor=1,
                      mobile=False)
        except BaseException:
            self.close()
            raise

    def _wait_port(self, timeout_s: float) -> int:
        marker = self._profile / "DevToolsActivePort"
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if self._proc.poll() is not None:
                raise RuntimeError(f"chromium exited with status {self._proc.returncode}")
            if marker.is_file() and (text := marker.read_text().split()):
                return int(text[0])
            time.sleep(0.05)  # the poll interval of a deadline poll, not a wait
        raise TimeoutError("chromium did not open its DevTools port")

    def call(self, method: str, timeout_s: float = 30.0, **params: Any) -> dict[str, Any]:
        """Send one DevTools command and return its result (events on the way are skipped)."""
        self._id += 1
        self._ws.send(json.dumps({"id": self._id, "method": method, "params": params}))
        deadline = time.monotonic() + timeout_s
        while True:
            reply = json.loads(self._ws.recv(timeout=max(0.01, deadline - time.monotonic())))
            if reply.get("id") == self._id:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error']}")
                return reply.get("result", {})

    def goto(self, url: str) -> None:
        self.call("Page.navigate", url=url)

    def evaluate(self, expression: str) -> Any:
        """The value of a JavaScript expression in the page (JSON-serialisable values)."""
        result = self.call("Runtime.evaluate", expression=expression, returnByValue=True, awaitPromise=True)
        if "exceptionDetails" in result:
            raise RuntimeError(f"{expression}: {result['exceptionDetails']}")
        return result["result"].get("value")

    def wait_for(self, expression: str, timeout_s: float = 30.0) -> Any:
        """Poll ``expression`` until it is truthy; its value (TimeoutError with the last one)."""
        deadline = time.monotonic() + timeout_s
        value = None
        while time.monotonic() < deadline:
            try:
                value = self.evaluate(expression)
            except RuntimeError:
                value = None  # the page is still loading
            if value:
                return value
            time.sleep(0.1)  # the poll interval of a deadline poll, not a wait
        raise TimeoutError(f"{expression!r} still {value!r} after {timeout_s} s")

    def open_until(self, url: str, expression: str, timeout_s: float = 60.0, retry_s: float = 10.0,
                   alive: Callable[[], bool] = lambda: True) -> Any:
        """Load ``url`` (again every ``retry_s``: a server still starting serves nothing) until
        ``expression`` is truthy; its value. TimeoutError after ``timeout_s``, or as soon as
        ``alive()`` says the server's process ended."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline and alive():
            self.goto(url)
            try:
                return self.wait_for(expression, min(retry_s, max(deadline - time.monotonic(), 0.1)))
            except TimeoutError:
                continue
        raise TimeoutError(f"{expression!r} never held on {url} within {timeout_s} s")

    def screenshot(self) -> bytes:
        """The page as PNG bytes."""
        return base64.b64decode(self.call("Page.captureScreenshot", format="png")["data"])

    def close(self) -> None:
        self._stack.close()
        # Chromium's helper processes (crashpad, utilities) share its process group and may write
        # into the profile after the browser itself has gone: stop them all, then remove it
        for sig in (signal.SIGTERM, signal.SIGKILL):
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.killpg(self._proc.pid, sig)
            try:
                self._proc.wait(5)
                break
            except subprocess.TimeoutExpired:
                continue
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(self._proc.pid, signal.SIGKILL)  # helpers that outlived the browser
        for _ in range(50):  # until nothing writes there any more
            shutil.rmtree(self._profile, ignore_errors=True)
            if not self._profile.exists():
                break
            time.sleep(0.1)  # poll interval, not a wait

    def __enter__(self) -> Browser:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
