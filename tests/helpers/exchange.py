"""Child process for the cross-process tests.

    python -m tests.helpers.exchange sub ENDPOINT OUTFILE   receive one of each example, write them back
    python -m tests.helpers.exchange pub ENDPOINT           publish one of each example
    python -m tests.helpers.exchange service ENDPOINT NAME  run a ServiceRuntime until SIGTERM
"""

from __future__ import annotations

import sys

import msgpack

from common.messages.codec import encode
from common.messages.keys import RELIABLE, Keys
from common.runtime.service import ServiceRuntime, Shutdown
from common.messages.samples import example_messages
from common.messages.schemas import Header, ServiceStatus
from common.transport.zenoh_config import ZenohOptions
from common.transport.zenoh import open_transport

KEYS = Keys(robot="xproc")
ACK = f"{KEYS.base}/exchange_ack"


def main(argv: list[str]) -> int:
    role, endpoint = argv[0], argv[1]
    opts = ZenohOptions(mode="client", connect=[endpoint], connect_timeout_s=10)
    expected = example_messages()
    with Shutdown() as shutdown, open_transport(opts) as t:
        if role == "sub":
            sub = t.subscribe(f"{KEYS.base}/exchange/**", None, RELIABLE)
            print("READY", flush=True)
            got = []
            while len(got) < len(expected):
                r = sub.recv(30.0)
                if r is None:
                    print(f"timed out after {len(got)} messages", file=sys.stderr)
                    return 1
                got.append(encode(r.msg))
            with open(argv[2], "wb") as f:
                f.write(msgpack.packb(got, use_bin_type=True))
            # Tell the publisher everything arrived: closing its session earlier could drop
            # what Zenoh still had queued.
            ack = t.publisher(ACK, ServiceStatus, RELIABLE)
            ack.wait_for_subscribers(30.0)
            ack.put(ServiceStatus(header=Header(stamp_ns=0), name="exchange", received=len(got)))
        elif role == "pub":
            acks = t.subscribe(ACK, ServiceStatus, RELIABLE)
            for i, msg in enumerate(expected):
                pub = t.publisher(f"{KEYS.base}/exchange/{i}", type(msg), RELIABLE)
                if not pub.wait_for_subscribers(30.0):
                    print("no subscriber", file=sys.stderr)
                    return 1
                pub.put(msg)
            if acks.recv(60.0) is None:
                print("the subscriber never confirmed", file=sys.stderr)
                return 1
        elif role == "service":
            with ServiceRuntime(argv[2], t, KEYS, period_s=0.2):
                print("READY", flush=True)
                shutdown.wait()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
