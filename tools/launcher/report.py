"""Tell the robot's Zenoh network about launched services that stopped for good.

A service that exits with a configuration or start-up error (exit status 2) is not
restarted (:mod:`tools.launcher.supervisor`), and its liveliness token is gone with it, so
``perception status`` would simply no longer list it. :class:`FailureReport` answers for
it instead: a :class:`ServiceStatus` with ``state="failed"``, the exit status and its error
line, on the key the service itself would have used (``status/{service}/{host}-{pid}``),
published once and served to status queries for as long as the launcher runs.

The Zenoh session is opened on the first failure only, on a thread of its own, so a
launch where nothing fails opens none and an unreachable router never holds up the
supervisor.
"""

from __future__ import annotations

import logging
import queue
import socket
import threading
import time
from collections.abc import Mapping

from common.messages.keys import STATUS, Keys
from common.runtime.service import instance_id, package_version
from common.messages.schemas import Header, ServiceStatus
from common.transport.zenoh_config import ZenohOptions
from common.transport.zenoh import TransportError, ZenohTransport, open_transport
from tools.launcher.supervisor import FailedChild

__all__ = ["FailureReport", "failed_status"]

log = logging.getLogger(__name__)


def failed_status(failed: FailedChild, service: str) -> ServiceStatus:
    """The status a failed child is reported with."""
    return ServiceStatus(
        header=Header(stamp_ns=time.time_ns(), source=service),
        name=service,
        instance=instance_id(failed.pid),
        host=socket.gethostname(),
        pid=failed.pid,
        version=package_version(),
        uptime_s=max(0.0, failed.run_s),
        state="failed",
        error=failed.error,
        exit_status=failed.returncode,
    )


#: How long the report's session waits for the router (the launcher's own router may be gone).
REPORT_CONNECT_S = 3.0


class FailureReport:
    """Serve the status of every failed child over Zenoh; call it with each :class:`FailedChild`.

    ``services`` maps a launch entry's name to the service name it runs under in keys
    (``command: embedder`` -> ``embedder``); entries not in it keep their own name.
    """

    def __init__(self, keys: Keys, options: ZenohOptions, services: Mapping[str, str]) -> None:
        self.keys = keys
        # Bounded, so close() can wait for the session: a thread still inside Zenoh when the
        # interpreter finalizes aborts the launcher ("FATAL: exception not rethrown").
        timeout = options.connect_timeout_s
        self.options = options.model_copy(update={"connect_timeout_s": REPORT_CONNECT_S if timeout < 0
                                                  else min(timeout, REPORT_CONNECT_S)})
        self.services = dict(services)
        self._queue: queue.Queue[ServiceStatus | None] = queue.Queue()
        self._thread: threading.Thread | None = None
        self._statuses: list[ServiceStatus] = []
        self._lock = threading.Lock()

    def __call__(self, failed: FailedChild) -> None:
        self._queue.put(failed_status(failed, self.services.get(failed.name, failed.name)))
        if self._thread is None:
            self._thread = threading.Thread(target=self._serve, name="failure-report", daemon=True)
            self._thread.start()

    @property
    def reported(self) -> list[ServiceStatus]:
        """The statuses served so far."""
        with self._lock:
            return list(self._statuses)

    def _serve(self) -> None:
        try:
            transport: ZenohTransport | None = open_transport(self.options)
        except TransportError as exc:
            log.warning("cannot tell perception status about the stopped service: %s", exc)
            transport = None
        try:
            while (status := self._queue.get()) is not None:
                if transport is None:
                    continue
                key = self.keys.status(status.name, status.instance)
                transport.serve(key, lambda _key, _params, st=status: [st])
                transport.publisher(key, ServiceStatus, STATUS).put(status)
                with self._lock:
                    self._statuses.append(status)
        finally:
            if transport is not None:
                transport.close()

    def close(self) -> None:
        """Withdraw the reports and close the session (if one was opened); again: nothing."""
        if self._thread is not None and self._thread.is_alive():
            self._queue.put(None)
            self._thread.join(timeout=REPORT_CONNECT_S + 10.0)  # opening is bounded; closing is quick
            if self._thread.is_alive():
                log.error("the failure report's Zenoh session did not close")
