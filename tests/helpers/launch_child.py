"""Small child programs for the launcher tests (run as ``python tests/helpers/launch_child.py MODE ...``).

    crash CODE        print 'boom', exit with CODE at once
    config-error      print a two-line 'perception: error:' message to stderr, exit with status 2
    family PIDFILE    start a grandchild, append both pids to PIDFILE, print 'family ready', sleep
    stubborn PIDFILE  ignore SIGTERM, append its pid to PIDFILE, print 'stubborn ready', sleep
    echo WORDS...     print the words and the env var LAUNCH_TEST, exit 0
    touch FILE        create FILE, sleep
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time


def _append_pids(path: str, *pids: int) -> None:
    with open(path, "a") as f:
        f.write("".join(f"{p}\n" for p in pids))


def _sleep_forever() -> None:
    while True:
        time.sleep(3600)  # not a wait: a child that runs until it is stopped


def main(argv: list[str]) -> int:
    mode = argv[0]
    if mode == "crash":
        print("boom", flush=True)
        return int(argv[1])
    if mode == "config-error":
        print("loading settings", flush=True)
        print("perception: error: model file /nowhere/reid.onnx not found\n(fix it in the config)", file=sys.stderr,
              flush=True)
        return 2
    if mode == "family":
        # the grandchild's time.sleep is not a wait: it runs until it is stopped
        grandchild = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(3600)"])
        _append_pids(argv[1], os.getpid(), grandchild.pid)
        print("family ready", flush=True)
        _sleep_forever()
    if mode == "stubborn":
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        _append_pids(argv[1], os.getpid())
        print("stubborn ready", flush=True)
        _sleep_forever()
    if mode == "echo":
        print(" ".join(argv[1:]), os.environ.get("LAUNCH_TEST", "<unset>"), flush=True)
        print("to stderr", file=sys.stderr, flush=True)
        return 0
    if mode == "touch":
        open(argv[1], "w").close()
        _sleep_forever()
    raise SystemExit(f"unknown mode {mode!r}")


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
