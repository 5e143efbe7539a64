"""Command latency of the attention node: from a Tracks message to its HeadCommand.

In-memory transport, one process: the time from publishing a Tracks message (5 people,
transforms and camera info known) to the HeadCommand the node publishes for it, i.e. the
node's own work (decode, choose, transform lookups, the control law, encode). Over Zenoh
add the transport's hop (ZENOH_NOTES.md: about 0.2 ms through a router on loopback).

    python benchmarks/attention.py [--n 2000]
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from common.keys import RELIABLE, Keys
from common.memory import MemoryBus
from common.progress import progress
from common.poses import OPTICAL_FROM_BODY, make_pose, rot_y
from common.samples import rgbd_frame
from common.schemas import HeadCommand, Header, RGBDFrame, TrackState, Tracks, TransformBatch
from services.attention.config import AttentionConfig
from services.attention.service import AttentionService
from tools.simulator.messages import transform


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=2000, help="Tracks messages (default 2000)")
    args = ap.parse_args()
    bus, keys = MemoryBus(), Keys(robot="bench")
    node = AttentionService(bus.transport(), keys, AttentionConfig(target="nearest"))
    t = bus.transport()
    stamp0 = 10**18
    t.publisher(keys.tf_static(), TransformBatch, RELIABLE).put(TransformBatch(header=Header(stamp_ns=stamp0), transforms=[
        transform("head_link", "camera", make_pose(OPTICAL_FROM_BODY, (0.06, 0, 0.08)), stamp0, static=True)]))
    t.publisher(keys.frames("head"), RGBDFrame, RELIABLE).put(rgbd_frame(320, 240, stamp_ns=stamp0))
    tf = t.publisher(keys.tf(), TransformBatch, RELIABLE)
    tracks = t.publisher(keys.tracks(), Tracks, RELIABLE)
    commands = t.subscribe(keys.head_command(), HeadCommand, RELIABLE)
    rng = np.random.default_rng(0)
    latencies = []
    for k in progress(range(args.n), total=args.n, desc="attention", unit="msg"):
        stamp = stamp0 + k * 10**8
        tf.put(TransformBatch(header=Header(stamp_ns=stamp), transforms=[
            transform("map", "base_link", np.eye(4), stamp),
            transform("base_link", "head_link", make_pose(rot_y(0.1), (0.05, 0.0, 1.15)), stamp)]))
        people = [TrackState(id=i, status="confirmed", position=np.array([2.0 + i, rng.uniform(-1, 1), 1.1]),
                             velocity=np.array([0.0, 0.5, 0.0]), covariance=np.eye(6), last_update_ns=stamp, hits=5,
                             age_s=1.0) for i in range(1, 6)]
        node.poll(k * 0.1)  # take the transforms first, as the node's loop does between tracks
        while commands.try_recv() is not None:  # a timed keep-alive command
            pass
        t0 = time.perf_counter()
        tracks.put(Tracks(header=Header(stamp_ns=stamp, frame_id="map"), tracks=people))
        node.poll(k * 0.1 + 0.05)
        got = commands.try_recv()
        latencies.append((time.perf_counter() - t0) * 1e3)
        assert got is not None and got.msg.input_stamp_ns == stamp
    lat = np.asarray(latencies[100:])
    print(json.dumps({"messages": len(lat), "latency_ms_p50": round(float(np.percentile(lat, 50)), 3),
                      "latency_ms_p95": round(float(np.percentile(lat, 95)), 3),
                      "latency_ms_max": round(float(lat.max()), 3)}))


if __name__ == "__main__":
    main()
