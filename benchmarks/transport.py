"""Transport benchmark: codec cost per message type, and 640x480 RGB-D round trip and throughput.

    python benchmarks/transport.py [--frames 300] [--round-trips 200]

Round trips and throughput run between this process and a child process (an echo or a
sink), peer to peer and through a `perception router` child, each with Zenoh's
same-host shared memory on (the default) and off (as between the robot's two PCs).
Every figure is a median (and p99/p95) over repeated runs; compare them as ratios.

--tls compares, through a router with shared memory off (as between the two PCs), plain
TCP with the secure deployment's link: TLS with mutual certificates and a password check
(deploy/secure/, certificates made in a temporary folder). --tls-only runs just that.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import subprocess
import sys
import time
from pathlib import Path

import msgpack
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from common.messages.codec import _pack_default, _packer, decode, encode  # noqa: E402
from common.messages.keys import FRAMES, RELIABLE, Delivery, Keys  # noqa: E402
from common.runtime.progress import progress_bar  # noqa: E402
from common.transport.router_process import RouterProcess, free_port, wait_for_port  # noqa: E402
from common.messages.samples import example_messages, rgbd_frame  # noqa: E402
from common.messages.schemas import Header, Message, RGBDFrame, ServiceStatus  # noqa: E402
from common.transport.zenoh_config import ZenohOptions  # noqa: E402
from common.transport.zenoh import open_transport  # noqa: E402

KEYS = Keys(robot="bench")
PING, PONG, DONE = f"{KEYS.base}/bench/ping", f"{KEYS.base}/bench/pong", f"{KEYS.base}/bench/done"
BULK = Delivery(latest=False, queue=1024, congestion="block")


def pct(values: list[float], q: float) -> float:
    return float(np.percentile(values, q))


def time_codec(msg: Message, n: int) -> tuple[float, float, float, float, int]:
    """Median and p99 of encode and decode in microseconds, and the payload size."""
    data = encode(msg)
    enc, dec = [], []
    for _ in range(n):
        t0 = time.perf_counter()
        data = encode(msg)
        t1 = time.perf_counter()
        decode(type(msg), data)
        t2 = time.perf_counter()
        enc.append((t1 - t0) * 1e6)
        dec.append((t2 - t1) * 1e6)
    return statistics.median(enc), pct(enc, 99), statistics.median(dec), pct(dec, 99), len(data)


def codec_table(n: int) -> None:
    frame = rgbd_frame(640, 480)
    rows = [(f"{type(m).__name__}" + (f" ({m.encoding})" if hasattr(m, "encoding") else ""), m) for m in example_messages()]
    rows.append(("RGBDFrame 640x480 (rgb8 + 16UC1)", frame))
    print(f"\n## Codec (n={n} each; microseconds)\n")
    print("| message | bytes | encode median | encode p99 | decode median | decode p99 |\n|---|---|---|---|---|---|")
    for name, msg in rows:
        em, ep, dm, dp, size = time_codec(msg, n if size_hint(msg) < 100_000 else max(50, n // 10))
        print(f"| {name} | {size:,} | {em:.1f} | {ep:.1f} | {dm:.1f} | {dp:.1f} |")
    # The allocation trap (ZENOH_NOTES): packing the same 1.5 MB body with a fresh packer per
    # frame, against the codec's reused per-thread packer.
    body = {"schema": "x", "version": 1, "body": frame.model_dump()}
    reused_packer = _packer()
    fresh, reused = [], []
    for _ in range(100):
        t0 = time.perf_counter()
        msgpack.Packer(default=_pack_default, use_bin_type=True).pack(body)
        t1 = time.perf_counter()
        reused_packer.pack(body)
        t2 = time.perf_counter()
        fresh.append((t1 - t0) * 1e6)
        reused.append((t2 - t1) * 1e6)
    print(f"\n640x480 RGB-D pack only: fresh msgpack.Packer per frame median {statistics.median(fresh):.0f} us, "
          f"reused packer {statistics.median(reused):.0f} us")


def size_hint(msg: Message) -> int:
    return len(encode(msg))


# ---------------------------------------------------------------- child processes


def child(role: str, opts_json: str) -> int:
    opts = ZenohOptions.model_validate_json(opts_json)
    with open_transport(opts) as t:
        ping = t.subscribe(PING, RGBDFrame, BULK)
        if role == "echo":
            pong = t.publisher(PONG, RGBDFrame, RELIABLE)
            print("READY", flush=True)
            while (r := ping.recv(30)) is not None:
                pong.put(r.msg)
        else:  # sink: count frames until told how many were sent
            done = t.subscribe(DONE, ServiceStatus, RELIABLE)
            ack = t.publisher(PONG, ServiceStatus, RELIABLE)
            print("READY", flush=True)
            got, total, last_ns = 0, None, 0
            while total is None or got < total:
                # Once the total is known, a 2 s silence means the rest was lost.
                r = ping.recv(0.01 if total is None else 2.0)
                if r is not None:
                    got += 1
                    last_ns = r.recv_ns
                elif total is not None:
                    break
                if total is None and (d := done.try_recv()) is not None:
                    total = d.msg.published
            ack.put(ServiceStatus(header=Header(stamp_ns=time.time_ns()), name="sink", received=got,
                                  dropped=ping.stats.dropped, extra={"last_recv_ns": float(last_ns)}))
            ack.wait_for_subscribers(1)
            time.sleep(0.2)  # let the ack leave before the session closes
    return 0


def setup(path: str, shm: bool, router: RouterProcess | None) -> tuple[ZenohOptions, ZenohOptions]:
    """(this process's options, the child's options) for one path."""
    if router is not None:
        via = ZenohOptions(mode="client", connect=[router.endpoint], shared_memory=shm)
        return via, via
    port = free_port()  # the child listens, this process dials it
    listen = ZenohOptions(mode="peer", listen=[f"tcp/127.0.0.1:{port}"], shared_memory=shm)
    dial = ZenohOptions(mode="peer", connect=[f"tcp/127.0.0.1:{port}"], shared_memory=shm)
    return dial, listen


def spawn(role: str, opts: ZenohOptions) -> subprocess.Popen[str]:
    proc = subprocess.Popen([sys.executable, __file__, "--child", role, opts.model_dump_json()],
                            stdout=subprocess.PIPE, text=True, env={**os.environ, "RUST_LOG": "error"})
    assert proc.stdout is not None and "READY" in proc.stdout.readline()
    return proc


def round_trips(local: ZenohOptions, remote: ZenohOptions, n: int) -> list[float]:
    echo = spawn("echo", remote)
    try:
        with open_transport(local) as t:
            pub = t.publisher(PING, RGBDFrame, RELIABLE)
            pong = t.subscribe(PONG, RGBDFrame, BULK)
            pub.wait_for_subscribers(10)
            frame = rgbd_frame(640, 480)
            times = []
            for i in range(n + 10):
                t0 = time.perf_counter()
                pub.put(frame)
                if pong.recv(10) is None:
                    raise RuntimeError("echo did not answer")
                if i >= 10:  # warm-up
                    times.append((time.perf_counter() - t0) * 1e3)
            return times
    finally:
        echo.kill()


def throughput(local: ZenohOptions, remote: ZenohOptions, n: int) -> tuple[float, float, int]:
    sink = spawn("sink", remote)
    try:
        with open_transport(local) as t:
            pub = t.publisher(PING, RGBDFrame, Delivery(latest=False, queue=1, congestion="block"))
            done = t.publisher(DONE, ServiceStatus, RELIABLE)
            ack = t.subscribe(PONG, ServiceStatus, RELIABLE)
            pub.wait_for_subscribers(10)
            frames = [rgbd_frame(640, 480, seq=i) for i in range(4)]
            t0 = time.time_ns()
            for i in range(n):
                pub.put(frames[i % 4])
            done.put(ServiceStatus(header=Header(stamp_ns=0), name="src", published=n))
            got = ack.recv(60)
            if got is None:
                raise RuntimeError("sink did not report")
            # Same host, same clock: from the first put to the sink's last reception.
            elapsed = (got.msg.extra["last_recv_ns"] - t0) / 1e9
            received = got.msg.received
            mb = received * len(encode(frames[0])) / 1e6
            return received / elapsed, mb / elapsed, n - received
    finally:
        sink.kill()


def slow_consumer(seconds: float = 3.0) -> None:
    """ZENOH_NOTES' backpressure case: 100 Hz of 1.5 MB frames, a consumer needing 100 ms each."""
    import resource
    import threading

    print("\n## Slow consumer: 100 Hz of 640x480 RGB-D, 100 ms of work per frame, latest-only delivery\n")
    with RouterProcess() as router:
        opts = ZenohOptions(mode="client", connect=[router.endpoint])
        with open_transport(opts) as a, open_transport(opts) as b:
            sub = b.subscribe(PING, RGBDFrame, FRAMES)
            pub = a.publisher(PING, RGBDFrame, FRAMES)
            pub.wait_for_subscribers(10)
            frame = rgbd_frame(640, 480)
            stop = threading.Event()

            def produce() -> None:
                seq = 0
                while not stop.is_set():
                    seq += 1
                    pub.put(frame.model_copy(update={"header": Header(stamp_ns=time.time_ns(), seq=seq)}))
                    stop.wait(0.01)

            rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
            threading.Thread(target=produce, daemon=True).start()
            stale = []
            deadline = time.monotonic() + seconds
            while time.monotonic() < deadline:
                got = sub.recv(1.0)
                if got is None:
                    continue
                stale.append((time.time_ns() - got.msg.header.stamp_ns) / 1e6)
                time.sleep(0.1)  # the slow model
            stop.set()
            rss1 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    print(f"processed {len(stale)} frames, skipped {sub.stats.dropped} stale ones; age of a frame when work on it "
          f"started: median {statistics.median(stale):.1f} ms, max {max(stale):.1f} ms; peak RSS grew {(rss1 - rss0) / 1024:.0f} MB")


def secure_router(folder: Path) -> tuple[subprocess.Popen[bytes], ZenohOptions]:
    """A router with deploy/secure's TLS, mutual TLS and password check, and a client's options for it.

    No access control: the benchmark's keys are not among the services'.
    """
    import shutil

    from common.transport.certs import make_certs

    secure = Path(__file__).resolve().parent.parent / "deploy" / "secure"
    for name in ("router-single-pc.json5", "client.json5"):
        shutil.copy(secure / name, folder / name)
    make_certs(folder / "certs")
    port = free_port()
    proc = subprocess.Popen([sys.executable, "-m", "perception", "-q", "router", f"--listen=tls/127.0.0.1:{port}",
                             "--config", str(folder / "router-single-pc.json5")],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env={**os.environ, "RUST_LOG": "off"})
    if not wait_for_port("127.0.0.1", port, 20, proc):
        proc.kill()
        raise RuntimeError("the TLS router did not start")
    opts = ZenohOptions(mode="client", connect=[f"tls/127.0.0.1:{port}"], config_file=folder / "client.json5",
                        credentials=folder / "certs" / "credentials" / "monitor.txt", shared_memory=False)
    return proc, opts


def tls_table(n_rt: int, n_frames: int) -> None:
    """Round trip and throughput through a router, plain TCP against TLS (shared memory off)."""
    print("\n## TLS against plain TCP, through a router, shared memory off (640x480 RGB-D frames)\n")
    print("| link | round trip median (ms) | p99 (ms) | throughput (frames/s) | MB/s | lost |\n|---|---|---|---|---|---|")
    links = ("tcp", "tls")
    with progress_bar(len(links), desc="TLS", unit="link") as bar:
        for link in links:
            rt, fps, mbs, lost = _tls_row(link, n_rt, n_frames)
            bar.update()
            print(f"| {link} | {statistics.median(rt):.2f} | {pct(rt, 99):.2f} | {fps:.0f} | {mbs:.0f} | {lost} |",
                  flush=True)


def _tls_row(link: str, n_rt: int, n_frames: int) -> tuple[list[float], float, float, int]:
    """(round trips ms, frames/s, MB/s, lost) through a router with a ``link`` (tcp or tls) connection."""
    import tempfile

    with tempfile.TemporaryDirectory(prefix="perception-tls-bench-") as tmp:
        if link == "tcp":
            router = RouterProcess().start()
            opts = ZenohOptions(mode="client", connect=[router.endpoint], shared_memory=False)
            stop = router.stop
        else:
            proc, opts = secure_router(Path(tmp))
            stop = lambda: (proc.terminate(), proc.wait(10))  # noqa: E731
        try:
            rt = round_trips(opts, opts, n_rt)
            fps, mbs, lost = throughput(opts, opts, n_frames)
        finally:
            stop()
    return rt, fps, mbs, lost


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--child", nargs=2, metavar=("ROLE", "OPTS"), help=argparse.SUPPRESS)
    ap.add_argument("--codec-n", type=int, default=2000, help="codec repetitions per small message")
    ap.add_argument("--round-trips", type=int, default=200)
    ap.add_argument("--frames", type=int, default=300, help="frames per throughput run")
    ap.add_argument("--tls", action="store_true", help="also compare TLS with plain TCP through a router")
    ap.add_argument("--tls-only", action="store_true", help="only the TLS against TCP comparison")
    args = ap.parse_args()
    if args.child:
        return child(*args.child)
    os.environ.setdefault("RUST_LOG", "error")
    if args.tls_only:
        print(f"# Transport benchmark, TLS\n\nmachine: {platform.node()}, {os.cpu_count()} cores, Python {platform.python_version()}")
        tls_table(args.round_trips, args.frames)
        return 0
    print(f"# Transport benchmark\n\nmachine: {platform.node()}, {os.cpu_count()} cores, {platform.processor() or platform.machine()}, "
          f"Python {platform.python_version()}")
    codec_table(args.codec_n)
    slow_consumer()
    print(f"\n## 640x480 RGB-D frame ({len(encode(rgbd_frame(640, 480))) / 1e6:.2f} MB) between two processes\n")
    print("| path | shared memory | round trip median (ms) | p99 (ms) | throughput (frames/s) | MB/s | lost |\n|---|---|---|---|---|---|---|")
    cases = [(shm, path) for shm in (True, False) for path in ("peer to peer", "via router")]
    with progress_bar(len(cases), desc="transport", unit="path") as bar:
        for shm, path in cases:
            router = RouterProcess().start() if path == "via router" else None
            try:
                local, remote = setup(path, shm, router)
                rt = round_trips(local, remote, args.round_trips)
                fps, mbs, lost = throughput(local, remote, args.frames)
            finally:
                if router is not None:
                    router.stop()
            bar.update()
            print(f"| {path} | {'on' if shm else 'off'} | {statistics.median(rt):.2f} | {pct(rt, 99):.2f} | {fps:.0f} | {mbs:.0f} | {lost} |",
                  flush=True)
    if args.tls:
        tls_table(args.round_trips, args.frames)
    return 0


if __name__ == "__main__":
    sys.exit(main())
