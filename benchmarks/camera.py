"""The camera node's cost: `perception camera` playing a 640x480, 30 fps video file in real time,
through a router to a subscriber, as a process; its CPU over wall time, in % of one core.

    python benchmarks/camera.py [--seconds 20] [--codec MJPG|mp4v] [--runs 3]

The video is written here with OpenCV (nothing downloaded): a moving gradient, so that the
codec has work to do. The figure includes decoding the video, which a live camera's driver
(V4L2 MJPG) also costs.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import cv2  # noqa: E402

from common.messages.keys import Delivery, Keys  # noqa: E402
from common.transport.router_process import RouterProcess  # noqa: E402
from common.transport.zenoh import open_transport  # noqa: E402
from common.transport.zenoh_config import ZenohOptions  # noqa: E402

_TCK = os.sysconf("SC_CLK_TCK")


def _cpu(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / _TCK


def _video(path: Path, seconds: float, codec: str) -> None:
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*codec), 30.0, (640, 480))
    yy, xx = np.mgrid[0:480, 0:640]
    for k in range(int(seconds * 30)):
        frame = np.stack([(xx + 4 * k) % 256, (yy + 2 * k) % 256, (xx + yy + k) % 256], -1).astype(np.uint8)
        writer.write(frame)
    writer.release()


def run(video: Path, seconds: float, extra: tuple[str, ...] = ()) -> float:
    router = RouterProcess(log_path=str(video.with_suffix(".router.log"))).start()
    keys = Keys(robot="bench")
    try:
        t = open_transport(ZenohOptions(mode="client", connect=[router.endpoint]))
        sub = t.subscribe(keys.frames("head"), None, Delivery(latest=True, queue=1, congestion="drop"))
        proc = subprocess.Popen([sys.executable, "-m", "perception", "-q", "camera", str(video), "--robot", "bench",
                                 "--connect", router.endpoint, "--hfov", "69", *extra],
                                env={**os.environ, "RUST_LOG": "error", "OPENBLAS_NUM_THREADS": "1"})
        while sub.recv(timeout=0.1) is None:  # started: its first frame is here
            assert proc.poll() is None, "the camera process stopped"
        c0, w0 = _cpu(proc.pid), time.monotonic()
        time.sleep(seconds * 0.6)  # a window inside the run: start-up and shutdown left out
        c1, w1 = _cpu(proc.pid), time.monotonic()
        proc.wait(timeout=seconds * 3)
        t.close()
        return 100.0 * (c1 - c0) / (w1 - w0)
    finally:
        router.stop()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=20.0)
    ap.add_argument("--codec", default="MJPG")
    ap.add_argument("--runs", type=int, default=3)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        video = Path(tmp) / ("clip.avi" if args.codec == "MJPG" else "clip.mp4")
        _video(video, args.seconds, args.codec)
        for label, extra in (("JPEG frames passed on", ()), ("decoded, sent raw (--service-config passthrough: false)",
                                                            ("--no-passthrough",))):
            cpus = [run(video, args.seconds, extra) for _ in range(args.runs)]
            print(f"perception camera, 640x480 {args.codec} file at 30 fps, {label}: "
                  f"{', '.join(f'{c:.1f}' for c in cpus)} % of one core (median {np.median(cpus):.1f} %)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
