"""Maximum replay throughput of 640x480 RGB-D frames, through a router and peer to peer.

Writes an MCAP recording of N frames (RGB noise + 16-bit depth, ~1.5 MB a frame) the
way ``perception record`` does, then runs ``perception replay --max`` as a real
subprocess while this process subscribes (FIFO, decoding every frame as a service
would) and times the frames from the first to the last arrival.

    .venv/bin/python benchmarks/replay.py [--frames 150] [--runs 3]

Prints frames/s and MB/s (median over runs) and the median and p95 gap between
frames. Shared memory is on, as between processes of one host, except in the row that
turns it off in both processes (payloads then go through the router's TCP links).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from common.messages.keys import Delivery, Keys  # noqa: E402
from common.runtime.progress import Bar, progress_bar  # noqa: E402
from common.transport.router_process import RouterProcess, free_port  # noqa: E402
from common.messages.samples import rgbd_frame  # noqa: E402
from common.transport.base import Subscription  # noqa: E402
from common.transport.zenoh_config import ZenohOptions  # noqa: E402
from common.transport.zenoh import open_transport  # noqa: E402
from tools.replay.recorder import McapRecorder  # noqa: E402

KEYS = Keys()
FIFO = Delivery(latest=False, queue=100_000, congestion="block")


def write_recording(path: Path, frames: int) -> int:
    """N frames 1/30 s apart; returns the payload bytes of one frame."""
    distinct = [rgbd_frame(640, 480, seq=i, stamp_ns=0, seed=i) for i in range(5)]
    t0 = 1_700_000_000_000_000_000
    with McapRecorder(path, compression="lz4") as rec:
        for i in range(frames):
            stamp = t0 + i * 33_333_333
            f = distinct[i % len(distinct)]
            header = f.header.model_copy(update={"stamp_ns": stamp, "seq": i})
            rec.write(KEYS.frames("head"), f.model_copy(update={"header": header}), stamp)
        return rec.bytes[KEYS.frames("head")] // frames


def one_run(path: Path, frames: int, subscriber: ZenohOptions, replay_zenoh: list[str]) -> tuple[float, list[float]]:
    """(seconds from first to last frame, gaps between frames in ms)."""
    with open_transport(subscriber) as t:
        sub: Subscription[Any] = t.subscribe(KEYS.frames("head"), None, FIFO)
        cmd = [sys.executable, "-m", "perception", "-q", "replay", str(path), "--max", "--no-progress",
               "--wait-subscribers", "30", *replay_zenoh]
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        arrivals: list[int] = []
        deadline = time.monotonic() + 300
        while len(arrivals) < frames and time.monotonic() < deadline:
            r = sub.recv(timeout=1.0)
            if r is not None:
                arrivals.append(time.monotonic_ns())
            elif proc.poll() is not None and not sub.pending():
                break
        out, _ = proc.communicate(timeout=60)
        if proc.returncode != 0:
            raise SystemExit(f"replay failed: {out}")
        if len(arrivals) < frames:
            print(f"  warning: {len(arrivals)}/{frames} frames arrived ({sub.stats.dropped} dropped, "
                  f"{sub.stats.invalid} invalid)", file=sys.stderr)
    gaps = np.diff(np.array(arrivals)) / 1e6
    return (arrivals[-1] - arrivals[0]) / 1e9, gaps.tolist()


def measure(name: str, path: Path, frames: int, frame_bytes: int, runs: int, subscriber: ZenohOptions,
            replay_zenoh: list[str], bar: Bar) -> str:
    """The table row of ``runs`` replays of ``path``; ``bar`` counts the runs."""
    fps, gaps = [], []
    for _ in range(runs):
        span, g = one_run(path, frames, subscriber, replay_zenoh)
        fps.append((len(g)) / span)
        gaps.extend(g)
        bar.update()
    f = float(np.median(fps))
    return (f"| {name} | {f:.0f} | {f * frame_bytes / 1e6:.0f} | {np.median(gaps):.2f} | "
            f"{np.percentile(gaps, 95):.2f} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=150)
    ap.add_argument("--runs", type=int, default=3)
    args = ap.parse_args()
    os.environ.setdefault("RUST_LOG", "error")
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "bench.mcap"
        frame_bytes = write_recording(path, args.frames)
        print(f"640x480 RGB-D, {frame_bytes / 1e6:.2f} MB a frame, {args.frames} frames, {args.runs} runs, "
              f"{os.cpu_count()} CPUs")
        print("| path | frames/s | MB/s | median gap ms | p95 gap ms |")
        print("|---|---|---|---|---|")
        no_shm = Path(tmp) / "no_shm.json5"
        no_shm.write_text('{ transport: { shared_memory: { enabled: false } } }')
        with progress_bar(3 * args.runs, desc="replay", unit="run") as bar:
            with RouterProcess() as router:
                client = ZenohOptions(mode="client", connect=[router.endpoint])
                print(measure("via router (clients)", path, args.frames, frame_bytes, args.runs, client,
                              ["--connect", router.endpoint], bar), flush=True)
                client_no_shm = ZenohOptions(mode="client", connect=[router.endpoint], shared_memory=False)
                print(measure("via router, shared memory off (as between PCs)", path, args.frames, frame_bytes,
                              args.runs, client_no_shm, ["--connect", router.endpoint, "--config", str(no_shm)], bar),
                      flush=True)
            port = free_port()
            endpoint = f"tcp/127.0.0.1:{port}"
            peer = ZenohOptions(mode="peer", listen=[endpoint])
            print(measure("peer to peer", path, args.frames, frame_bytes, args.runs, peer,
                          ["--mode", "peer", "--connect", endpoint], bar), flush=True)


if __name__ == "__main__":
    main()
