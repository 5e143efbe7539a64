"""PETS09-S2L1 through the live services: real video as processes over a real router, scored
beside the offline chain of ``benchmarks/quality.py`` on the same frames.

    python benchmarks/pets_live.py [--frames 400] [--data ../shared/data]

It prints one markdown table (``benchmarks/quality.py --only pets-live`` runs this script and
prints the same table; this module uses quality.py's chain and judge, never the other way).

``perception camera`` plays ``pets09_dev/frames`` (a folder; ``--max``: each frame once the
detector has answered the previous one) -> the HOG detector (quality.py's upsampling for 50 px
people) -> the localizer on the floor through ``ground_homography.json`` (no depth) -> the colour
embedder -> the tracker (robust, once per input frame, no ID memory file). The tracks are judged
as quality.py judges its PETS chain (ground plane, 1 m gate, the conf-0 rows as ignore regions),
and the live chain's frames/s is printed beside it.
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any


ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from common.messages.keys import RELIABLE, Keys  # noqa: E402
from common.messages.schemas import Tracks  # noqa: E402
from common.transport.router_process import RouterProcess  # noqa: E402
from common.transport.zenoh import open_transport  # noqa: E402
from common.transport.zenoh_config import ZenohOptions  # noqa: E402
from services.tracker.presets import preset_environment  # noqa: E402

__all__ = ["LiveRun", "judge", "quality_module", "run_live", "run_offline", "runs", "table"]

SERVICES = ("detector", "localizer", "embedder", "tracker")


def quality_module() -> ModuleType:
    """benchmarks/quality.py: its PETS chain's settings and its judge are the reference (imported
    when first needed: it is large, and the live run alone does not need it)."""
    from benchmarks import quality

    return quality


@dataclass
class LiveRun:
    rows: list[tuple[int, float, int, float, float, float, str]]
    frames: int
    seconds: float
    log: str

    @property
    def fps(self) -> float:
        return self.frames / self.seconds if self.seconds > 0 else 0.0


def _perception(*args: str) -> list[str]:
    return [sys.executable, "-m", "perception", *args]


#: The tracker as the offline chain runs it: its fixed measurement noise instead of each
#: detection's covariance (the offline chain's detections carry none).
LIKE_OFFLINE = {"PERCEPTION_TRACKER__ROBUST__USE_DETECTION_COVARIANCE": "false"}
#: quality.py's site preset (deploy/presets/pets-site.yaml), given to the services as their
#: environment: the open place's ID-memory prior (the localizer sends the camera's floor view
#: through the homography by itself)
SITE_PRESET = "pets-site"


def run_live(root: Path, n_frames: int, workdir: Path, timeout_s: float = 900.0,
             env: dict[str, str] | None = None) -> LiveRun:
    """The live chain on the first ``n_frames`` PETS frames; the tracks as quality.py's rows.
    ``env``: settings of the services (``LIKE_OFFLINE``: the tracker as the offline chain runs it)."""
    q = quality_module()
    frames = sorted((root / "frames").glob("frame_*.jpg"))[:n_frames]
    folder = workdir / "frames"
    folder.mkdir(parents=True, exist_ok=True)
    for f in frames:
        link = folder / f.name
        if not link.exists():
            link.symlink_to(f.resolve())
    keys = Keys(robot=f"pets{os.getpid()}")
    log_path = workdir / "processes.log"
    log = log_path.open("wb")
    env = {**os.environ, "RUST_LOG": "error", "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1",
           "PERCEPTION_DETECTOR__HOG__UPSAMPLE": str(q.PETS_UPSAMPLE), "XDG_STATE_HOME": str(workdir), **(env or {})}
    router = RouterProcess(log_path=str(workdir / "router.log")).start()
    zen = ("--robot", keys.robot, "--connect", router.endpoint)
    specs = {
        "detector": _perception("detector", *zen, "--backend", "hog"),
        # a surveillance camera: people 17-35 m away
        "localizer": _perception("localizer", *zen, "--floor-homography", str(root / "ground_homography.json"),
                                 "--max-floor-range", "100"),
        "embedder": _perception("embedder", *zen, "--backend", "colour"),
        "tracker": _perception("tracker", *zen, "--no-memory", "--output-rate", "0"),
    }
    procs: dict[str, subprocess.Popen[bytes]] = {}
    rows: list[tuple[int, float, int, float, float, float, str]] = []
    seen: set[int] = set()
    started = finished = 0.0
    try:
        for name, cmd in specs.items():
            procs[name] = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env=env)
        with open_transport(ZenohOptions(mode="client", connect=[router.endpoint], connect_timeout_s=30)) as t:
            tracks = t.subscribe(keys.tracks(), Tracks, RELIABLE.__class__(latest=False, queue=4096, congestion="block"))
            deadline = time.monotonic() + 90
            while time.monotonic() < deadline:
                alive = {keys.parse_alive(k).service for k in t.alive(keys.alive(), timeout=0.5)}
                if set(SERVICES) <= alive:
                    break
                if any(p.poll() is not None for p in procs.values()):
                    raise RuntimeError(f"a service stopped at start-up:\n{log_path.read_text()[-3000:]}")
            else:
                raise RuntimeError(f"services did not come up:\n{log_path.read_text()[-3000:]}")
            started = time.monotonic()
            camera = subprocess.Popen(_perception("camera", str(folder), *zen, "--max", "--fps", str(q.PETS_FPS),
                                                  "--start-ns", "0", "--hfov", "60"),
                                      stdout=log, stderr=subprocess.STDOUT, env=env)
            procs["camera"] = camera
            last = time.monotonic()
            end = time.monotonic() + timeout_s
            while time.monotonic() < end:
                got = tracks.recv(timeout=0.2)
                if got is not None:
                    last = time.monotonic()
                    msg = got.msg
                    if msg.header.seq in seen:
                        continue  # the first output per frame is what a consumer had
                    seen.add(msg.header.seq)
                    for tr in msg.tracks:
                        x, y, z = (float(v) for v in tr.position)
                        rows.append((msg.header.seq, msg.header.stamp_ns / 1e9, tr.id, x, y, z, tr.status))
                    finished = last
                elif camera.poll() is not None and time.monotonic() - last > 3.0:
                    break
            if camera.poll() is None:
                raise RuntimeError(f"the camera did not finish in {timeout_s:.0f} s")
    finally:
        for p in procs.values():
            if p.poll() is None:
                p.send_signal(signal.SIGINT)
        for p in procs.values():
            try:
                p.wait(20)
            except subprocess.TimeoutExpired:
                p.kill()
        router.stop()
        log.close()
    return LiveRun(rows, len(seen), max(0.0, finished - started), log_path.read_text()[-3000:])


def run_offline(root: Path, n_frames: int, cache_dir: Path | None) -> list[Any]:
    """quality.py's offline PETS chain on the first ``n_frames``, robust profile: its cached
    detections of all 400 frames (``cache_dir``), or, without a cache dir, those frames detected now."""
    q = quality_module()
    if cache_dir is not None:
        (seq,) = q.load_pets(root, cache_dir, log=lambda _m: None)
        dets = q.select(seq.dets, seq.dets.frames <= n_frames)
    else:
        with tempfile.TemporaryDirectory() as tmp:
            part = Path(tmp)
            (part / "frames").mkdir()
            for f in sorted((root / "frames").glob("frame_*.jpg"))[:n_frames]:
                (part / "frames" / f.name).symlink_to(f.resolve())
            (part / "ground_homography.json").symlink_to((root / "ground_homography.json").resolve())
            dets = q.detect_pets(part, log=lambda _m: None)
    robust = next(a for a in q.project_adapters() if a.name == "robust")
    return robust.run(dets)


def judge(root: Path, n_frames: int, rows: list[Any]) -> Any:
    q = quality_module()
    table, ignore = q.pets_truth(root, n_frames)
    return q.judge(table, rows, ignore)


def runs() -> tuple[tuple[str, dict[str, str]], ...]:
    """The live runs of :func:`table`: label and the services' settings."""
    return (("live, tracker as offline (fixed R)", LIKE_OFFLINE),
            ("live, defaults (R from the floor homography)", {}),
            ("live, as offline, the site's settings (pets-site)", {**LIKE_OFFLINE, **preset_environment(SITE_PRESET)}))


def table(root: Path, n_frames: int, cache_dir: Path | None) -> str:
    """The first ``n_frames`` through the live services (each of :func:`runs`), beside the offline
    chain, as a markdown table with its notes."""
    lines = [f"### PETS09-S2L1 frames 1-{n_frames} through the live services (robust), beside the offline chain", "",
             "| chain | MOTA | IDF1 | IDSW | frames/s |", "|---|---|---|---|---|"]
    offline = judge(root, n_frames, run_offline(root, n_frames, cache_dir))
    lines.append(f"| offline (quality.py's PETS chain) | {offline.mota:.3f} | {offline.idf1:.3f} | {offline.id_switches} | |")
    for label, env in runs():
        with tempfile.TemporaryDirectory() as tmp:
            run = run_live(root, n_frames, Path(tmp), env=env)
        r = judge(root, n_frames, run.rows)
        lines.append(f"| {label} | {r.mota:.3f} | {r.idf1:.3f} | {r.id_switches} | {run.fps:.1f} |")
    lines += ["", "(camera --max -> HOG -> localizer -> embedder -> tracker, each a process over a real router; "
              "'as offline': the tracker's fixed measurement noise, as the offline chain's detections carry no "
              "covariance; 'defaults': each detection's covariance from the floor homography; 'the site's settings': "
              "the pets-site preset, an open place's ID-memory prior. Live, the tracker has the camera's floor view "
              "the localizer sends; offline it has none.)"]
    return "\n".join(lines)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=400)
    ap.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data")
    ap.add_argument("--cache-dir", type=Path, default=ROOT / "benchmarks" / ".cache",
                    help="quality.py's cache of the offline chain's detections (git-ignored)")
    args = ap.parse_args()
    root = args.data / "pets09_dev"
    if not root.is_dir():
        print(f"PETS09 not found at {root}")
        return 2
    print(table(root, args.frames, args.cache_dir))
    return 0


if __name__ == "__main__":
    sys.exit(main())
