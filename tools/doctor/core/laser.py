"""Laser: does each 2-D laser's ``scans/{laser}`` arrive at a sane rate, with stamps that advance
and beams that see something, and does its frame reach the map (or at least odom) through the
transforms, so that ``perception laser`` can place the legs it finds."""

from __future__ import annotations

from tools.doctor.core.facts import Check, NodeFacts, Observation, ScanFacts
from tools.doctor.core.transforms import chain_check

__all__ = ["MAX_HZ", "MIN_HZ", "SECTION", "laser_checks", "ros2_scan_topics"]

SECTION = "Laser"
#: Below this a walking person moves more than half a metre between scans: the leg tracker's
#: gate loses them (2-D scanners send 5-40 Hz). Above MAX_HZ the scans are not one scanner's.
MIN_HZ, MAX_HZ = 2.0, 100.0
#: Scans arriving at less than this share of the rate the scanner states (its scan_time) are lost
#: on the way.
LOST_SHARE = 0.5
#: A laser whose beams come back without a return this often sees nothing.
BLIND_SHARE = 0.95
#: The frame a laser's people can at least be related to while map is missing.
ODOM = "odom"


def ros2_scan_topics(node: NodeFacts) -> dict[str, str]:
    """laser name -> ROS topic, from a ros2 node's ``scans`` setting (``/scan:front,/rear/scan:rear``)."""
    out = {}
    for item in node.settings.get("scans", "").split(","):
        topic, _, name = item.strip().partition(":")
        if topic:
            out[name or "front"] = topic
    return out


def _laser_nodes(obs: Observation, laser: str) -> list[NodeFacts]:
    return [n for n in obs.running("laser") if n.settings.get("laser", "front") == laser]


def _feeder(obs: Observation, laser: str) -> str:
    """Where the scans of ``laser`` should come from, as a fix."""
    for node in obs.running("ros2"):
        topic = ros2_scan_topics(node).get(laser)
        if topic:
            return (f"the ros2 node reads {topic} for it: is the laser driver publishing {topic} (ros2 topic hz "
                    f"{topic})? see the ROS 2 lines")
    if obs.running("ros2"):
        return (f"add the laser's topic to the ros2 node's scans (scans: [/scan:{laser}], or --scan /scan:{laser}), "
                "or set the laser node's --laser to a laser the ros2 node reads")
    return (f"publish the laser's scans on scans/{laser}: perception ros2 reads sensor_msgs/LaserScan (scans: "
            f"[/scan:{laser}]); perception replay and perception simulate publish them too")


def _rate(obs: Observation, laser: str, s: ScanFacts | None) -> Check:
    key = f"scans/{laser}"
    d = obs.duration_s
    stream = obs.stream(key)
    if s is None or s.count == 0:
        if stream.count and stream.invalid == stream.count:
            return Check(SECTION, key, "fail", f"{stream.invalid} of {stream.count} payloads invalid: {stream.error}",
                         "the publisher sends scans the laser node refuses: run one version of the project everywhere")
        return Check(SECTION, key, "fail", f"nothing in {d:.1f} s, and perception laser reads it", _feeder(obs, laser))
    arrived = s.count / d if d > 0 else 0.0
    stated = 1.0 / s.scan_time_s if s.scan_time_s > 0 else 0.0
    figure = (f"{arrived:.1f} Hz ({s.beams} beams" + (f", the scanner says {stated:.0f} Hz" if stated else "")
              + f", {s.no_return:.0%} without return)")
    if s.count < 2:
        return Check(SECTION, key, "warn", f"one scan in {d:.1f} s: too few to tell its rate",
                     "watch longer (--duration 5), or see why the scanner sends so few")
    if stream.invalid:
        return Check(SECTION, key, "fail", f"{stream.invalid} of {stream.count} payloads invalid: {stream.error}",
                     "the publisher sends scans the laser node refuses: run one version of the project everywhere")
    if s.backwards:
        return Check(SECTION, key, "warn", f"{figure}; {s.backwards} scans stamped at or before the one before",
                     "two drivers publish on one topic, or a recording loops: one publisher per laser, stamped by "
                     "the time of each scan")
    if arrived < MIN_HZ:
        return Check(SECTION, key, "warn", f"{figure}: below {MIN_HZ:g} Hz a walking person moves over half a metre "
                     "between scans", "run the scanner at 10 Hz or more (its driver's frequency setting), and check "
                     "that nothing on the way drops scans")
    if arrived > MAX_HZ:
        return Check(SECTION, key, "warn", f"{figure}: more than one scanner's rate",
                     f"several drivers publish scans/{laser}: give each laser its own name (perception ros2's "
                     "scans: [/front/scan:front, /rear/scan:rear])")
    if stated and arrived < LOST_SHARE * stated:
        return Check(SECTION, key, "warn", f"{figure}: {1 - arrived / stated:.0%} of the scans are lost on the way",
                     "a best-effort topic over a weak link, or a node that falls behind: bring the ros2 node near the "
                     "scanner (the same machine or wired), or lower the scanner's rate")
    if s.no_return >= BLIND_SHARE:
        return Check(SECTION, key, "warn", f"{figure}: the laser sees almost nothing",
                     "is the scanner covered or facing the sky? check its range_min and range_max (a range_max below "
                     "the room's size reads every wall as no return)")
    return Check(SECTION, key, "ok", figure + "".join(f" from {p}" for p in _producers(obs, key)))


def _producers(obs: Observation, key: str) -> list[str]:
    who = sorted({n.service for n in obs.nodes if key in n.publishes and n.state == "running"})
    return [", ".join(who)] if who else []


def _chain(obs: Observation, laser: str, s: ScanFacts | None) -> list[Check]:
    nodes = _laser_nodes(obs, laser)
    target = next((n.settings["target_frame"] for n in nodes if n.settings.get("target_frame")), "map")
    configured = next((n.settings["laser_frame"] for n in nodes if n.settings.get("laser_frame")), "")
    frames = [f for f in (s.frame_ids if s else []) if f] or ([configured] if configured else [])
    if s is not None and s.count and "" in s.frame_ids and not configured:
        return [Check(SECTION, f"chain {target} ← {laser}", "fail", f"the scans of {laser} name no frame",
                      "set the laser driver's frame_id (e.g. laser), or the laser node's laser_frame")]
    stamp = s.last_stamp_ns if s else obs.end_ns
    parents = obs.parents()
    out = []
    for frame in frames:
        check, complete = chain_check(parents, frame, stamp, target, section=SECTION, what="scans")
        if not complete and target != ODOM:
            to_odom, reaches = chain_check(parents, frame, stamp, ODOM, section=SECTION, what="scans")
            if reaches and to_odom.status == "ok":
                shown = to_odom.figure.removesuffix(" at the scans' stamps")
                placed = ": the laser node places no one" if nodes else ""
                check = Check(SECTION, check.name, "fail" if nodes else "warn",
                              f"{shown}, but nothing links {ODOM} to {target}{placed}",
                              f"publish {target} → {ODOM} (the robot's localization: AMCL, slam_toolbox), or set the "
                              f"laser node's target_frame: {ODOM} and the tracker's frame_id to match")
        out.append(check)
    return out


def laser_checks(obs: Observation) -> list[Check]:
    """Per laser in play (scans seen, or a laser node reading it): its rate line and the chain
    from its frame to the laser node's target frame. Nothing when there is no laser."""
    lasers = sorted(set(obs.scans) | {n.settings.get("laser", "front") for n in obs.running("laser")}
                    | {k.split("/", 1)[1] for k in obs.streams if k.startswith("scans/") and "/" in k})
    out: list[Check] = []
    for laser in lasers:
        s = obs.scans.get(laser)
        out.append(_rate(obs, laser, s))
        out += _chain(obs, laser, s)
    return out
