"""``perception demo``: the whole pipeline on a simulated apartment, live, then scored.

A local router, the four services and the simulator run as separate processes (the
services supervised by the launcher's :class:`Supervisor`, their output in a log file).
This process watches the streams, shows the confirmed tracks, the frame rate and the
latency per stage, and at the end scores the tracks against the simulator's ground truth
with the ``evaluate`` code (the thesis's Table II).
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from common.runtime.cli_util import CliError
from common.messages.keys import Keys
from common.messages.registry import stages
from common.transport.router_process import free_port
from common.runtime.service import Shutdown
from common.transport.base import Transport
from common.transport.zenoh_config import ZenohOptions
from common.transport.zenoh import TransportError, open_transport
from services.tracker.presets import preset_environment
from tools.demo.attention import AttentionLog
from tools.demo.monitor import Monitor
from tools.demo.ros2_echo import TrackedEcho
from tools.demo.scoring import GroundTruthLog, score
from tools.demo.text import WIDTH, attention_line, closing_text, wrap
from tools.launcher.supervisor import ProcessSpec, Supervisor
from tools.simulator.core.cameras import BACK_CAMERA_OFFSET
from tools.simulator.core.render import default_camera
from tools.simulator.static_map import write_apartment_map

DESCRIPTION = """\
Run the whole system on a simulated RGB-D apartment with the embedded defaults: a local
Zenoh router, the detector (depth clusters), localizer, embedder (colour descriptor) and
tracker (the robust profile with the colour descriptor's thresholds), and the simulator,
each as a separate process. A live view shows the confirmed tracks, the frame rate and the
latency per stage; at the end the tracks are scored against the simulator's ground truth
(objects, misses, FP, ID switches, recall errors, MOTP, MOTA). Ctrl-C ends the run early
and still prints the table. Nothing is left running afterwards."""

SERVICES = stages()
_CLK_TCK = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100


def _cpu_seconds(pid: int) -> float | None:
    """User + system CPU time of a process (Linux /proc), or None."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return None
    return (int(fields[11]) + int(fields[12])) / _CLK_TCK


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--scenario", default="still", help="simulated scenario (see `perception simulate --list`)")
    parser.add_argument("--duration", type=float, default=30.0, metavar="S", help="simulated seconds (default 30)")
    parser.add_argument("--seed", type=int, default=0, help="random seed of the scenario (default 0): same seed, same run")
    parser.add_argument("--width", type=int, default=320, metavar="PX", help="image width (default 320, for speed)")
    parser.add_argument("--height", type=int, default=240, metavar="PX", help="image height (default 240)")
    parser.add_argument("--fps", type=float, default=10.0, metavar="HZ", help="camera frames per second (default 10)")
    parser.add_argument("--detector", default="depth", help="detector backend (default depth; hog also needs no model)")
    parser.add_argument("--second-detector", default=None, metavar="BACKEND",
                        help="also run a second, slower detector on the camera (as in the TU Ilmenau "
                             "framework: e.g. hog next to depth) on its own stream; the tracker fuses both")
    parser.add_argument("--second-rate", type=float, default=3.0, metavar="HZ",
                        help="the second detector's frames per second (default 3)")
    parser.add_argument("--back-camera", default=None, metavar="NAME",
                        help="also simulate a camera on the base looking backwards (e.g. back) with its own detector, "
                             "localizer and embedder; the tracker fuses both cameras (try --scenario handover)")
    parser.add_argument("--laser", action="store_true",
                        help="also simulate a 2-D laser on the base (360 degrees, scans/front) and run the laser node "
                             "(perception laser: people from their legs); the tracker fuses them, and the tracks are "
                             "judged over everyone the camera or the laser could see (try --scenario guided-tour)")
    parser.add_argument("--no-view", action="store_true", help="no live view in the terminal, only the final table")
    parser.add_argument("--view", action="store_true",
                        help="also serve the live page (perception view) and open it in a browser when there is a display")
    parser.add_argument("--view-port", type=int, default=8080, metavar="PORT",
                        help="the page's port with --view (default 8080)")
    parser.add_argument("--attention", action="store_true",
                        help="also run the attention node (target lock: the nearest person, then their ID) and let it steer the simulated "
                             "head; the JSON gains attention: centring error and visible share of person 1")
    parser.add_argument("--ros2", action="store_true",
                        help="through ROS 2: the simulated robot publishes its camera and /tf as ROS 2 topics "
                             "(rmw_zenoh), the ros2 node reads them in and publishes the people on /humans/...; the "
                             "end report adds what /humans/bodies/tracked carried")
    parser.add_argument("--no-static-map", action="store_true",
                        help="do not give the tracker the apartment's static map (the robot's laser map, "
                             "`perception simulate --write-map`, or with --ros2 the robot's /map; with it no track "
                             "is born on a wall or a door jamb)")
    parser.add_argument("--json", action="store_true", help="print the final metrics as JSON")
    parser.add_argument("--plot", type=Path, default=None, metavar="OUT.png",
                        help="where the top-down plot of the run goes (default: tracks.png in the log dir)")
    parser.add_argument("--log-dir", type=Path, default=None, help="where the processes' log goes (default: a temp dir)")


def _perception(*args: str) -> list[str]:
    return [sys.executable, "-m", "perception", *args]


def _specs(endpoint: str, port: int, robot: str, args: argparse.Namespace, memory: Path,
           static_map: Path | None = None) -> list[ProcessSpec]:
    env = {**os.environ, "RUST_LOG": os.environ.get("RUST_LOG", "error"), "OPENBLAS_NUM_THREADS": "1",
           "OMP_NUM_THREADS": "1"}
    common = ("--connect", endpoint, "--robot", robot)
    specs = [ProcessSpec("router", _perception("router", "--listen", endpoint, "--no-multicast-scouting"), env,
                         restart="on-failure", ready_tcp=("127.0.0.1", port), stop_last=True)]
    extra = {
        "detector": ("--backend", args.detector),
        "localizer": (),
        "embedder": ("--backend", "colour"),
        # once per camera frame: Table II scores every frame against its ground truth
        "tracker": ("--memory", str(memory), "--output-rate", "0",
                    *(("--static-map", str(static_map)) if static_map is not None else ())),
    }
    names = list(SERVICES)
    if args.second_detector:
        stream = f"head-{args.second_detector}"
        extra["detector-slow"] = ("--backend", args.second_detector, "--stream", stream, "--max-rate",
                                  str(args.second_rate))
        extra["localizer-slow"] = ("--stream", stream)
        extra["tracker"] += ("--camera", "*", "--no-embeddings", stream)
        names[1:1] = ["detector-slow"]
        names[3:3] = ["localizer-slow"]
    if args.back_camera:
        cam = ("--camera", args.back_camera)
        # the depth detector's floor plane starts from the back camera's mount (level; own_env)
        extra["detector-back"] = (*extra["detector"], *cam)
        extra["localizer-back"] = cam
        extra["embedder-back"] = (*extra["embedder"], *cam)
        if "--camera" not in extra["tracker"]:
            extra["tracker"] += ("--camera", "*")
        names += ["detector-back", "localizer-back", "embedder-back"]
    own_env = {"detector-back": {"PERCEPTION_DETECTOR__DEPTH__CAMERA_HEIGHT_M": f"{BACK_CAMERA_OFFSET[2]:g}",
                                 "PERCEPTION_DETECTOR__DEPTH__TILT_DEG": "0"}}
    if args.back_camera:  # the tracker bridges the blind stretches between the two views
        own_env["tracker"] = preset_environment("several-cameras")
    if getattr(args, "laser", False):
        extra["laser"] = ("--laser", "front", *(("--static-map", str(static_map)) if static_map is not None else ()))
        names.append("laser")
    if args.no_static_map:  # nor from the ROS 2 robot's /map
        own_env.setdefault("tracker", {})["PERCEPTION_TRACKER__ROBUST__STATIC_MAP__TOPIC"] = "false"
    for name in names:
        command = name.partition("-")[0]  # detector-slow, localizer-back, ...: the service's command
        specs.append(ProcessSpec(name, _perception(command, *common, *extra[name]), {**env, **own_env.get(name, {})},
                                 restart="on-failure",
                                 backoff_initial_s=0.5, backoff_max_s=5.0, stop_timeout_s=5.0))
    if args.attention:
        specs.append(ProcessSpec("attention", _perception("attention", *common, "--target", "lock"), env,
                                 restart="on-failure", backoff_initial_s=0.5, backoff_max_s=5.0, stop_timeout_s=5.0))
    if args.ros2:
        specs.append(ProcessSpec("ros2", _perception("ros2", *common, "--domain-id", "0"), env,
                                 restart="on-failure", backoff_initial_s=0.5, backoff_max_s=5.0, stop_timeout_s=5.0))
    if args.view:
        shown = ("--static-map", str(static_map)) if static_map is not None else ()  # --ros2: /map's
        specs.append(ProcessSpec("viewer", _perception("view", *common, "--port", str(args.view_port), *shown), env,
                                 restart="on-failure", backoff_initial_s=0.5, backoff_max_s=5.0, stop_timeout_s=5.0))
    return specs


def _open_page(url: str) -> None:
    """Open ``url`` in the desktop's browser, only when there is a desktop (a text browser
    would take the terminal over)."""
    if os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY") or sys.platform == "darwin":
        import webbrowser

        webbrowser.open(url)


def _wait_alive(transport: Transport, keys: Keys, supervisor_thread: threading.Thread, shutdown: Shutdown,
                timeout: float, services: tuple[str, ...] = SERVICES) -> list[str]:
    """The services alive once all four are (or whatever is alive at the timeout)."""
    deadline = time.monotonic() + timeout
    alive: list[str] = []
    while time.monotonic() < deadline and supervisor_thread.is_alive() and not shutdown.is_set():
        alive = sorted({keys.parse_alive(k).service for k in transport.alive(keys.alive(), timeout=0.5)})
        if all(s in alive for s in services):
            return alive
        shutdown.wait(0.2)
    return alive


def main(args: argparse.Namespace) -> int:
    # The live view owns the terminal: the supervisor's and the session's info lines would
    # scroll it away (the children's own output goes to the log file).
    for name in ("tools.launcher", "common.transport.zenoh"):
        logging.getLogger(name).setLevel(logging.WARNING)
    if args.duration <= 0 or args.fps <= 0 or args.width < 64 or args.height < 48:
        raise CliError("--duration and --fps must be positive and the image at least 64x48")
    if args.ros2 and args.back_camera:
        raise CliError("--ros2 carries one camera (the head's, as the RealSense ROS 2 driver publishes it): drop --back-camera")
    log_dir = args.log_dir or Path(tempfile.mkdtemp(prefix="perception-demo-"))
    log_dir.mkdir(parents=True, exist_ok=True)
    port = free_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    robot = f"demo{os.getpid()}"
    keys = Keys(robot=robot)
    log_file = open(log_dir / "processes.log", "wb")  # noqa: SIM115
    # the robot's map of its home, as its laser drew it (--ros2: the robot's map server sends it on /map)
    static_map = None if args.no_static_map or args.ros2 else log_dir / "map.yaml"
    if static_map is not None:
        write_apartment_map(static_map)
    specs = _specs(endpoint, port, robot, args, log_dir / "id-memory.json", static_map)
    # CPU is reported per process (detector, detector-slow, detector-back, ...), not per service
    measured = [s.name for s in specs if s.name not in ("router", "viewer")]
    supervisor = Supervisor(specs, log_file, handle_signals=False)
    codes: list[int] = []
    sup_thread = threading.Thread(target=lambda: codes.append(supervisor.run()), name="supervisor", daemon=True)
    sim: subprocess.Popen[bytes] | None = None
    looked: AttentionLog | None = None
    echo: TrackedEcho | None = None
    print(wrap(f"starting the router and the services (log: {log_dir / 'processes.log'}) ..."), flush=True)
    with Shutdown() as shutdown:
        sup_thread.start()
        try:
            transport = open_transport(ZenohOptions(mode="client", connect=[endpoint], connect_timeout_s=30))
        except TransportError as exc:
            supervisor.request_stop()
            sup_thread.join(30)
            raise CliError(f"{exc} (see {log_dir / 'processes.log'})") from exc
        try:
            monitor = Monitor(transport, keys)
            gt = GroundTruthLog(transport, keys)
            wanted = (*SERVICES, *(("attention",) if args.attention else ()), *(("ros2",) if args.ros2 else ()),
                      *(("laser",) if args.laser else ()))
            echo = TrackedEcho(transport) if args.ros2 else None
            looked = AttentionLog(transport, keys, default_camera(args.width, args.height)) if args.attention else None
            alive = _wait_alive(transport, keys, sup_thread, shutdown, 60.0, wanted)
            if not all(s in alive for s in wanted):
                if shutdown.is_set():
                    return 130
                raise CliError(f"services did not come up (alive: {', '.join(alive) or 'none'}); see {log_dir / 'processes.log'}")
            sim = subprocess.Popen(
                _perception("simulate", "--scenario", args.scenario, "--duration", str(args.duration), "--seed", str(args.seed),
                            "--width", str(args.width), "--height", str(args.height), "--fps", str(args.fps),
                            "--connect", endpoint, "--robot", robot, *(("--head-control",) if args.attention else ()),
                            *(("--back-camera", args.back_camera) if args.back_camera else ()),
                            *(("--laser", "front") if args.laser else ()),
                            *(("--ros2",) if args.ros2 else ())),
                stdout=log_file, stderr=subprocess.STDOUT, start_new_session=True,
                env={**os.environ, "RUST_LOG": os.environ.get("RUST_LOG", "error")},
            )
            started = time.monotonic()
            page = f"\nthe live page: http://127.0.0.1:{args.view_port}/" if args.view else ""
            if args.view:
                print(f"the live page is on http://127.0.0.1:{args.view_port}/", flush=True)
                _open_page(f"http://127.0.0.1:{args.view_port}/")
            pids = {n: supervisor.pid(n) for n in measured}
            cpu_start = {n: (pid, _cpu_seconds(pid)) for n, pid in pids.items() if pid is not None}
            tty = sys.stdout.isatty() and not args.no_view
            last_line = 0.0
            while not shutdown.is_set():
                monitor.poll()
                gt.poll()
                if looked is not None:
                    looked.poll()
                if echo is not None:
                    echo.poll()
                elapsed = time.monotonic() - started
                if sim.poll() is not None and gt.idle_for(1.5):
                    break  # the scenario is over and the pipeline has drained
                if tty:
                    view = monitor.render(f"perception demo: {args.scenario}, {args.width}x{args.height} at {args.fps:g} fps, "
                                          f"{args.duration:g} s (Ctrl-C stops){page}", elapsed)
                    sys.stdout.write("\x1b[H\x1b[J" + view + "\n")
                    sys.stdout.flush()
                elif not args.no_view and time.monotonic() - last_line > 5:
                    last_line = time.monotonic()
                    n = sum(t.status == "confirmed" for t in monitor.latest_tracks.tracks) if monitor.latest_tracks else 0
                    print(f"{elapsed:6.1f} s: {monitor.meters['tracker'].count} track updates, {n} confirmed tracks", flush=True)
                shutdown.wait(0.5)
            monitor.poll()
            gt.poll()
            if echo is not None:
                echo.poll()
            wall = time.monotonic() - started
            cpu = {}
            for name, (pid, t0) in cpu_start.items():
                t1 = _cpu_seconds(pid)
                cpu[name] = round(100.0 * (t1 - t0) / wall, 1) if t0 is not None and t1 is not None else None
        finally:
            if sim is not None and sim.poll() is None:
                os.killpg(sim.pid, signal.SIGTERM)
                try:
                    sim.wait(10)
                except subprocess.TimeoutExpired:
                    os.killpg(sim.pid, signal.SIGKILL)
                    sim.wait()
            transport.close()
            supervisor.request_stop()
            sup_thread.join(60)
            log_file.close()
    plot = args.plot or log_dir / "tracks.png"
    several = args.second_detector or args.back_camera or args.laser
    report, table = score(gt, monitor, args.scenario, plot=plot, source="head" if several else None, width=WIDTH,
                          truth="around" if args.laser else "camera")
    if looked is not None:
        report["attention"] = looked.report()
    if echo is not None:
        report["ros2"] = echo.report()
    plotted = str(plot) if plot.is_file() else None
    if args.json:
        print(json.dumps({"scenario": args.scenario, "log": str(log_dir / "processes.log"), "plot": plotted,
                          "pipeline": monitor.summary(), "cpu_percent": cpu, **report}, indent=2))
    else:
        print(closing_text(monitor.render_summary(), table, log_dir, cpu,
                           [*((attention_line(report["attention"]),) if "attention" in report else ()),
                            *((echo.line(),) if echo is not None else ())], plotted))
    return 0
