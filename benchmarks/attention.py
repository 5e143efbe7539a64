"""Command latency of the attention node: from a Tracks message to its HeadCommand; with
``--loop``, how well the closed loop keeps person 1 in view on the simulator.

In-memory transport, one process: the time from publishing a Tracks message (5 people,
transforms and camera info known) to the HeadCommand the node publishes for it, i.e. the
node's own work (decode, choose, transform lookups, the control law, encode). Over Zenoh
add the transport's hop (ZENOH_NOTES.md: about 0.2 ms through a router on loopback).

    python benchmarks/attention.py [--n 2000]
    python benchmarks/attention.py --loop [--scenario people-following] [--seeds 0 1 2] [--json FILE]

``--loop`` runs the scenario through the whole chain in one process (``run_chain``, 320x240
at 10 fps) with the head driven four ways and scores person 1 each time (the centring
error of their true torso centre, the share of frames where they are visible):

- ``rest``: the head stays at its rest pose (attention target none);
- ``nearest`` and ``lock``: the attention node on the tracker's tracks, with those targets;
- ``truth``: the attention node on the ground truth (a perfect tracker, target ID 1): the
  loop without tracking errors (what the walls, the robot's path, the other people and the
  head's limits leave on this scenario).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from common.messages.keys import RELIABLE, Keys
from common.transport.memory import MemoryBus
from common.runtime.progress import progress
from common.geometry.poses import OPTICAL_FROM_BODY, make_pose, rot_y
from common.messages.samples import rgbd_frame
from common.messages.schemas import HeadCommand, Header, RGBDFrame, TrackState, Tracks, TransformBatch
from services.attention.config import AttentionConfig
from services.attention.service import AttentionService
from tools.simulator.messages import transform


def loop(scenario: str, seeds: list[int], json_path: Path | None) -> None:
    """The closed loop four ways (module docstring) on each scenario seed, one table row each."""
    from tools.demo.inprocess import run_chain
    from tools.simulator.core.scenarios import SCENARIOS

    duration = SCENARIOS[scenario].duration_s
    runs: dict[str, dict[str, dict]] = {}
    for seed in seeds:
        rows = runs.setdefault(str(seed), {})
        for name, target, truth in (("rest", "none", False), ("nearest", "nearest", False), ("lock", "lock", False),
                                    ("truth", "1", True)):
            t0 = time.perf_counter()
            r = run_chain(scenario, duration_s=duration, seed=seed, attention=AttentionConfig(target=target),
                          attention_truth=truth)
            assert r.attention is not None
            rows[name] = {**r.attention, "mota": round(r.report["overall"]["mota"], 3)}
            print(f"seed {seed} {name:8s} centring error p50 {r.attention['center_error_px_p50']} px, p95 "
                  f"{r.attention['center_error_px_p95']} px; person {r.attention['person_id']} visible "
                  f"{r.attention['target_visible_fraction']:.3f} ({time.perf_counter() - t0:.0f} s)", flush=True)
    result = {"scenario": scenario, "duration_s": duration, "runs": runs}
    print(json.dumps(result))
    if json_path is not None:
        json_path.write_text(json.dumps(result, indent=1) + "\n")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=2000, help="Tracks messages (default 2000)")
    ap.add_argument("--loop", action="store_true", help="score the closed loop on the simulator instead (see above)")
    ap.add_argument("--scenario", default="people-following", help="--loop: the scenario (default people-following)")
    ap.add_argument("--seeds", type=int, nargs="+", default=[0], metavar="N",
                    help="--loop: the scenario's seeds, each run four ways (default 0)")
    ap.add_argument("--json", type=Path, default=None, metavar="FILE", help="--loop: also write the figures here")
    args = ap.parse_args()
    if args.loop:
        from tools.simulator.core.scenarios import SCENARIOS

        if args.scenario not in SCENARIOS:
            ap.error(f"unknown scenario {args.scenario!r}; choose one of {', '.join(SCENARIOS)}")
        loop(args.scenario, args.seeds, args.json)
        return
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
