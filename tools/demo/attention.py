"""How well the head kept the person of interest in view, from the simulator's own streams.

For every ground-truth frame: the true camera pose (the simulator's transforms, whose
``map -> odom`` is the exact drift correction, so ``map -> camera`` is the true pose), the
person of interest's true torso centre projected into the image, and whether the person
counts as visible there (the simulator's ground-truth rule: at least ``min_visible`` of the
body seen). The figures: the median and 95th percentile of the distance from the image
centre (frames where the person is in front of the camera), and the share of frames where
the person is visible.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from common.geometry.transforms import PinholeCamera, TransformBuffer, TransformError
from common.geometry.messages import add_transform
from common.messages.keys import RELIABLE, Delivery, Keys
from common.messages.schemas import Header, Message, PeopleGroundTruth, TrackState, Tracks, TransformBatch
from common.transport.base import Transport

__all__ = ["AttentionLog", "AttentionScore", "TruthTracks"]

#: The person of interest: the scenario's person 1 (in people-following, the one the robot follows).
PERSON_OF_INTEREST = 1


class AttentionScore:
    """Feed it the simulator's transforms and ground truth in publishing order; ``report()`` at the end."""

    def __init__(self, camera: PinholeCamera, person_id: int = PERSON_OF_INTEREST, camera_frame: str = "camera",
                 map_frame: str = "map") -> None:
        self.camera = camera
        self.person_id = person_id
        self.camera_frame = camera_frame
        self.map_frame = map_frame
        self.buffer = TransformBuffer(history_s=30.0, tolerance_s=0.01)
        self.errors_px: list[float] = []
        self.visible: list[bool] = []

    def add(self, msg: Message) -> None:
        if isinstance(msg, TransformBatch):
            for t in msg.transforms:
                add_transform(self.buffer, t)
        elif isinstance(msg, PeopleGroundTruth):
            self._frame(msg)

    def _frame(self, gt: PeopleGroundTruth) -> None:
        person = next((p for p in gt.people if p.id == self.person_id), None)
        if person is None:
            return
        self.visible.append(bool(person.counted))
        try:
            cam_from_map = self.buffer.lookup(self.camera_frame, self.map_frame, gt.header.stamp_ns)
        except TransformError:
            return
        x = cam_from_map.apply(np.array(person.position, float))
        if x[2] <= 0.1:
            return
        c = self.camera
        u, v = c.fx * x[0] / x[2] + c.cx, c.fy * x[1] / x[2] + c.cy
        self.errors_px.append(float(np.hypot(u - (c.width - 1) / 2.0, v - (c.height - 1) / 2.0)))

    def report(self) -> dict[str, Any]:
        e = np.asarray(self.errors_px)
        return {
            "person_id": self.person_id,
            "frames": len(self.visible),
            "center_error_px_p50": round(float(np.percentile(e, 50)), 1) if e.size else None,
            "center_error_px_p95": round(float(np.percentile(e, 95)), 1) if e.size else None,
            "target_visible_fraction": round(float(np.mean(self.visible)), 3) if self.visible else None,
        }


class AttentionLog:
    """:class:`AttentionScore` fed from a live transport (``perception demo --attention``)."""

    def __init__(self, transport: Transport, keys: Keys, camera: PinholeCamera) -> None:
        keep = Delivery(latest=False, queue=4096, congestion="block")
        # static first: a frame's dynamic transforms and ground truth are scored after it
        self._subs = [transport.subscribe(keys.tf_static(), TransformBatch, keep),
                      transport.subscribe(keys.tf(), TransformBatch, keep),
                      transport.subscribe(keys.groundtruth(), PeopleGroundTruth, keep)]
        self.score = AttentionScore(camera)
        self._pending: list[PeopleGroundTruth] = []

    def poll(self) -> None:
        for sub in self._subs[:2]:
            while (got := sub.try_recv()) is not None:
                self.score.add(got.msg)
        while (got := self._subs[2].try_recv()) is not None:
            self._pending.append(got.msg)
        # ground truth is scored once the transforms of its stamp are in (they may arrive later)
        newest = max((e[4] for e in self.score.buffer.edges() if not e[2]), default=-1)
        while self._pending and self._pending[0].header.stamp_ns <= newest:
            self.score.add(self._pending.pop(0))

    def report(self) -> dict[str, Any]:
        for msg in self._pending:
            self.score.add(msg)
        self._pending.clear()
        return self.score.report()


class TruthTracks:
    """The simulator's ground truth republished as ``Tracks``: a perfect tracker for the
    attention node (``run_chain(attention_truth=True)``), so the loop's own limits (control,
    the robot's path, walls) can be told from the tracker's errors.

    Every person is reported, seen or not, with their true position and velocity and their
    ground-truth ID; ``poll`` republishes the ground truth received since the last call."""

    def __init__(self, transport: Transport, keys: Keys) -> None:
        self.key = f"{keys.groundtruth()}/tracks"
        self._sub = transport.subscribe(keys.groundtruth(), PeopleGroundTruth, RELIABLE)
        self._pub = transport.publisher(self.key, Tracks, RELIABLE)

    def poll(self, _now: float) -> None:
        while (got := self._sub.try_recv()) is not None:
            gt = got.msg
            eye = np.eye(6) * 1e-4
            self._pub.put(Tracks(
                header=Header(stamp_ns=gt.header.stamp_ns, frame_id=gt.header.frame_id or "map", seq=gt.header.seq,
                              source="truth"),
                tracks=[TrackState(id=p.id, status="confirmed", position=p.position, velocity=p.velocity,
                                   covariance=eye, last_update_ns=gt.header.stamp_ns, hits=1, age_s=0.0)
                        for p in gt.people]))

    def close(self) -> None:
        self._sub.close()
