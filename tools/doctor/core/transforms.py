"""Transforms: is ``map ← odom ← base_link ← … ← camera`` complete at the frames' stamps,
which edge is missing or stale, and are static transforms republished."""

from __future__ import annotations

from tools.doctor.core.facts import Check, EdgeFacts, Observation

__all__ = ["chain_check", "transform_checks"]

SECTION = "Transforms"
#: A dynamic edge whose newest stamp is this much older than the frames is stale (s).
STALE_S = 0.5
#: Watching this long without seeing tf_static (or seeing it once) is conclusive (s).
STATIC_WATCH_S = 2.5


def _setting(obs: Observation, service: str, name: str, default: str) -> str:
    values = [n.settings[name] for n in obs.running(service) if n.settings.get(name)]
    return values[0] if values else default


def _localizer_statics(obs: Observation) -> int:
    text = _setting(obs, "localizer", "static_transforms", "0")
    return int(text) if text.isdigit() else len(text.split(","))


def _localizes(obs: Observation) -> bool:
    """Whether the localizer publishes and drops nothing for want of a transform."""
    nodes = obs.running("localizer")
    return (bool(nodes) and all(n.counters.get("dropped_no_transform", 0) == 0 for n in nodes)
            and any(s.startswith("localized/") and f.count > 0 for s, f in obs.streams.items()))


def _camera_frames(obs: Observation) -> dict[str, int]:
    """camera frame id -> the newest stamp of the frames in it."""
    out: dict[str, int] = {}
    configured = _setting(obs, "localizer", "camera_frame", "")
    for frames in obs.frames.values():
        for f in frames:
            frame_id = f.frame_id or configured
            if frame_id:
                out[frame_id] = max(out.get(frame_id, 0), f.stamp_ns)
    return out


def chain_check(parents: dict[str, EdgeFacts], frame: str, stamp_ns: int, target: str, *, section: str = SECTION,
                what: str = "frames") -> tuple[Check, bool]:
    """(the line ``chain {target} ← {frame}``, whether the chain reaches ``target``): complete and
    fresh at ``stamp_ns`` (the newest of the ``what``), or where it stops and the edge to publish."""
    name = f"chain {target} ← {frame}"
    path, node = [frame], frame
    while node != target and node in parents and parents[node].parent not in path:
        node = parents[node].parent
        path.append(node)
    shown = " ← ".join(reversed(path))
    if node == target:
        stale = [(parents[c], (stamp_ns - parents[c].last_stamp_ns) / 1e9) for c in path[:-1]
                 if not parents[c].static]
        stale = [(e, lag) for e, lag in stale if lag > STALE_S]
        if stale:
            e, lag = max(stale, key=lambda item: item[1])
            return Check(section, name, "fail", f"{shown}, but {e.parent} → {e.child} is {lag:.1f} s older than the "
                         f"{what}", f"the publisher of {e.parent} → {e.child} lags or stopped: it must keep up with the "
                         f"{'camera' if what == 'frames' else what}'s stamps"), True
        return Check(section, name, "ok", f"{shown} at the {what}' stamps"), True
    children: dict[str, list[str]] = {}
    for e in parents.values():
        children.setdefault(e.parent, []).append(e.child)
    below, todo = [], [target]
    while todo:
        f = todo.pop()
        below.append(f)
        todo += [c for c in children.get(f, []) if c not in below]
    leaves = [f for f in below if not children.get(f)]
    if not parents:
        figure, fix = "no transform received", (f"publish {target} ← odom ← base_link ← … ← {frame} on tf (and the "
                                                "fixed ones on tf_static, about once a second)")
    else:
        start = f"no transform has {frame} as its child" if node == frame else f"{shown} stops at {node}"
        between = " → … → " if node == frame else " → "
        if not children.get(target):
            reach, gap = f"nothing hangs from {target}", f"{target}{between}{node}"
        elif len(leaves) == 1:
            reach, gap = f"the {target} side ends at {leaves[0]}", f"{leaves[0]}{between}{node}"
        else:
            reach, gap = f"the {target} side ends at {', '.join(sorted(leaves))}", f"one of those{between}{node}"
        figure = f"{start}; {reach}: missing {gap}"
        fix = f"publish {gap}: on tf stamped like the {what}, or, if it is fixed, on tf_static about once a second"
    return Check(section, name, "fail", figure, fix), False


def _chain(obs: Observation, parents: dict[str, EdgeFacts], camera: str, stamp_ns: int, target: str) -> Check:
    check, complete = chain_check(parents, camera, stamp_ns, target)
    if not complete and _localizes(obs):
        return Check(SECTION, check.name, "warn", check.figure + " (the localizer still has it, from earlier or its "
                     "config)", check.fix + "; a restarted localizer would miss it")
    return check


def _static(obs: Observation, complete: bool) -> Check:
    name = "static transforms"
    n, d = obs.stream("tf_static").count, obs.duration_s
    republish = ("republish static transforms about once a second (Zenoh keeps no latched topic, so a late "
                 "subscriber never gets a one-off), or list them in the localizer's static_transforms")
    if n >= 2:
        return Check(SECTION, name, "ok", f"tf_static {n} times in {d:.1f} s (every {d / n:.1f} s)")
    statics = _localizer_statics(obs)
    if n == 0 and statics:
        return Check(SECTION, name, "ok", f"none on tf_static; the localizer has {statics} in its config")
    if n == 0 and complete:
        return Check(SECTION, name, "ok", "none on tf_static, none needed: the chain is complete on tf")
    if d < STATIC_WATCH_S:
        return Check(SECTION, name, "warn", f"tf_static {n} times in {d:.1f} s: too short to tell",
                     "watch longer (--duration 5)")
    what = "tf_static published once" if n == 1 else "no tf_static"
    return Check(SECTION, name, "fail", f"{what} in {d:.1f} s", republish)


def transform_checks(obs: Observation) -> list[Check]:
    """One chain line per camera frame, then the static transforms line."""
    target = _setting(obs, "localizer", "target_frame", "map")
    parents = obs.parents()
    cameras = _camera_frames(obs)
    if not cameras:
        return [Check(SECTION, f"chain {target} ← camera", "fail", "no frame names its camera frame",
                      "set the frames' frame_id (or the localizer's camera_frame)"), _static(obs, False)]
    floor = set(obs.floor_camera_frames)
    out = [Check(SECTION, f"chain {target} ← {cam}", "ok", "none needed: placed on the floor by its homography")
           if cam in floor else _chain(obs, parents, cam, stamp, target) for cam, stamp in sorted(cameras.items())]
    if floor >= set(cameras):
        return out + [Check(SECTION, "static transforms", "ok", "none needed: every camera is placed on the floor by "
                                                                 "its homography")]
    return out + [_static(obs, all(c.status == "ok" for c in out))]
