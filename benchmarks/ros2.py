"""The ROS 2 node's cost: converting a ROS 2 RGB-D pair into frames/{camera}, a frame's people into
ROS 2 messages, and the node's CPU at a camera rate.

    python benchmarks/ros2.py [--repeats 200] [--people 3 10] [--rate 30 --seconds 10]

1. **In**: a 640x480 rgb8 image, its 16UC1 aligned depth and the camera info as rmw_zenoh
   delivers them (CDR and attachment) -> the node's ``RGBDFrame`` on ``frames/head``, encoded
   (``common.messages.codec``): deserialize, check, pair, build, encode. Median and p95 in ms.
2. **Out**: one ``Tracks`` with N confirmed people -> ``/humans/bodies/tracked``, each body's
   position and velocity, the ``body_<id>`` frames on ``/tf`` and ``/humans/markers``, in CDR
   with their attachments. Median and p95 in ms.
3. **Node**: the node on the in-memory transport, fed at ``--rate`` Hz with RGB-D pairs and
   ``Tracks`` of 3 people, as ``perception ros2`` runs; its CPU time (``time.thread_time`` of
   the thread that polls, which does every conversion) over wall time, in % of one core.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from common.messages.codec import encode  # noqa: E402
from common.messages.keys import RELIABLE, Delivery, Keys  # noqa: E402
from common.transport.memory import MemoryBus  # noqa: E402
from common.runtime.service import Counters  # noqa: E402
from common.messages.schemas import CameraInfo, Header, Image, RGBDFrame, Tracks, TrackState  # noqa: E402
from services.ros2.config import Ros2Config  # noqa: E402
from services.ros2.convert import camera_info_message, image_message  # noqa: E402
from services.ros2.core.types import types_of  # noqa: E402
from services.ros2.participant import RosParticipant  # noqa: E402
from services.ros2.service import Ros2Service  # noqa: E402

KEYS = Keys()
T = types_of()


def _frame(stamp: int, w: int = 640, h: int = 480) -> RGBDFrame:
    rng = np.random.default_rng(0)
    header = Header(stamp_ns=stamp, frame_id="camera_color_optical_frame", source="head")
    rgb = rng.integers(0, 255, (h, w, 3), dtype=np.uint8)
    depth = rng.integers(500, 6000, (h, w), dtype=np.uint16)
    K = np.array([[600.0, 0, w / 2], [0, 600.0, h / 2], [0, 0, 1]])
    return RGBDFrame(header=header, rgb=Image.from_array(rgb, "rgb8", header), depth=Image.from_array(depth, "16UC1", header),
                     camera_info=CameraInfo(header=header, width=w, height=h, K=K, distortion_model="none"))


def _tracks(stamp: int, n: int) -> Tracks:
    return Tracks(header=Header(stamp_ns=stamp, frame_id="map"), tracks=[
        TrackState(id=i + 1, status="confirmed", position=np.array([1.0 + i, 2.0, 0.9]), velocity=np.array([0.3, 0, 0]),
                   covariance=np.eye(6), last_update_ns=stamp, hits=10, age_s=2.0) for i in range(n)])


def _stats(ms: list[float]) -> str:
    return f"median {np.median(ms):.2f} ms, p95 {np.percentile(ms, 95):.2f} ms"


class Rig:
    def __init__(self, **settings: object) -> None:
        self.bus = MemoryBus()
        self.robot = RosParticipant(self.bus.transport(), T, domain_id=0, node_name="camera")
        self.node = Ros2Service(self.bus.transport(), KEYS, Ros2Config(domain_id=0, **settings), Counters())
        app = self.bus.transport()
        self.frames = app.subscribe(KEYS.frames("head"), None, Delivery(latest=True, queue=1, congestion="drop"))
        self.tracks = app.publisher(KEYS.tracks(), Tracks, RELIABLE)
        cfg = self.node.config
        self.colour = self.robot.publisher(cfg.colour_topic, "sensor_msgs/msg/Image")
        self.depth = self.robot.publisher(cfg.depth_topic, "sensor_msgs/msg/Image")
        self.info = self.robot.publisher(cfg.camera_info_topic, "sensor_msgs/msg/CameraInfo")
        self.readers = [self.bus.transport().subscribe_raw("0/humans/**", Delivery(latest=False, queue=4096, congestion="drop")),
                        self.bus.transport().subscribe_raw("0/tf/**", Delivery(latest=False, queue=4096, congestion="drop"))]

    def cdr(self, frame: RGBDFrame) -> tuple[bytes, bytes, bytes]:
        return (T.serialize(camera_info_message(T, frame), "sensor_msgs/msg/CameraInfo"),
                T.serialize(image_message(T, frame, depth=True), "sensor_msgs/msg/Image"),
                T.serialize(image_message(T, frame), "sensor_msgs/msg/Image"))

    def feed(self, payloads: tuple[bytes, bytes, bytes], stamp: int) -> None:
        for pub, payload in zip((self.info, self.depth, self.colour), payloads):
            pub.put_cdr(payload, stamp)


def bench_in(repeats: int) -> list[float]:
    rig = Rig(people_out=False, tf_in=False)
    out = []
    base = 1_700_000_000_000_000_000
    payloads = rig.cdr(_frame(base))
    for k in range(repeats):
        stamp = base + k * 33_000_000
        # a new stamp in each CDR: re-serialize only the headers' stamps would be cheaper, but the
        # node must see distinct stamps to pair them
        info, depth, colour = (_restamp(p, stamp) for p in payloads)
        rig.feed((info, depth, colour), stamp)
        t0 = time.perf_counter()
        published = rig.node.poll(float(k))
        for f in published:
            encode(f)
        out.append((time.perf_counter() - t0) * 1e3)
        assert len(published) == 1, rig.node.counters.extra
        while rig.frames.try_recv() is not None:
            pass
    return out


def _restamp(cdr: bytes, stamp: int) -> bytes:
    """The CDR with header.stamp replaced (sec, nanosec are the first 8 bytes after the 4-byte header)."""
    return cdr[:4] + int(stamp // 10**9).to_bytes(4, "little", signed=True) + int(stamp % 10**9).to_bytes(4, "little") + cdr[12:]


def bench_out(repeats: int, people: int) -> list[float]:
    rig = Rig(camera_in=False, tf_in=False)
    out = []
    for k in range(repeats):
        stamp = 1_700_000_000_000_000_000 + k * 33_000_000
        rig.tracks.put(_tracks(stamp, people))
        t0 = time.perf_counter()
        rig.node.poll(float(k))
        out.append((time.perf_counter() - t0) * 1e3)
        for r in rig.readers:
            while r.try_recv() is not None:
                pass
    return out


def bench_node(rate: float, seconds: float) -> float:
    rig = Rig()
    base = time.time_ns()
    payloads = rig.cdr(_frame(base))
    busy = 0.0
    t_start = time.monotonic()
    n = int(rate * seconds)
    for k in range(n):
        due = t_start + k / rate
        if (wait := due - time.monotonic()) > 0:
            time.sleep(wait)
        stamp = base + int(k / rate * 1e9)
        rig.feed(tuple(_restamp(p, stamp) for p in payloads), stamp)  # type: ignore[arg-type]
        rig.tracks.put(_tracks(stamp, 3))
        c0 = time.thread_time()
        rig.node.poll(time.monotonic())
        busy += time.thread_time() - c0
        while rig.frames.try_recv() is not None:
            pass
        for r in rig.readers:
            while r.try_recv() is not None:
                pass
    wall = time.monotonic() - t_start
    return 100.0 * busy / wall


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=200)
    ap.add_argument("--people", type=int, nargs="+", default=[3, 10])
    ap.add_argument("--rate", type=float, default=30.0)
    ap.add_argument("--seconds", type=float, default=10.0)
    args = ap.parse_args()
    print(f"in:   640x480 rgb8 + 16UC1 + camera info -> frames/head (encoded): {_stats(bench_in(args.repeats))}")
    for n in args.people:
        print(f"out:  Tracks of {n} people -> ROS 2 (tracked, position, velocity, /tf, markers): "
              f"{_stats(bench_out(args.repeats, n))}")
    print(f"node: {bench_node(args.rate, args.seconds):.1f} % of one core at {args.rate:g} Hz "
          f"(640x480 RGB-D in, 3 people out)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
