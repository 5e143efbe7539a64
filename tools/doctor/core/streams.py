"""Streams: is each expected key alive and at what rate, who publishes it, which nodes run,
and which of them drop or refuse what they receive."""

from __future__ import annotations

from tools.doctor.core.facts import NODES, Check, NodeFacts, Observation
from tools.doctor.core.reasons import reason_fix

__all__ = ["node_checks", "position_only_text", "stream_checks"]

SECTION = "Streams"
#: stream -> the node that publishes it ("" for the robot's own drivers).
PRODUCER = {"frames": "", "detections": "detector", "localized": "localizer", "embeddings": "embedder",
            "tracks": "tracker", "tf": ""}
#: node -> the streams that feed it (the inputs its drops are counted against).
INPUT = {"detector": ("frames",), "localizer": ("detections",), "embedder": ("detections",),
         "tracker": ("localized", "embeddings")}
#: The tracker's counters of frames tracked without appearance, shown next to a failed node.
POSITION_ONLY = ("position_only_frames", "position_only_timeout")
#: A node dropping this share of its input fails the check; above WARN_SHARE it is a warning.
FAIL_SHARE, WARN_SHARE = 0.3, 0.05


def publishers(obs: Observation, key: str) -> list[str]:
    """The services whose status says they publish ``key``."""
    return sorted({n.service for n in obs.nodes if key in n.publishes and n.state == "running"})


def position_only_text(obs: Observation) -> str:
    """The tracker's position-only counters (``position_only_frames=120``), or ''."""
    return ", ".join(f"{k}={n.counters.get(k, 0):g}" for n in obs.running("tracker") for k in POSITION_ONLY)


def _elsewhere(obs: Observation) -> tuple[str, str] | None:
    """Nodes alive under another robot name or key prefix: what a name mismatch looks like."""
    if not obs.other_robots:
        return None
    names = "; ".join(f"{base} ({', '.join(services)})" for base, services in obs.other_robots.items())
    base = next(iter(obs.other_robots))
    parts = base.split("/")
    fix = f"use --robot {parts[-1]}" + (f" --key-prefix {'/'.join(parts[:-1])}" if parts[:-1] != ["pp"] else "")
    return names, f"the nodes run under another name: {fix} (or set that robot name on every node)"


def _silent(obs: Observation, key: str, producer: str) -> tuple[str, str]:
    """(why nothing arrived on ``key``, the fix)."""
    d = obs.duration_s
    if (other := _elsewhere(obs)) is not None and not obs.nodes:
        return f"nothing in {d:.1f} s here, but traffic under {other[0]}", other[1]
    stream, _, camera = key.partition("/")
    if not producer:
        if stream == "frames":
            for node in obs.running("camera"):
                if node.settings.get("camera", camera) == camera and node.counters.get("connected", 1) == 0:
                    lost = node.counters.get("stream_lost", 0)
                    return (f"nothing in {d:.1f} s: the camera node lost its source {node.settings.get('source', '')!r}"
                            f" (stream_lost {lost:g}, reopen_failed {node.counters.get('reopen_failed', 0):g})",
                            "check the camera's cable and power, or the stream's server; the node reopens it by "
                            "itself with backoff")
            fix = (f"start the camera driver (or perception simulate / replay) publishing frames/{camera}, "
                   "and check it uses this robot's name")
            return f"nothing in {d:.1f} s", fix
        return f"nothing in {d:.1f} s", "publish the robot's transforms on tf (odometry, localization)"
    failed = obs.failed(producer)
    if failed:
        return (f"nothing in {d:.1f} s: the {producer} stopped ({failed[0].error or 'no error line'})",
                f"fix the {producer}'s error, then start it again")
    if not obs.running(producer):
        return f"nothing in {d:.1f} s: no {producer} is running", f"start it: perception {producer} (or perception launch)"
    cameras = [camera] if camera else obs.cameras()
    for source in INPUT[producer]:
        for inp in (obs.stream(f"{source}/{c}") for c in cameras):
            if inp.count == 0:
                return f"nothing in {d:.1f} s: its input {inp.key} carries nothing", f"see the {inp.key} line"
            if inp.invalid == inp.count:
                return f"nothing in {d:.1f} s: its input {inp.key} is all invalid", f"see the {inp.key} line"
    return (f"nothing in {d:.1f} s although the {producer} runs",
            "see the Chain line for where the frames stop")


def _stream(obs: Observation, key: str, producer: str) -> Check:
    s = obs.stream(key)
    who = publishers(obs, key) or ([producer] if producer else ["the robot's drivers"])
    if s.count == 0 and key == "tf" and obs.stream("tf_static").count:
        return Check(SECTION, key, "ok", "nothing: every transform comes on tf_static (a fixed camera)")
    if s.count == 0 and key == "tf" and obs.only_floor_cameras():
        return Check(SECTION, key, "ok", "nothing, none needed: every camera is placed on the floor by its homography")
    if s.count == 0:
        figure, fix = _silent(obs, key, producer)
        return Check(SECTION, key, "fail", figure, fix)
    if s.invalid:
        fix = ("the camera driver sends frames the nodes refuse: see the Camera lines" if key.startswith("frames/")
               else f"{' and '.join(who)} send payloads the receivers refuse: run one version of the project everywhere")
        return Check(SECTION, key, "fail", f"{s.invalid} of {s.count} payloads invalid: {s.error}", fix)
    return Check(SECTION, key, "ok", f"{s.rate_hz(obs.duration_s):.1f} Hz from {', '.join(who)}")


def stream_checks(obs: Observation) -> list[Check]:
    """One line per expected key: the chain's streams of every camera, tracks and tf."""
    out = []
    for camera in obs.cameras():
        for stream in ("frames", "detections", "localized", "embeddings"):
            out.append(_stream(obs, f"{stream}/{camera}", PRODUCER[stream]))
    out.append(_stream(obs, "tracks", "tracker"))
    out.append(_stream(obs, "tf", ""))
    return out


def _node(obs: Observation, service: str) -> Check:
    failed, up = obs.failed(service), obs.running(service)
    if failed and not up:
        f = failed[-1]
        status = f"exit status {f.exit_status}" if f.exit_status is not None else "stopped"
        po = position_only_text(obs)
        figure = f"FAILED ({status}, not restarted): {f.error or 'no error line'}" + (
            f"; tracker {po} while watched" if po and service != "tracker" else "")
        return Check(SECTION, service, "fail", figure, f"fix what the error says, then start the {service} again")
    if not up:
        gone = [n for n in obs.nodes if n.service == service and n.alive is False]
        if gone:
            return Check(SECTION, service, "fail", "stopped while the doctor watched",
                         f"see the {service}'s log; perception launch restarts it unless it exited with status 2")
        if obs.source == "recording":  # no liveliness, only the statuses recorded
            return Check(SECTION, service, "warn", "no status of it in the recording",
                         "record with the services running, or record the status keys too")
        return Check(SECTION, service, "fail", "not running", f"start it: perception {service} (or perception launch)")
    hosts = ", ".join(sorted({n.host or "?" for n in up}))
    uptime = min(n.uptime_s for n in up)
    many = f"{len(up)} instances" if len(up) > 1 else "running"
    status = "warn" if len(up) > 1 else "ok"
    fix = f"stop all but one {service} of this robot: each publishes the same keys" if len(up) > 1 else ""
    return Check(SECTION, service, status, f"{many} on {hosts}, up {uptime:.0f} s", fix)


def _input_count(obs: Observation, service: str) -> int:
    return sum(len(stages.get(stream, {})) for stages in obs.stages.values() for stream in INPUT.get(service, ()))


def _drops(obs: Observation, node: NodeFacts) -> Check | None:
    invalid = node.counters.get("invalid", 0)
    drops = node.drops()
    if not invalid and not drops:
        return None
    name = f"{node.service} drops"
    if invalid:
        return Check(SECTION, name, "fail", f"{invalid:g} invalid payloads refused",
                     "a publisher sends what this node cannot decode: see the stream lines")
    n_in = max(1, _input_count(obs, node.service))
    reason, worst = max(drops.items(), key=lambda kv: kv[1])
    share = worst / n_in
    figure = ", ".join(f"{r} {v:g}" for r, v in sorted(drops.items(), key=lambda kv: -kv[1])) + (
        f" of {n_in} inputs" if node.service in INPUT else "")
    if node.window_s == 0:
        figure += " (since it started)"
    status = "fail" if share >= FAIL_SHARE else "warn" if share > WARN_SHARE else "ok"
    return Check(SECTION, name, status, figure, "" if status == "ok" else reason_fix(reason, node.service))


def node_checks(obs: Observation) -> list[Check]:
    """One line per pipeline node (running, failed or absent), one per other failed
    service, and one per node that drops or refuses inputs."""
    out = [_node(obs, s) for s in NODES]
    for f in obs.failed():
        if f.service not in NODES:
            out.append(Check(SECTION, f.service, "fail", f"FAILED (exit status {f.exit_status}): {f.error}",
                             f"fix what the error says, then start the {f.service} again"))
    for node in obs.nodes:
        if node.service == "ros2":
            continue  # its unreadable ROS 2 input is named in the ROS 2 section
        if node.state == "running" and node.alive is not False and (check := _drops(obs, node)) is not None:
            out.append(check)
    return out
