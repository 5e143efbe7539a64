"""Run as a script: a router and two client sessions in this process, one 4 KB message from one
client to the other, and print how much shared memory the process mapped for it (KiB of
RssShmem, after minus before). ``ours``: the project's Zenoh config; ``zenoh-default``: the
same with Zenoh's own 3,072 B shared-memory threshold (the control)."""

from __future__ import annotations

import json
import sys
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

import zenoh  # noqa: E402

from common.transport.router_process import free_port  # noqa: E402
from common.transport.zenoh_config import ZenohOptions, build_zenoh_config  # noqa: E402
from tests.helpers.wait import wait_until  # noqa: E402


def shmem_kib() -> int:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("RssShmem:"):
            return int(line.split()[1])
    return 0


def config(opts: ZenohOptions, variant: str) -> zenoh.Config:
    conf = build_zenoh_config(opts)
    if variant == "zenoh-default":
        conf.insert_json5("transport/shared_memory/transport_optimization/message_size_threshold", "3072")
    return conf


def main(variant: str) -> None:
    port = free_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    router = zenoh.open(config(ZenohOptions(mode="router", listen=[endpoint]), variant))
    sub_s = zenoh.open(config(ZenohOptions(connect=[endpoint]), variant))
    pub_s = zenoh.open(config(ZenohOptions(connect=[endpoint]), variant))
    got, small = threading.Event(), threading.Event()
    sub = sub_s.declare_subscriber("probe/x", lambda s: (got if len(s.payload) == 4096 else small).set())
    pub = pub_s.declare_publisher("probe/x")

    def matched() -> bool:  # small ones first, until one arrives: the sessions are up and matched
        pub.put(b"s" * 512)
        return small.wait(0.05)

    wait_until(matched, 30.0, interval=0.0, what="a small message to arrive")
    before = shmem_kib()
    pub.put(b"x" * 4096)
    if not got.wait(5.0):
        raise SystemExit("the 4 KB message did not arrive")
    # not a wait: the same settling time for both before measuring (the default's pool is still being
    # mapped; ours must have mapped nothing by then), as a mapping that never comes cannot be awaited
    time.sleep(0.5)
    print(json.dumps({"variant": variant, "shmem_kib_added": shmem_kib() - before}), flush=True)
    sub.undeclare()
    pub.undeclare()
    for s in (pub_s, sub_s, router):
        s.close()


if __name__ == "__main__":
    main(sys.argv[1])
