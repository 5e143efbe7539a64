"""Collect the simulator's ground truth and score the tracker's output with ``evaluate``.

Frames are matched on the source frame's ``seq``: the simulator's ground truth and the
tracker's ``Tracks`` both carry the camera frame's header. A ``Tracks`` whose stamp is a
ground-truth frame's is taken as that frame's whatever its ``seq`` (a frame that came through
ROS 2 is numbered by the ``ros2`` node, not by the simulator). Only the people the simulator
marks as ``counted`` (in view and visible enough) are ground-truth objects; a frame the
tracker published nothing for counts all its objects as misses.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import Any, Literal

import numpy as np

from common.messages.keys import Delivery, Keys
from common.messages.schemas import PeopleGroundTruth, PersonGroundTruth, Tracks, TrackState
from common.transport.base import Transport
from tools.demo.monitor import Monitor
from tools.evaluation.evaluate import evaluate_tables, format_table, make_report
from tools.evaluation.identity import Identity, IdentityCollector
from tools.evaluation.metrics import FrameEvents
from tools.evaluation.plot import PlotUnavailable, SequencePlot, plot_sequences
from tools.evaluation.readers import TrackTable

__all__ = ["GroundTruthLog", "frame_outputs", "identity_line", "pose_scores", "score", "score_rows", "score_tracks"]

_POSTURES = ("standing", "sitting", "lying")

log = logging.getLogger(__name__)


class GroundTruthLog:
    """Every ground-truth message of the run, by frame seq."""

    def __init__(self, transport: Transport, keys: Keys) -> None:
        self._sub = transport.subscribe(keys.groundtruth(), PeopleGroundTruth,
                                        Delivery(latest=False, queue=4096, congestion="block"))
        self.frames: dict[int, PeopleGroundTruth] = {}
        self._last_arrival = time.monotonic()

    def poll(self) -> None:
        while (got := self._sub.try_recv()) is not None:
            self.frames[got.msg.header.seq] = got.msg
            self._last_arrival = time.monotonic()

    def idle_for(self, seconds: float) -> bool:
        return time.monotonic() - self._last_arrival >= seconds


def _table(rows: list[tuple[int, int, np.ndarray]]) -> TrackTable:
    if not rows:
        return TrackTable.from_arrays(np.zeros(0, int), np.zeros(0, int), np.zeros((0, 3)))
    frames, ids, pos = zip(*rows)
    return TrackTable.from_arrays(np.array(frames), np.array(ids), np.stack(pos))


def frame_outputs(tracks: list[Tracks], source: str | None = None) -> list[Tracks]:
    """One ``Tracks`` per frame seq, the first published: a late input (a slow second detector's
    frame) makes the tracker rewind and publish the frames after it again, and what a consumer
    had at the time is what counts. ``source``: only the outputs of that stream's frames (the
    camera the ground truth's seq counts)."""
    first: dict[int, Tracks] = {}
    for t in tracks:
        if source is None or t.header.source == source:
            first.setdefault(t.header.seq, t)
    return list(first.values())


def score_tracks(gt: dict[int, PeopleGroundTruth], tracks: list[Tracks], name: str, plot: Path | None = None,
                 source: str | None = None, width: int | None = None,
                 truth: Literal["camera", "around"] = "camera") -> tuple[dict[str, Any], str]:
    """(metrics as a dict, Table II and the pose line as text) of a run's ground truth by frame
    seq and its published ``Tracks``; ``plot``: also draw it there (PNG); ``source``: score the
    outputs of that camera's frames (see :func:`frame_outputs`); ``width``: the tables' most
    columns (see :func:`~tools.evaluation.evaluate.format_table`); ``truth``: who is a ground-truth
    object, the camera's counted people or everyone the robot's sensors could see (``around``:
    the laser's too, all round the robot)."""
    seq_of_stamp = {msg.header.stamp_ns: seq for seq, msg in gt.items()}
    tracks = frame_outputs([_as_frame(t, seq_of_stamp) for t in tracks], source)
    gt_rows = [(seq, p.id, p.position) for seq, msg in gt.items()
               for p in (msg.around() if truth == "around" else msg.counted())]
    hyp_rows = [(t.header.seq, tr.id, tr.position) for t in tracks for tr in t.tracks if t.header.seq in gt]
    report, table = score_rows(gt_rows, hyp_rows, name, plot, width)
    report["pose"] = pose_scores(gt, tracks)
    return report, table + "\n\n" + pose_line(report["pose"])


def _as_frame(t: Tracks, seq_of_stamp: dict[int, int]) -> Tracks:
    """``t`` numbered as the ground-truth frame of its stamp, when there is one."""
    seq = seq_of_stamp.get(t.header.stamp_ns)
    if seq is None or seq == t.header.seq:
        return t
    return t.model_copy(update={"header": t.header.model_copy(update={"seq": seq})})


def score(gt: GroundTruthLog, monitor: Monitor, name: str, plot: Path | None = None,
          source: str | None = None, width: int | None = None,
          truth: Literal["camera", "around"] = "camera") -> tuple[dict[str, Any], str]:
    """:func:`score_tracks` of a live run's logs."""
    return score_tracks(gt.frames, monitor.all_tracks, name, plot, source, width, truth)


def nearest_pairs(people: list[PersonGroundTruth], tracks: list[TrackState], gate_m: float) -> list[tuple[int, int]]:
    """(person, track) index pairs on the floor within ``gate_m``, greedy, the nearest pairs first."""
    pairs = sorted((float(np.linalg.norm(p.position[:2] - t.position[:2])), i, j)
                   for i, p in enumerate(people) for j, t in enumerate(tracks))
    used_p: set[int] = set()
    used_t: set[int] = set()
    out = []
    for d, i, j in pairs:
        if d <= gate_m and i not in used_p and j not in used_t:
            used_p.add(i)
            used_t.add(j)
            out.append((i, j))
    return out


def pose_scores(gt: dict[int, PeopleGroundTruth], tracks: list[Tracks], gate_m: float = 1.0) -> dict[str, Any]:
    """Posture accuracy and orientation error of the tracks against the simulator's truth.

    Per frame, each counted person is paired with the nearest track within ``gate_m`` on
    the ground plane (greedy, nearest pairs first). A track whose distribution is uniform
    (unknown) is left out: ``posture_accuracy`` is the share of the others whose most likely
    posture is the true one, ``orientation_error_deg_p50`` the median angle between the most
    likely orientation bin's centre and the direction the person faces.
    """
    right = known_posture = 0
    errors: list[float] = []
    for msg in tracks:
        truth = gt.get(msg.header.seq)
        if truth is None or not msg.tracks:
            continue
        people = truth.counted()
        for i, j in nearest_pairs(people, msg.tracks, gate_m):
            person, track = people[i], msg.tracks[j]
            posture = np.asarray(track.posture)
            if np.ptp(posture) > 1e-6 and person.posture in _POSTURES:
                known_posture += 1
                right += int(int(np.argmax(posture)) == _POSTURES.index(person.posture))
            orientation = np.asarray(track.orientation)
            if np.ptp(orientation) > 1e-6 and person.facing_rad is not None:
                centre = int(np.argmax(orientation)) * 2 * np.pi / len(orientation)
                diff = (centre - person.facing_rad + np.pi) % (2 * np.pi) - np.pi
                errors.append(abs(float(np.degrees(diff))))
    return {"posture_pairs": known_posture,
            "posture_accuracy": round(right / known_posture, 4) if known_posture else None,
            "orientation_pairs": len(errors),
            "orientation_error_deg_p50": round(float(np.median(errors)), 1) if errors else None}


def pose_line(pose: dict[str, Any]) -> str:
    """The pose scores as two lines of text: posture, then orientation."""
    acc, err = pose["posture_accuracy"], pose["orientation_error_deg_p50"]
    return (f"posture: {'-' if acc is None else f'{100 * acc:.1f} %'} right ({pose['posture_pairs']} pairs)\n"
            f"orientation: median error {'-' if err is None else f'{err:.1f} deg'} ({pose['orientation_pairs']} pairs)")


def score_rows(gt_rows: list[tuple[int, int, np.ndarray]], hyp_rows: list[tuple[int, int, np.ndarray]],
               name: str, plot: Path | None = None, width: int | None = None) -> tuple[dict[str, Any], str]:
    """(metrics as a dict, Table II as text) of (frame, id, position) rows.

    ``plot``: also draw the tracks against the ground truth there (``perception evaluate
    --plot``'s picture); without matplotlib it is skipped with a warning.
    """
    gt, hyp = _table(gt_rows), _table(hyp_rows)
    panel = SequencePlot(name, gt, hyp)
    collect = IdentityCollector()

    def on_frame(frame: int, events: FrameEvents) -> None:
        collect(frame, events)
        if plot is not None:
            panel.on_frame(frame, events)

    mot = evaluate_tables(gt, hyp, on_frame=on_frame)
    if plot is not None:
        panel.result = mot
        try:
            plot_sequences([panel], plot)
        except PlotUnavailable as exc:
            log.warning("no plot of the run: %s", exc)
    report = make_report([(name, mot)])
    identity = collect.result(gt.frames, gt.ids)
    out = report.to_dict()
    out["identity"] = {k: v for k, v in identity.to_dict().items() if k not in ("coverage", "events")}
    return out, format_table(report, width) + "\n\n" + identity_line(identity)


def identity_line(i: Identity) -> str:
    """The ID memory at work, in three lines of at most 80 columns: what the people who came back
    were given, and IDs given to the wrong person (``perception evaluate --identity``'s measures)."""
    lost = f", {i.unmatched_returns} not tracked" if i.unmatched_returns else ""
    return (f"identity: people came back {i.returns} times (after {i.gap} frames or more out of view):\n"
            f"  {i.true_recoveries} got their own ID, {i.missed_recoveries} a new one, "
            f"{i.false_recoveries - i.false_newcomers} someone else's{lost}\n"
            f"  newcomers given an old ID: {i.false_newcomers}; track IDs covering two people: {i.shared_tracks}")
