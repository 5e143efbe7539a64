"""LaserService: a 2-D laser's scans -> the people around the robot, in the map frame.

Inputs: ``scans/{laser}`` (:class:`LaserScan`), ``tf`` and ``tf_static`` (the scanner's pose in
``target_frame`` at each scan's stamp), ``static_map`` (its obstacles: a person is never inside a
wall: legs on its obstacles are dropped before they are paired into people). Output: ``localized/{laser}``, :class:`LocalizedDetections` the tracker fuses like any
camera's, position only: one detection per person (a pair of legs, or a lone leg with a wider
covariance), ``score`` the probability that it is a person's leg, ``depth_m`` its range from the
scanner, ``valid_pixels`` its beams, no image box (``bbox_xyxy`` all zeros) and ``detector``
``laser-legs``, and the scan's coverage (``scan_view``: whom the laser could have seen, so the tracker
does not count a person hidden behind another as missed). A scan waits up to ``transform_wait_s`` for its transform, then is dropped and
counted; invalid beams (no return) are counted by reason, never an error.
"""

from __future__ import annotations

import logging
from collections import deque
from dataclasses import dataclass

import numpy as np

from common.geometry.messages import obstacles_from_map, take_transforms
from common.geometry.occupancy import ObstacleMap
from common.geometry.transforms import ExtrapolationError, MissingTransformError, TransformBuffer
from common.messages.keys import MAPS, RELIABLE, SCANS, Keys
from common.messages.schemas import (
    Header,
    LaserScan,
    LocalizedDetection,
    LocalizedDetections,
    ScanCoverage,
    StaticMap,
    TransformBatch,
)
from common.runtime.node import Node
from common.runtime.ratelog import RateLimitedLog
from common.runtime.service import Counters
from common.transport.base import Transport
from services.laser.config import LaserConfig
from services.laser.core.boost import Boosted
from services.laser.core.legs import detect, in_frame, pair
from services.laser.core.scan import ScanGeometry

__all__ = ["DETECTOR", "LaserService", "coverage"]

log = logging.getLogger(__name__)

#: ``LocalizedDetections.detector`` of the laser's people.
DETECTOR = "laser-legs"
NO_BOX = (0.0, 0.0, 0.0, 0.0)


def coverage(scan: LaserScan, rotation: np.ndarray, translation: np.ndarray, max_range_m: float) -> ScanCoverage:
    """What the scan could see, for the tracker: the scanner's pose in the target frame and its
    ranges, no return (NaN, inf, outside the scanner's limits) and beyond ``max_range_m`` as
    ``max_range_m`` (free as far as the detector looks)."""
    pose = np.eye(4)
    pose[:3, :3], pose[:3, 3] = rotation, translation
    r = np.asarray(scan.ranges, np.float32)
    with np.errstate(invalid="ignore"):
        valid = np.isfinite(r) & (r > scan.range_min) & (r < scan.range_max)
    reach = np.where(valid, np.minimum(r, max_range_m), max_range_m).astype(np.float32)
    return ScanCoverage(scanner_to_frame=pose, angle_min=scan.angle_min, angle_increment=scan.angle_increment,
                        ranges=reach, max_range_m=max_range_m)


@dataclass
class _Waiting:
    scan: LaserScan
    frame: str
    arrived: float


class LaserService(Node):
    """The laser node on a transport it is handed (Zenoh or in-memory); ``model``: the leg
    classifier (``services.laser.model_file.load_model``)."""

    name = "laser"

    def __init__(self, transport: Transport, keys: Keys, config: LaserConfig, counters: Counters | None = None,
                 model: Boosted | None = None, obstacles: ObstacleMap | None = None) -> None:
        super().__init__(transport, keys, counters)
        if model is None:
            from services.laser.model_file import load_model

            model = load_model(config.model)[0]
        self.config = config
        self.model = model
        self.params = config.params()
        self.buffer = TransformBuffer(history_s=config.tf_history_s, tolerance_s=config.tf_tolerance_s)
        #: the static map's obstacles: the file's (``static_map``), else the static_map stream's newest
        self.obstacles: ObstacleMap | None = obstacles if obstacles is not None else config.obstacles()
        self.waiting: deque[_Waiting] = deque()
        self._log = RateLimitedLog(log)
        self.sub_tf_static = self.io.subscribe(keys.tf_static(), TransformBatch, RELIABLE)
        self.sub_tf = self.io.subscribe(keys.tf(), TransformBatch, RELIABLE)
        self.sub_map = self.io.subscribe(keys.static_map(), StaticMap, MAPS) if config.static_map is None else None
        self.sub_scans = self.io.subscribe(keys.scans(config.laser), LaserScan, SCANS)
        self.pub = self.io.publisher(keys.localized(config.laser), LocalizedDetections, RELIABLE)

    def describe(self) -> str:
        return f"finding people in {self.sub_scans.key}, publishing them in {self.config.target_frame!r}"

    def deadline(self, now: float) -> float | None:
        if not self.waiting:
            return None
        return max(0.0, self.waiting[0].arrived + self.config.transform_wait_s - now)

    def poll(self, now: float) -> list[LocalizedDetections]:
        take_transforms(self.buffer, ((self.sub_tf_static, True), (self.sub_tf, False)), self.counters, self._log)
        while self.sub_map is not None and (got := self.sub_map.try_recv()) is not None:
            if got.msg.header.frame_id in ("", self.config.target_frame):
                self.obstacles = obstacles_from_map(got.msg)
            else:
                self._drop("map_wrong_frame", "the static map is in %r, the people in %r: map ignored",
                           got.msg.header.frame_id, self.config.target_frame)
        while (got := self.sub_scans.try_recv()) is not None:
            frame = got.msg.header.frame_id or self.config.laser_frame
            if not frame:
                self._drop("no_laser_frame", "scan %s names no frame id (set laser_frame)", got.msg.header.seq)
                continue
            self.waiting.append(_Waiting(got.msg, frame, now))
            if len(self.waiting) > self.config.max_pending:
                self.waiting.popleft()
                self._drop("pending_overflow", "more than %d scans wait for their transform", self.config.max_pending)
        out = []
        while self.waiting:
            done, msg = self._try(self.waiting[0], now)
            if not done:
                break
            self.waiting.popleft()
            if msg is not None:
                self.pub.put(msg)
                out.append(msg)
        return out

    def _drop(self, reason: str, fmt: str, *args: object) -> None:
        self.counters.drop(reason)
        self._log.warning(reason, "laser: " + fmt, *args)

    def _try(self, w: _Waiting, now: float) -> tuple[bool, LocalizedDetections | None]:
        h = w.scan.header
        try:
            tf = self.buffer.lookup(self.config.target_frame, w.frame, h.stamp_ns)
        except (MissingTransformError, ExtrapolationError) as exc:
            never = isinstance(exc, ExtrapolationError) and not exc.future
            if not never and now - w.arrived < self.config.transform_wait_s:
                return False, None
            self._drop("no_transform", "missing transform %s: %s", exc.edge, exc)
            return True, None
        return True, self._people(w, tf.rotation_matrix, tf.translation)

    def _people(self, w: _Waiting, rotation: np.ndarray, translation: np.ndarray) -> LocalizedDetections:
        s, c = w.scan, self.config
        geometry = ScanGeometry(s.angle_min, s.angle_increment, s.range_min, s.range_max)
        legs = detect(s.ranges, geometry, self.model, self.params)
        for reason, n in legs.invalid.items():
            if n:
                self.counters.count(f"beams_{reason}", n)
        rejected = {}
        if self.obstacles is not None and c.map_clearance_m > 0 and len(legs):
            # before pairing: two chair or table legs on the map would pair into a "person" between them
            local = np.column_stack([legs.xy, np.zeros(len(legs))])
            on_map = self.obstacles.blocked((local @ rotation.T + translation)[:, :2], c.map_clearance_m)
            rejected["legs_on_map"] = int(on_map.sum())
            legs = legs.only(~on_map)
        people = pair(legs, self.params)
        pos, cov = in_frame(people, rotation, translation, c.floor_z_m + c.person_z_m, c.person_z_sigma_m)
        keep = people.probability >= c.min_probability
        rejected["unlikely"] = int((~keep).sum())
        dets = [LocalizedDetection(index=i, bbox_xyxy=NO_BOX, score=float(people.probability[k]), position=pos[k],
                                   cov=cov[k], depth_m=max(float(np.hypot(*people.xy[k])), 1e-3),
                                   valid_pixels=int(sum(len(legs.beams[j]) for j in people.legs[k])))
                for i, k in enumerate(np.flatnonzero(keep))]
        header = Header(stamp_ns=s.header.stamp_ns, frame_id=c.target_frame, seq=s.header.seq, source=c.laser)
        return LocalizedDetections(header=header, camera_frame=w.frame, detections=dets,
                                   rejected={k: v for k, v in rejected.items() if v}, detector=DETECTOR,
                                   scan_view=coverage(s, rotation, translation, c.max_range_m))
