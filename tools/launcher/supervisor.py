"""Run processes as supervised children: prefixed output, restart with backoff, clean stop.

Each child runs in its own session (``setsid``), so its process group holds it and
everything it spawns. Stopping a child signals the whole group; a child that exits on its
own has its group SIGKILLed at once, so no grandchild outlives it.

A child that exits with a status in its ``no_restart_status`` (2 by default: the
``perception`` commands' configuration or start-up error, systemd's
``RestartPreventExitStatus``) is never restarted, whatever its policy: the supervisor says
once which child stopped and its error line, and tells ``on_failed``.

One thread does everything: a ``selectors`` loop over the children's merged
stdout/stderr pipes and a wake-up socket that SIGINT/SIGTERM/SIGCHLD write to.
"""

from __future__ import annotations

import logging
import os
import re
import selectors
import signal
import socket
import subprocess
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import IO, BinaryIO, Literal

__all__ = ["BackoffState", "FailedChild", "ProcessSpec", "Supervisor", "describe_exit", "error_line", "should_restart"]

log = logging.getLogger(__name__)

RestartPolicy = Literal["always", "on-failure", "never"]
_COLOURS = (36, 33, 35, 32, 34, 31, 96, 93, 95, 92, 94, 91)
_MAX_LINE = 64 * 1024
#: Output lines kept per child, to say why it stopped.
_TAIL_LINES = 20
#: Exit status of a configuration or start-up error (common/runtime/node.py): restarting cannot help.
CONFIG_ERROR_STATUS = 2
_ANSI = re.compile(r"\x1b\[[0-9;?]*[A-Za-z]")
_ERROR_MARK = "perception: error:"


@dataclass(frozen=True)
class ProcessSpec:
    """What to run and how to supervise it."""

    name: str
    argv: Sequence[str]
    env: Mapping[str, str]
    restart: RestartPolicy = "on-failure"
    backoff_initial_s: float = 0.5
    backoff_max_s: float = 30.0
    stable_after_s: float = 10.0
    stop_timeout_s: float = 10.0
    stop_last: bool = False
    ready_tcp: tuple[str, int] | None = None
    ready_timeout_s: float = 20.0
    #: Exit statuses after which the child is never restarted, whatever ``restart`` says.
    no_restart_status: tuple[int, ...] = (CONFIG_ERROR_STATUS,)


@dataclass(frozen=True)
class FailedChild:
    """A child that stopped with a status in its ``no_restart_status`` and stays stopped."""

    name: str
    pid: int
    returncode: int
    error: str
    run_s: float


def describe_exit(returncode: int) -> str:
    """``exit status 3`` or ``killed by SIGKILL``."""
    if returncode < 0:
        try:
            return f"killed by {signal.Signals(-returncode).name}"
        except ValueError:
            return f"killed by signal {-returncode}"
    return f"exit status {returncode}"


def should_restart(policy: RestartPolicy, returncode: int, no_restart: Sequence[int] = (CONFIG_ERROR_STATUS,)) -> bool:
    """Whether a child that exited with ``returncode`` is started again (never for a status in ``no_restart``)."""
    if returncode in no_restart:
        return False
    return policy == "always" or (policy == "on-failure" and returncode != 0)


def error_line(lines: Sequence[str]) -> str:
    """Why a child stopped, from its last output ``lines``: its last ``perception: error:``
    message (with the lines that continue it), else its last line."""
    for i in range(len(lines) - 1, -1, -1):
        if lines[i].startswith(_ERROR_MARK):
            return " ".join(line.strip() for line in lines[i:])
    return lines[-1].strip() if lines else ""


class BackoffState:
    """Exponential restart delay: initial, x2 per consecutive crash, capped; reset by a stable run."""

    def __init__(self, initial_s: float, max_s: float, stable_after_s: float) -> None:
        self.initial_s, self.max_s, self.stable_after_s = initial_s, max_s, stable_after_s
        self._next = initial_s

    def on_exit(self, run_s: float) -> float:
        """The delay before the next start, for a run that lasted ``run_s`` seconds."""
        if run_s >= self.stable_after_s:
            self._next = self.initial_s
        delay = self._next
        self._next = min(self._next * 2.0, self.max_s)
        return delay


@dataclass
class _Child:
    spec: ProcessSpec
    prefix: bytes
    backoff: BackoffState
    proc: subprocess.Popen[bytes] | None = None
    started_at: float = 0.0
    next_start: float | None = None
    restarts: int = 0
    last_rc: int | None = None
    term_at: float | None = None
    pid: int = 0
    buf: bytearray = field(default_factory=bytearray)
    tail: deque[str] = field(default_factory=lambda: deque(maxlen=_TAIL_LINES))

    @property
    def running(self) -> bool:
        return self.proc is not None


def _port_open(host: str, port: int) -> bool:
    try:
        with socket.create_connection((host, port), timeout=0.2):
            return True
    except OSError:
        return False


def _has_exited(proc: subprocess.Popen[bytes]) -> bool:
    """Whether ``proc`` has exited, without reaping it: while it is a zombie its pid, and so
    its process group id, cannot be reused, which makes signalling the group afterwards safe."""
    if proc.returncode is not None:
        return True
    try:
        return os.waitid(os.P_PID, proc.pid, os.WEXITED | os.WNOHANG | os.WNOWAIT) is not None
    except ChildProcessError:
        return True


def _signal_group(proc: subprocess.Popen[bytes], sig: signal.Signals) -> None:
    try:
        os.killpg(proc.pid, sig)
    except (ProcessLookupError, PermissionError):
        pass  # the group is already empty


class Supervisor:
    """Start ``specs`` in order, keep them running per their policy, stop them on request.

    ``run()`` returns 0 after a requested stop (signal or :meth:`request_stop`) or when
    every child finished with status 0; 1 if a child that was not restarted failed, or a
    child with ``ready_tcp`` did not come up. ``on_failed`` is called (on the supervisor's
    thread) for each child that stops with a status in its ``no_restart_status``;
    ``before_last`` once when stopping, after the other children and before those stopped
    last (the router), e.g. to close a session that goes through that router.
    """

    def __init__(self, specs: Sequence[ProcessSpec], out: BinaryIO, *, colour: bool = False,
                 handle_signals: bool = True, tick_s: float = 0.2,
                 on_failed: Callable[[FailedChild], None] | None = None,
                 before_last: Callable[[], None] | None = None) -> None:
        width = max((len(s.name) for s in specs), default=0) + 2
        self._children = []
        for i, s in enumerate(specs):
            tag = f"[{s.name}]".ljust(width).encode() + b" "
            if colour:
                tag = f"\x1b[{_COLOURS[i % len(_COLOURS)]}m".encode() + tag + b"\x1b[0m"
            self._children.append(_Child(s, tag, BackoffState(s.backoff_initial_s, s.backoff_max_s, s.stable_after_s)))
        self._out = out
        self._out_broken = False
        self._handle_signals = handle_signals
        self._tick_s = tick_s
        self._sel = selectors.DefaultSelector()
        self._wake_r, self._wake_w = socket.socketpair()
        self._wake_r.setblocking(False)
        self._wake_w.setblocking(False)
        self._sel.register(self._wake_r, selectors.EVENT_READ, None)
        self._stop_requests = 0
        self._lock = threading.Lock()
        self._on_failed = on_failed
        self._before_last = before_last
        #: Children stopped for good (a status in their ``no_restart_status``), in order.
        self.failed: list[FailedChild] = []

    # -- public -------------------------------------------------------------------------
    def request_stop(self) -> None:
        """Ask ``run()`` to stop everything (a second call SIGKILLs what is still running)."""
        with self._lock:
            self._stop_requests += 1
        try:
            self._wake_w.send(b"\0")
        except OSError:
            pass  # the loop is already awake or gone

    def restarts(self, name: str) -> int:
        return next(c.restarts for c in self._children if c.spec.name == name)

    def pid(self, name: str) -> int | None:
        """The pid of child ``name`` while it runs, else None."""
        child = next(c for c in self._children if c.spec.name == name)
        return child.pid if child.running else None

    def run(self) -> int:
        with self._signals():
            code = 1
            try:
                if self._start_all():
                    code = self._supervise()
                else:
                    code = 0 if self._stop_requests else 1
            finally:
                self._stop_all()
                self._sel.close()
                self._wake_r.close()
                self._wake_w.close()
        log.info("all processes stopped")
        return code

    # -- phases -------------------------------------------------------------------------
    def _start_all(self) -> bool:
        for child in self._children:
            if self._stop_requests:
                return False
            if child.spec.ready_tcp is not None and _port_open(*child.spec.ready_tcp):
                host, port = child.spec.ready_tcp
                log.error("something already accepts connections on %s:%d (another router?); not starting %s "
                          "or anything after it", host, port, child.spec.name)
                return False
            self._spawn(child)
            if child.spec.ready_tcp is not None and not self._wait_ready(child):
                return False
        return True

    def _wait_ready(self, child: _Child) -> bool:
        host, port = child.spec.ready_tcp  # type: ignore[misc]
        deadline = time.monotonic() + child.spec.ready_timeout_s
        while not self._stop_requests:
            if child.proc is None or _has_exited(child.proc):
                rc = self._reap(child) if child.proc is not None else child.last_rc or 127
                log.error("%s exited during start-up (%s); not starting the others", child.spec.name, describe_exit(rc))
                return False
            if _port_open(host, port):
                log.info("%s is ready on %s:%d", child.spec.name, host, port)
                return True
            if time.monotonic() > deadline:
                log.error("%s did not accept connections on %s:%d within %g s; not starting the others",
                          child.spec.name, host, port, child.spec.ready_timeout_s)
                return False
            self._pump(0.05)
        return False

    def _supervise(self) -> int:
        while not self._stop_requests:
            now = time.monotonic()
            due = [c.next_start for c in self._children if c.next_start is not None]
            self._pump(max(0.0, min([self._tick_s, *(d - now for d in due)])))
            now = time.monotonic()
            for child in self._children:
                if child.proc is not None and _has_exited(child.proc):
                    self._on_exit(child, now)
                if child.next_start is not None and now >= child.next_start and not self._stop_requests:
                    child.restarts += 1
                    self._spawn(child)
            if all(c.proc is None and c.next_start is None for c in self._children):
                failed = [c.spec.name for c in self._children if c.last_rc != 0]
                log.info("every process has finished%s", f"; failed: {', '.join(failed)}" if failed else "")
                return 1 if failed else 0
        return 0

    def _stop_all(self) -> None:
        for c in self._children:
            c.next_start = None
        first = [c for c in self._children if not c.spec.stop_last]
        last = [c for c in self._children if c.spec.stop_last]
        for phase in (first, last):
            if phase is last and self._before_last is not None:
                self._before_last()
            for child in reversed(phase):
                if child.proc is not None and child.term_at is None:
                    log.info("stopping %s (SIGTERM to pid %d and its group)", child.spec.name, child.proc.pid)
                    _signal_group(child.proc, signal.SIGTERM)
                    child.term_at = time.monotonic()
            while any(c.proc is not None for c in phase):
                self._pump(0.05)
                now = time.monotonic()
                for child in phase:
                    if child.proc is None:
                        continue
                    if _has_exited(child.proc):
                        self._on_exit(child, now)
                    elif self._stop_requests > 1 or now - (child.term_at or now) > child.spec.stop_timeout_s:
                        log.warning("%s did not stop after SIGTERM; sending SIGKILL", child.spec.name)
                        _signal_group(child.proc, signal.SIGKILL)
                        child.proc.wait()
                        self._on_exit(child, now)

    # -- children -----------------------------------------------------------------------
    def _spawn(self, child: _Child) -> None:
        child.next_start = None
        child.term_at = None
        s = child.spec
        try:
            proc = subprocess.Popen(list(s.argv), stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                    stderr=subprocess.STDOUT, env=dict(s.env), start_new_session=True)
        except OSError as exc:
            log.error("cannot start %s: %s", s.name, exc)
            child.last_rc = 127
            self._schedule(child, 0.0, 127)
            return
        assert proc.stdout is not None
        os.set_blocking(proc.stdout.fileno(), False)
        self._sel.register(proc.stdout, selectors.EVENT_READ, child)
        child.proc, child.started_at, child.pid = proc, time.monotonic(), proc.pid
        child.tail.clear()
        log.info("started %s (pid %d)%s", s.name, proc.pid, f", restart #{child.restarts}" if child.restarts else "")

    def _reap(self, child: _Child) -> int:
        """Collect an exited child: its status, what is left in its group and its pipe."""
        proc = child.proc
        assert proc is not None
        _signal_group(proc, signal.SIGKILL)  # whatever it left behind in its group (it is a zombie now)
        rc = proc.wait()
        if proc.stdout is not None and not proc.stdout.closed:
            self._read(proc.stdout, child, final=True)
        child.proc, child.last_rc = None, rc
        return rc

    def _on_exit(self, child: _Child, now: float) -> None:
        rc = self._reap(child)
        run_s = now - child.started_at
        if child.term_at is not None:
            log.info("%s stopped (%s)", child.spec.name, describe_exit(rc))
            return
        self._schedule(child, run_s, rc)

    def _schedule(self, child: _Child, run_s: float, rc: int) -> None:
        name, policy = child.spec.name, child.spec.restart
        if rc in child.spec.no_restart_status and not self._stop_requests:
            self._give_up(child, run_s, rc)
            return
        if self._stop_requests or not should_restart(policy, rc, child.spec.no_restart_status):
            level = logging.INFO if rc == 0 else logging.ERROR
            log.log(level, "%s exited (%s) after %.1f s; not restarted (restart: %s)", name, describe_exit(rc), run_s, policy)
            return
        delay = child.backoff.on_exit(run_s)
        child.next_start = time.monotonic() + delay
        log.warning("%s exited (%s) after %.1f s; restart #%d in %.2f s", name, describe_exit(rc), run_s,
                    child.restarts + 1, delay)

    def _give_up(self, child: _Child, run_s: float, rc: int) -> None:
        """Say once, plainly, that ``child`` stopped for good and why."""
        failed = FailedChild(child.spec.name, child.pid, rc, error_line(list(child.tail)), run_s)
        self.failed.append(failed)
        log.error("%s stopped after %.1f s and is NOT restarted: %s means a configuration or start-up error, "
                  "which a restart cannot fix. Its error: %s. Fix it, then start the launcher again.",
                  failed.name, run_s, describe_exit(rc), failed.error or "(it printed nothing)")
        if self._on_failed is not None:
            self._on_failed(failed)

    # -- output -------------------------------------------------------------------------
    def _pump(self, timeout: float) -> None:
        for key, _ in self._sel.select(timeout):
            if key.data is None:
                try:
                    while self._wake_r.recv(4096):
                        pass
                except BlockingIOError:
                    pass
            else:
                self._read(key.fileobj, key.data, final=False)  # type: ignore[arg-type]

    def _read(self, pipe: IO[bytes], child: _Child, *, final: bool) -> None:
        fd = pipe.fileno()
        eof = False
        while True:
            try:
                data = os.read(fd, 65536)
            except BlockingIOError:
                break
            if not data:
                eof = True
                break
            child.buf += data
            self._emit(child, final=False)
            if not final:
                break
        if eof or final:
            self._emit(child, final=True)
            self._sel.unregister(pipe)
            pipe.close()

    def _emit(self, child: _Child, *, final: bool) -> None:
        buf = child.buf
        end = buf.rfind(b"\n") + 1
        if final and len(buf) > end:
            buf += b"\n"
            end = len(buf)
        elif end == 0 and len(buf) > _MAX_LINE:
            buf += b"\n"
            end = len(buf)
        if end == 0:
            return
        lines = bytes(buf[:end]).splitlines(keepends=True)
        del buf[:end]
        for line in lines:
            text = _ANSI.sub("", line.decode(errors="replace")).rstrip()
            if text:
                child.tail.append(text)
        if self._out_broken:
            return
        try:
            self._out.write(b"".join(child.prefix + line for line in lines))
            self._out.flush()
        except (BrokenPipeError, ValueError):
            # Whoever read our output has gone (e.g. `| head`): keep supervising, drop output.
            self._out_broken = True
            log.warning("output stream closed; children's output is discarded from now on")

    # -- signals ------------------------------------------------------------------------
    @contextmanager
    def _signals(self) -> Iterator[None]:
        if not self._handle_signals or threading.current_thread() is not threading.main_thread():
            yield
            return

        def on_signal(signum: int, _frame: object) -> None:
            self._stop_requests += 1

        previous = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)}
        previous[signal.SIGCHLD] = signal.signal(signal.SIGCHLD, lambda *_: None)
        old_fd = signal.set_wakeup_fd(self._wake_w.fileno(), warn_on_full_buffer=False)
        try:
            yield
        finally:
            signal.set_wakeup_fd(old_fd)
            for s, handler in previous.items():
                signal.signal(s, handler)
