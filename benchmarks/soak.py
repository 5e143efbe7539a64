"""Soak benchmark: the demo pipeline for a long time, sampled every interval.

    python benchmarks/soak.py --duration 3600 [--fps 30] [--interval 60] [--kill-router-at S] [--json FILE] [--plot PNG]
    python benchmarks/soak.py --plot-only benchmarks/results/soak_3600s.json --plot docs/soak.png

Starts what `perception demo` starts (a router and the four services as supervised
processes, restarted on failure; the simulator feeding them at ``--fps``, 320x240 by
default, its people walking on after the scenario's script ends) and, every
``--interval`` seconds, samples each process's resident memory (RSS, and apart the shared
memory it maps: ``shmem_kib``) and CPU share from /proc (Linux), the services' counters from their status (received, published, dropped,
invalid and every ``dropped_*`` reason) and the tracker's ID memory size
(``ids_remembered``). ``--kill-router-at S`` SIGKILLs the router once, S seconds in, under
load: the launcher restarts it, and the time until tracks flow again is measured.

The summary checks the targets: RSS growth from minute 5 (or the first sample after it)
to the end at most 5 % in every process, no restarts (beyond the one router kill), no
drop by any service reason (``dropped_*``) other than the latest-only frame skips of
:data:`FRAME_SKIPS`, which are the design and are reported apart (``frame_skips``), and
the ID memory within its bound.
Exit status 1 when a target is missed.

``--plot PNG`` draws each process's RSS and CPU share over time, with the start of the
RSS-growth window and the router kill marked (matplotlib, the ``view`` extra);
``--plot-only JSON`` draws it from an earlier run's ``--json`` file without running.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from common.messages.keys import RELIABLE, Keys
from common.transport.router_process import free_port
from common.messages.schemas import ServiceStatus, Tracks
from common.transport.zenoh_config import ZenohOptions
from common.transport.zenoh import open_transport
from services.tracker.config import TrackerConfig
from tools.demo.main import SERVICES, _cpu_seconds, _perception, _specs
from tools.demo.main import add_arguments as add_demo_arguments
from tools.evaluation.plot import PlotUnavailable
from tools.launcher.supervisor import Supervisor

if TYPE_CHECKING:
    from matplotlib.figure import Figure

PROCESSES = ("router", *SERVICES)
#: RSS growth is measured from this time on by default (after warm-up).
GROWTH_FROM_S = 300.0


def rss_kib(pid: int, field: str = "VmRSS") -> int | None:
    """Resident memory of a process in KiB (Linux /proc), or None. ``field``: ``VmRSS`` (all
    of it) or ``RssShmem`` (the shared memory it maps, e.g. Zenoh's pools, which every process
    mapping a pool counts in full)."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith(f"{field}:"):
                return int(line.split()[1])
    except OSError:
        return None
    return None


def growth(samples: list[dict[str, Any]], name: str, from_s: float) -> float | None:
    """RSS growth (%) of process ``name`` from the first sample at or after ``from_s`` to the last."""
    series = [(s["t"], s["processes"][name]["rss_kib"]) for s in samples
              if s["processes"].get(name, {}).get("rss_kib")]
    later = [r for t, r in series if t >= from_s] or [r for _, r in series]
    if len(later) < 2:
        return None
    return 100.0 * (later[-1] - later[0]) / later[0]


#: The services' dropped_* reasons that are latest-only frame skips by design, which the
#: target allows: the detector's frames overwritten in its ring of one before it took them;
#: the embedder's work on a frame older than ``max_lag_s`` behind the newest (shed, not queued);
#: the localizer's detections whose depth frame its latest-only ring no longer holds.
FRAME_SKIPS: dict[str, frozenset[str]] = {
    "detector": frozenset({"dropped_stale"}),
    "embedder": frozenset({"dropped_stale"}),
    "localizer": frozenset({"dropped_no_depth_frame"}),
}


def split_drops(final: dict[str, dict[str, Any]]) -> tuple[dict[str, dict[str, float]], dict[str, dict[str, float]]]:
    """(drops, frame skips) by process from the last sample's ``drops``: the reasons in
    :data:`FRAME_SKIPS` are skips, every other one a drop against the target."""
    lost: dict[str, dict[str, float]] = {}
    skipped: dict[str, dict[str, float]] = {}
    for name, p in final.items():
        for reason, n in (p.get("drops") or {}).items():
            (skipped if reason in FRAME_SKIPS.get(name, ()) else lost).setdefault(name, {})[reason] = n
    return lost, skipped


def drops(status: ServiceStatus) -> dict[str, float]:
    """The service's own drops by reason (``dropped_*``: stale, unpaired, late, overflow of
    a join...). A subscription's latest-only skips are not among them: they count in the
    status's ``dropped`` total only, with its FIFO overflows."""
    return {k: v for k, v in status.extra.items() if k.startswith("dropped_") and v}


def router_kill_time(data: dict[str, Any]) -> float | None:
    """Seconds into the run the router was killed: the summary's ``router_killed_at_s``, or,
    in files written before it was recorded, the time of the last sample before the router's
    restart count rose (the kill came at most one interval after it)."""
    summary = data.get("summary", {})
    if summary.get("router_killed_at_s") is not None:
        return float(summary["router_killed_at_s"])
    before: float | None = None
    for s in data.get("samples", []):
        router = s["processes"].get("router", {})
        if router.get("restarts"):
            return before
        before = float(s["t"])
    return None


def soak_figure(data: dict[str, Any]) -> Figure:
    """A matplotlib ``Figure`` of a soak run (``--json``'s content: summary and samples).

    Two panels over the run's minutes: each process's RSS (MiB), labelled with its growth
    over the window, and its CPU share (% of one core) between samples. A dashed line marks
    the start of the RSS-growth window, a red one the router kill. A missing sample (a
    process down at that moment) leaves a gap. Raises ``PlotUnavailable`` without matplotlib.
    """
    try:
        from matplotlib.figure import Figure
    except ImportError as exc:
        raise PlotUnavailable("the plot needs matplotlib: pip install 'people-perception[view]'") from exc
    samples, summary = data["samples"], data.get("summary", {})
    if not samples:
        raise ValueError("no samples to plot")
    minutes = [s["t"] / 60.0 for s in samples]
    names = [n for n in PROCESSES if any(n in s["processes"] for s in samples)]
    names += sorted({n for s in samples for n in s["processes"]} - set(names))
    growth_from = float(summary.get("growth_from_s", GROWTH_FROM_S))
    grown = summary.get("rss_growth_percent", {})

    def series(name: str, field: str, scale: float = 1.0) -> list[float]:
        return [math.nan if (v := s["processes"].get(name, {}).get(field)) is None else v / scale for s in samples]

    fig = Figure(figsize=(9.0, 6.2), layout="constrained")
    rss_ax, cpu_ax = fig.subplots(2, 1, sharex=True)
    for i, name in enumerate(names):
        colour = f"C{i}"
        g = grown.get(name)
        label = name if g is None else f"{name} ({g:+.1f} %)"
        rss_ax.plot(minutes, series(name, "rss_kib", 1024.0), color=colour, lw=1.5, marker=".", ms=3, label=label)
        cpu_ax.plot(minutes, series(name, "cpu_percent"), color=colour, lw=1.2, marker=".", ms=3)
    kill = router_kill_time(data)
    for ax in (rss_ax, cpu_ax):
        ax.axvline(growth_from / 60.0, color="0.3", ls="--", lw=1.0,
                   label=f"minute {growth_from / 60.0:g}: RSS growth measured from here" if ax is rss_ax else None)
        if kill is not None:
            ax.axvline(kill / 60.0, color="#d62728", ls=":", lw=1.5,
                       label=f"router killed (minute {kill / 60.0:.0f})" if ax is rss_ax else None)
        ax.grid(True, lw=0.3)
        ax.set_ylim(bottom=0)
    rss_ax.set_ylabel("RSS (MiB)")
    rss_ax.legend(fontsize=7, loc="lower right", ncols=2, title_fontsize=7,
                  title=f"process (RSS growth, minute {growth_from / 60.0:g} to the end)")
    cpu_ax.set_ylabel("CPU (% of one core)")
    cpu_ax.set_xlabel("minutes")
    cpu_ax.set_title("CPU share between samples (colours as above)", fontsize=8)
    title = "Soak: RSS and CPU per process"
    if "duration_s" in summary and "fps" in summary:
        size = summary.get("size")
        title += f", {summary['duration_s'] / 60:g} min at {summary['fps']:g} fps" + (f", {size[0]}x{size[1]}" if size else "")
    fig.suptitle(title, fontsize=10)
    return fig


def plot_soak(data: dict[str, Any], out: Path) -> Path:
    """Draw :func:`soak_figure` of ``data`` into the PNG ``out``; returns its path."""
    fig = soak_figure(data)
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=100)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--duration", type=float, default=3600.0, metavar="S", help="seconds to run (default 3600)")
    ap.add_argument("--interval", type=float, default=60.0, metavar="S", help="seconds between samples (default 60)")
    ap.add_argument("--fps", type=float, default=30.0)
    ap.add_argument("--width", type=int, default=320)
    ap.add_argument("--height", type=int, default=240)
    ap.add_argument("--scenario", default="still")
    ap.add_argument("--kill-router-at", type=float, default=None, metavar="S",
                    help="SIGKILL the router once, S seconds in, and time the recovery")
    ap.add_argument("--growth-from", type=float, default=GROWTH_FROM_S, metavar="S",
                    help="RSS growth is measured from this time on (default 300 s: after warm-up)")
    ap.add_argument("--json", type=Path, default=None, metavar="FILE", help="write every sample and the summary")
    ap.add_argument("--plot", type=Path, default=None, metavar="PNG",
                    help="draw RSS and CPU per process over time (needs matplotlib, the 'view' extra)")
    ap.add_argument("--plot-only", type=Path, default=None, metavar="JSON",
                    help="no run: draw --plot from an earlier run's --json file")
    args = ap.parse_args()
    if args.plot_only is not None:
        if args.plot is None:
            ap.error("--plot-only needs --plot PNG")
        try:
            print(f"wrote {plot_soak(json.loads(args.plot_only.read_text()), args.plot)}")
        except (OSError, ValueError, KeyError, PlotUnavailable) as exc:
            print(f"soak.py: cannot plot {args.plot_only}: {exc}", file=sys.stderr)
            return 2
        return 0
    if args.duration <= 0 or args.interval <= 0:
        ap.error("--duration and --interval must be positive")

    log_dir = Path(tempfile.mkdtemp(prefix="perception-soak-"))
    port = free_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    robot = f"soak{os.getpid()}"
    keys = Keys(robot=robot)
    demo_parser = argparse.ArgumentParser()
    add_demo_arguments(demo_parser)
    demo_args = demo_parser.parse_args([])  # the demo's defaults: depth detector, no page, no attention
    log_file = open(log_dir / "processes.log", "wb")  # noqa: SIM115
    memory = log_dir / "id-memory.npz"
    supervisor = Supervisor(_specs(endpoint, port, robot, demo_args, memory), log_file, handle_signals=False)
    sup_thread = threading.Thread(target=supervisor.run, name="supervisor", daemon=True)
    sup_thread.start()
    transport = open_transport(ZenohOptions(mode="client", connect=[endpoint], connect_timeout_s=30))
    tracks = transport.subscribe(keys.tracks(), Tracks, RELIABLE)
    print(f"# Soak: {args.duration:g} s at {args.fps:g} fps, {args.width}x{args.height}, scenario {args.scenario}; "
          f"log {log_dir / 'processes.log'}", flush=True)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        alive = {keys.parse_alive(k).service for k in transport.alive(keys.alive(), timeout=0.5)}
        if all(s in alive for s in SERVICES):
            break
    sim = subprocess.Popen(
        _perception("simulate", "--scenario", args.scenario, "--duration", str(args.duration + 30), "--fps",
                    str(args.fps), "--width", str(args.width), "--height", str(args.height), "--connect", endpoint,
                    "--robot", robot), stdout=log_file, stderr=subprocess.STDOUT, start_new_session=True,
        env={**os.environ, "RUST_LOG": "error"})
    started = time.monotonic()
    samples: list[dict[str, Any]] = []
    cpu_prev: dict[str, tuple[int, float | None, float]] = {}
    last_tracks = time.monotonic()
    recovery_s: float | None = None
    killed_at: float | None = None
    next_sample = started
    try:
        while (now := time.monotonic()) - started < args.duration:
            while (got := tracks.try_recv()) is not None:
                last_tracks = time.monotonic()
                if killed_at is not None and recovery_s is None and got.msg.header.stamp_ns:
                    recovery_s = last_tracks - killed_at
            if args.kill_router_at is not None and killed_at is None and now - started >= args.kill_router_at:
                pid = supervisor.pid("router")
                if pid:
                    os.kill(pid, signal.SIGKILL)
                    killed_at = time.monotonic()
                    print(f"{now - started:7.0f} s: router (pid {pid}) killed", flush=True)
            if now >= next_sample:
                next_sample += args.interval
                statuses = {m.name: m for _, m in transport.query(keys.status(), timeout=2.0)
                            if isinstance(m, ServiceStatus)}
                procs: dict[str, Any] = {}
                for name in PROCESSES:
                    pid = supervisor.pid(name)
                    cpu_s = _cpu_seconds(pid) if pid else None
                    prev = cpu_prev.get(name)
                    share = None
                    if prev and prev[0] == pid and prev[1] is not None and cpu_s is not None and now > prev[2]:
                        share = round(100.0 * (cpu_s - prev[1]) / (now - prev[2]), 1)
                    cpu_prev[name] = (pid or 0, cpu_s, now)
                    st = statuses.get(name)
                    procs[name] = {
                        "pid": pid, "rss_kib": rss_kib(pid) if pid else None,
                        "shmem_kib": rss_kib(pid, "RssShmem") if pid else None, "cpu_percent": share,
                        "restarts": supervisor.restarts(name),
                        **({"received": st.received, "published": st.published, "dropped": st.dropped,
                            "invalid": st.invalid, "drops": drops(st), "extra": st.extra} if st else {}),
                    }
                sample = {"t": round(now - started, 1), "processes": procs,
                          "tracks_age_s": round(time.monotonic() - last_tracks, 2)}
                samples.append(sample)
                mem = procs["tracker"].get("extra", {}).get("ids_remembered")
                print(f"{sample['t']:7.0f} s: " + ", ".join(
                    f"{n} {p['rss_kib'] / 1024 if p['rss_kib'] else 0:.0f} MiB {p['cpu_percent'] or 0:.0f}%"
                    for n, p in procs.items()) + f"; ids remembered {mem}", flush=True)
            time.sleep(0.05)
    finally:
        if sim.poll() is None:
            os.killpg(sim.pid, signal.SIGTERM)
            sim.wait(10)
        transport.close()
        supervisor.request_stop()
        sup_thread.join(60)
        log_file.close()

    limit = TrackerConfig().max_remembered_ids
    final = samples[-1]["processes"] if samples else {}
    restarts = {n: p["restarts"] for n, p in final.items() if p["restarts"]}
    expected_restarts = {"router": 1} if killed_at is not None else {}
    all_drops, frame_skips = split_drops(final)
    grown = {n: growth(samples, n, args.growth_from) for n in PROCESSES}
    remembered = final.get("tracker", {}).get("extra", {}).get("ids_remembered")
    summary = {
        "machine": f"{platform.node()}, {os.cpu_count()} cores, {platform.machine()}, Python {platform.python_version()}",
        "duration_s": args.duration, "fps": args.fps, "size": [args.width, args.height], "scenario": args.scenario,
        "rss_growth_percent": {n: None if g is None else round(g, 2) for n, g in grown.items()},
        "restarts": restarts, "drops": all_drops, "frame_skips": frame_skips, "ids_remembered": remembered, "max_remembered_ids": limit,
        "router_kill_recovery_s": None if recovery_s is None else round(recovery_s, 2),
        "router_killed_at_s": None if killed_at is None else round(killed_at - started, 1),
        "growth_from_s": args.growth_from, "interval_s": args.interval,
        "ok": {
            "rss_growth": all(g is None or g <= 5.0 for g in grown.values()),
            "restarts": restarts == expected_restarts,
            "drops": not all_drops,
            "id_memory": remembered is None or remembered <= limit,
            **({"router_recovery": recovery_s is not None and recovery_s <= 2.0} if killed_at is not None else {}),
        },
    }
    print("\n" + json.dumps(summary, indent=2))
    if args.json:
        args.json.write_text(json.dumps({"summary": summary, "samples": samples}, indent=1))
    if args.plot:
        try:
            print(f"plot: {plot_soak({'summary': summary, 'samples': samples}, args.plot)}")
        except (ValueError, PlotUnavailable) as exc:
            print(f"no plot: {exc}", file=sys.stderr)
    return 0 if all(summary["ok"].values()) else 1


if __name__ == "__main__":
    sys.exit(main())
