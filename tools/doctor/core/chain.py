"""Clocks and the chain: how far the frames' stamps are from the receiving clock, and how
many frames pass each stage, frames → detections → localized → embeddings → tracks, with
the counted reason at the first stage that loses them."""

from __future__ import annotations

import numpy as np

from tools.doctor.core.facts import CHAIN, Check, Observation
from tools.doctor.core.reasons import reason_fix

__all__ = ["chain_checks", "clock_checks"]

#: Frames stamped this far from their arrival (s) warn, and fail beyond FAIL.
CLOCK_WARN_S, CLOCK_FAIL_S = 0.2, 1.0
#: Keys first seen this close to the end are still in flight and not judged (s).
SETTLE_S = 0.5
#: A stage passing less than this share of its input fails, less than WARN warns. The
#: detector takes the newest frame only, so it may skip frames by design: its floor is lower.
PASS_FAIL, PASS_WARN, DETECTOR_WARN = 0.5, 0.8, 0.25


def clock_checks(obs: Observation) -> list[Check]:
    """One line per camera: the median of (receive time - stamp) of its frames."""
    out = []
    replay = bool(obs.running("replay"))
    for cam in obs.cameras():
        offsets = obs.offsets_ns.get(cam, [])
        name = f"frame stamps ({cam})"
        if not offsets:
            out.append(Check("Clocks", name, "warn", "no frame to compare", "see the frames line"))
            continue
        med = float(np.median(offsets)) / 1e9
        if abs(med) < CLOCK_WARN_S:
            out.append(Check("Clocks", name, "ok", f"frames arrive {med * 1000:.0f} ms after their stamp (median)"))
            continue
        if med > 0:
            figure = f"frames are stamped {med:.1f} s before they arrive"
            fix = ("the camera PC's clock is behind this one, or its driver stamps late: synchronise the PCs' "
                   "clocks (chrony or NTP); a replay that publishes old stamps does the same")
        else:
            figure = f"frames are stamped {-med:.1f} s after they arrive (in the future)"
            fix = "the camera PC's clock is ahead of this one: synchronise the PCs' clocks (chrony or NTP)"
        if replay:
            out.append(Check("Clocks", name, "warn", figure + " while a replay runs",
                             "a replay publishes the recording's stamps: expected while replaying"))
            continue
        out.append(Check("Clocks", name, "fail" if abs(med) >= CLOCK_FAIL_S else "warn", figure, fix))
    return out


def _why(obs: Observation, node: str, source: str, camera: str) -> tuple[str, str]:
    """(the reason ``node`` passes on too little of ``source``, its fix)."""
    failed = obs.failed(node)
    up = obs.running(node)
    if failed and not up:
        return f"the {node} stopped: {failed[-1].error or 'no error line'}", f"fix the {node}'s error, then start it again"
    if not up:
        return f"no {node} is running", f"start it: perception {node}"
    source_key = f"{source}/{camera}"
    listens = sorted({k for n in up for k in n.subscribes if k.split("/", 1)[0] == source})
    if listens and source_key not in listens and not any(k.endswith("/*") for k in listens):
        return (f"the {node} listens to {', '.join(listens)}, not {source_key}",
                f"set the {node}'s camera to {camera} (--camera {camera}), or every other node's to its camera")
    drops: dict[str, float] = {}
    for n in up:
        for reason, count in n.drops().items():
            drops[reason] = drops.get(reason, 0) + count
    if drops:
        reason, count = max(drops.items(), key=lambda kv: kv[1])
        return f"{reason} ({count:g} dropped by the {node})", reason_fix(reason, node)
    if any(n.counters.get("invalid", 0) for n in up):
        return f"the {node} refuses its inputs as invalid", "see the stream lines"
    if node == "tracker" and any(n.counters.get("wrong_frame", 0) for n in up):
        return "wrong frame", reason_fix("wrong_frame", node)
    return f"no counted reason (the {node} may be busy)", f"see the {node}'s log"


def _stage_counts(obs: Observation, camera: str) -> tuple[dict[str, int], list[tuple[str, str, str, int, int]]]:
    """(keys seen per stream, [(stream, node, source, passed, eligible)]) of one camera."""
    stages = obs.stages.get(camera, {})
    cutoff = obs.end_ns - int(SETTLE_S * 1e9)
    counts = {stream: len(stages.get(stream, {})) for stream, _, _ in CHAIN}
    passes = []
    for stream, node, source in CHAIN[1:]:
        eligible = [k for k, t in stages.get(source, {}).items() if t <= cutoff]
        if stream == "tracks":
            # at a fixed output rate not every frame has its own Tracks message: a frame has
            # passed when tracks including it (up to its stamp) were published
            newest = max((k[0] for k in stages.get(stream, {})), default=None)
            passed = sum(1 for k in eligible if newest is not None and k[0] <= newest)
        else:
            passed = sum(1 for k in eligible if k in stages.get(stream, {}))
        passes.append((stream, node, source, passed, len(eligible)))
    return counts, passes


def chain_checks(obs: Observation) -> list[Check]:
    """One line per camera: the counts of every stage and the first stage that loses frames."""
    out = []
    for cam in obs.cameras():
        name = f"frames → tracks ({cam})"
        counts, passes = _stage_counts(obs, cam)
        figure = " → ".join(f"{stream} {counts[stream]}" for stream, _, _ in CHAIN)
        if counts["frames"] == 0:
            frames = obs.stream(f"frames/{cam}")
            why = (f"all {frames.count} frames are invalid" if frames.count and frames.invalid == frames.count
                   else "no frame arrives")
            out.append(Check("Chain", name, "fail", f"{figure}: {why}", "see the Camera and Streams lines"))
            continue
        verdict: Check | None = None
        for stream, node, source, passed, eligible in passes:
            if eligible == 0:
                continue
            share = passed / eligible
            low_fail, low_warn = (0.0, DETECTOR_WARN) if node == "detector" else (PASS_FAIL, PASS_WARN)
            if passed == 0 or share < low_fail or share < low_warn:
                why, fix = _why(obs, node, source, cam)
                status = "fail" if passed == 0 or share < low_fail else "warn"
                verdict = Check("Chain", name, status,
                                f"{figure}: {node} passes {passed} of {eligible} {source} ({share:.0%}): {why}", fix)
                break
        if verdict is None:
            verdict = _appearance(obs, name, figure)
        out.append(verdict)
    if obs.stages and not obs.boxes_total and not any(c.status == "fail" for c in out):
        out.append(Check("Chain", "people", "warn", f"no person detected in {obs.duration_s:.1f} s",
                         "if people are in view: check the Camera lines and the detector's backend"))
    return out


def _appearance(obs: Observation, name: str, figure: str) -> Check:
    """Every stage passes: are the tracks associated by appearance, or position-only?"""
    if obs.tracks_total and obs.position_only / obs.tracks_total > 0.5:
        share = obs.position_only / obs.tracks_total
        why, fix = "the tracker gets no usable embeddings", "see the Config lines"
        for n in obs.running("tracker"):
            for reason in ("wrong_model", "wrong_dimension", "late_embeddings"):
                if n.counters.get(f"dropped_{reason}", 0):
                    why, fix = f"{reason} ({n.counters[f'dropped_{reason}']:g} dropped)", reason_fix(reason, "tracker")
            if n.counters.get("no_thresholds", 0):
                why = "the tracker has no thresholds for the embedding model"
        return Check("Chain", name, "fail", f"{figure}, but {share:.0%} of the tracks are position-only: {why}", fix)
    return Check("Chain", name, "ok", figure)
