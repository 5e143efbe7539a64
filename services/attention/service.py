"""AttentionService: tracks, camera info and transforms in, HeadCommand out (Ban et al.'s
person-of-interest visual servoing).

* ``tracks`` (Tracks): the people, in the tracking frame (``map``);
* ``frames/{camera}`` (RGBDFrame, latest-only): only its camera info is used, read at most
  every ``camera_info_period_s`` (the frames in between are discarded undecoded; the ring
  of one counts the ones overwritten before a poll as dropped);
* ``tf``, ``tf_static``: where the camera and the head's joints are;
* the queryable ``query/attention?target=K|nearest|lock|none`` sets whom to look at and answers
  with an :class:`AttentionReply` (an unknown ID is refused, saying which IDs are known).

A command goes out for every Tracks message, and at least ``command_rate_hz`` times a
second without one (holding, returning to rest, keeping the head's command alive).
Bad inputs are counted and survived: ``unknown_target_ids``, ``bad_requests``,
``nan_tracks``, ``no_camera_info``, ``no_transform``, ``transforms_rejected``.
"""

from __future__ import annotations

import logging
import math
import threading
import time

import numpy as np

from common.geometry.transforms import PinholeCamera, RigidTransform, TransformBuffer, TransformError
from common.geometry.messages import camera_from_info, take_transforms
from common.messages.keys import COMMANDS, FRAMES, RELIABLE, Keys
from common.runtime.node import Node
from common.runtime.ratelog import RateLimitedLog
from common.runtime.service import Counters
from common.messages.schemas import AttentionReply, HeadCommand, Header, RGBDFrame, Tracks, TransformBatch
from common.transport.base import Transport
from services.attention.config import AttentionConfig, parse_target
from services.attention.core import Chooser, Decision, HeadGeometry, Person, head_angles, rest_rates, servo

__all__ = ["AttentionService"]

log = logging.getLogger(__name__)

#: The base's motion (for the feed-forward) is measured over this interval of its transforms.
BASE_DT_S = 0.1


class AttentionService(Node):
    name = "attention"

    def __init__(self, transport: Transport, keys: Keys, config: AttentionConfig, counters: Counters | None = None,
                 tracks_key: str | None = None) -> None:
        """``tracks_key``: where the people come from instead of the tracker's ``tracks``
        (a harness that feeds it the ground truth, to measure the loop without tracking errors)."""
        super().__init__(transport, keys, counters)
        self.config = config
        self.params = config.servo_params()
        self.chooser = Chooser(config.hold_s, config.switch_margin_m, config.reacquire_radius_m)
        mode, track_id = parse_target(config.target)
        self.chooser.request(mode, track_id)  # type: ignore[arg-type]
        self.buffer = TransformBuffer(history_s=config.tf_history_s, tolerance_s=config.tf_tolerance_s)
        self.camera: PinholeCamera | None = None
        self.camera_frame = config.camera_frame
        self._lock = threading.Lock()  # the chooser and the known IDs: the query runs on the transport's thread
        self._known_ids: list[int] = []
        self._people: list[Person] = []
        self._tracks_at: float | None = None  # when the newest tracks arrived (poll clock)
        self._tracks_stamp_ns = 0
        self._frame_id = "map"  # the tracks' frame
        self._last_info_at = -math.inf
        self._last_command_at = -math.inf
        self._log = RateLimitedLog(log)
        self.sub_tf_static = self.io.subscribe(keys.tf_static(), TransformBatch, RELIABLE)
        self.sub_tf = self.io.subscribe(keys.tf(), TransformBatch, RELIABLE)
        self.sub_frames = self.io.subscribe(keys.frames(config.camera), RGBDFrame, FRAMES)
        self.sub_tracks = self.io.subscribe(tracks_key or keys.tracks(), Tracks, RELIABLE)
        self.pub = self.io.publisher(keys.head_command(), HeadCommand, COMMANDS)
        self.io.serve(keys.attention_query(), self._answer)

    def describe(self) -> str:
        return (f"servoing the head ({self.config.base_frame} pan, {self.config.tilt_frame} tilt) on "
                f"{self.sub_tracks.key} with camera {self.config.camera}; target {self.config.target}")

    # ------------------------------------------------------------------ inputs
    def _take_transforms(self) -> None:
        take_transforms(self.buffer, ((self.sub_tf_static, True), (self.sub_tf, False)), self.counters, self._log)

    def _take_camera_info(self, now: float) -> None:
        if now - self._last_info_at < self.config.camera_info_period_s:
            self.sub_frames.try_recv_raw()  # not due: discard the frame undecoded (a waiting one would wake the loop)
            return
        if (got := self.sub_frames.try_recv()) is not None:
            info = got.msg.camera_info
            self.camera = camera_from_info(info)
            self.camera_frame = info.header.frame_id or got.msg.header.frame_id or self.config.camera_frame
            self._last_info_at = now

    def _people_of(self, msg: Tracks) -> list[Person]:
        people = []
        for t in msg.tracks:
            if t.status == "deleted":
                continue
            if not (np.all(np.isfinite(t.position)) and np.all(np.isfinite(t.velocity))):
                self.counters.count("nan_tracks")
                self._log.warning("nan", "track %d has a non-finite position or velocity: ignored", t.id)
                continue
            people.append(Person(t.id, np.array(t.position, float), np.array(t.velocity, float),
                                 t.status in ("confirmed", "coasting")))
        return people

    # ------------------------------------------------------------------ control
    def _command(self, decision: Decision, frame_id: str, stamp_ns: int) -> HeadCommand:
        """The joint rates for ``decision`` from the newest transforms and camera info."""
        cfg = self.config
        header = Header(stamp_ns=stamp_ns, frame_id=cfg.base_frame, source=self.name)
        base = dict(header=header, timeout_s=cfg.command_timeout_s, input_stamp_ns=self._tracks_stamp_ns,
                    target_id=max(decision.target_id, -1))
        if decision.phase == "hold" and decision.target is None:
            return HeadCommand(**base, mode="hold")
        try:
            base_tilt = self.buffer.lookup(cfg.base_frame, cfg.tilt_frame, None)
        except TransformError as exc:
            self.counters.count("no_transform")
            self._log.warning("no_tf", "no head transform %s -> %s: %s", cfg.base_frame, cfg.tilt_frame, exc)
            return HeadCommand(**base, mode="blind")
        angles = head_angles(base_tilt.matrix[:3, :3])
        if decision.phase == "rest":
            pan_rate, tilt_rate, at_rest = rest_rates(angles, self.params)
            return HeadCommand(**base, mode="idle" if at_rest else "rest", pan_rate=pan_rate, tilt_rate=tilt_rate)
        assert decision.target is not None
        if self.camera is None:
            self.counters.count("no_camera_info")
            self._log.warning("no_info", "no camera info yet on %s: the head stands still", self.sub_frames.key)
            return HeadCommand(**base, mode="blind")
        try:
            tf_stamp = self.buffer.latest_common_stamp(self.camera_frame, frame_id)
            cam_from_map = self.buffer.lookup(self.camera_frame, frame_id, tf_stamp)
            cam_from_base = self.buffer.lookup(self.camera_frame, cfg.base_frame, tf_stamp)
            cam_from_pan = self.buffer.lookup(self.camera_frame, cfg.pan_frame, tf_stamp)
            cam_from_tilt = self.buffer.lookup(self.camera_frame, cfg.tilt_frame, tf_stamp)
        except TransformError as exc:
            self.counters.count("no_transform")
            self._log.warning("no_tf", "no transform %s -> %s: %s", frame_id, self.camera_frame, exc)
            return HeadCommand(**base, mode="blind")
        ahead_s = 0.0 if tf_stamp is None else min(max((tf_stamp - self._tracks_stamp_ns) * 1e-9, 0.0), cfg.max_predict_s)
        target = decision.target
        aim = target.position + ahead_s * target.velocity
        if cfg.aim_height_m is not None:
            aim[2] = cfg.aim_height_m
        X = cam_from_map.apply(aim)
        X_dot = cam_from_map.rotation.apply(target.velocity) + self._base_motion(aim, frame_id, tf_stamp, cam_from_base, X)
        geometry = HeadGeometry(pan_axis=cam_from_base.matrix[:3, 2], pan_pivot=cam_from_pan.translation,
                                tilt_axis=cam_from_tilt.matrix[:3, 1], tilt_pivot=cam_from_tilt.translation)
        cam = self.camera
        result = servo(cam.K, ((cam.width - 1) / 2.0, (cam.height - 1) / 2.0), X, X_dot, geometry, angles, self.params)
        for flag in ("saturated", "at_limit", "fallback"):
            if getattr(result, flag):
                self.counters.count(f"commands_{flag}")
        error = (0.0, 0.0) if not all(map(math.isfinite, result.error_px)) else result.error_px
        if all(map(math.isfinite, result.error_px)):
            self.counters.gauge("error_px", float(np.hypot(*error)))
        mode = "track" if decision.phase == "track" else "hold"
        return HeadCommand(**base, mode=mode, pan_rate=result.pan_rate, tilt_rate=result.tilt_rate, error_px=error)

    def _base_motion(self, aim: np.ndarray, frame_id: str, tf_stamp: int | None, cam_from_base: RigidTransform,
                     X: np.ndarray) -> np.ndarray:
        """(3,) the target point's velocity in the camera frame caused by the base's own motion
        (the head's joints held), from the base's pose over the last ``BASE_DT_S``; zero if unknown."""
        if tf_stamp is None:
            return np.zeros(3)
        before = tf_stamp - int(BASE_DT_S * 1e9)
        try:
            base_from_map = self.buffer.lookup(self.config.base_frame, frame_id, before)
        except TransformError:
            return np.zeros(3)
        return (X - cam_from_base.apply(base_from_map.apply(aim))) / BASE_DT_S

    def _step(self, now: float, frame_id: str, stamp_ns: int) -> HeadCommand:
        origin = np.zeros(3)
        try:
            origin = self.buffer.lookup(frame_id, self.camera_frame, None).translation
        except TransformError:
            pass  # 'nearest' then measures from the map's origin until the transforms come
        with self._lock:
            decision = self.chooser.decide(self._people, origin, now)
        cmd = self._command(decision, frame_id, stamp_ns)
        self.pub.put(cmd)
        self._last_command_at = now
        self.counters.count(f"mode_{cmd.mode}")
        return cmd

    def poll(self, now: float) -> list[HeadCommand]:
        self._take_transforms()
        self._take_camera_info(now)
        out = []
        newest: Tracks | None = None
        while (got := self.sub_tracks.try_recv()) is not None:
            if newest is not None:
                self.counters.count("tracks_superseded")
            newest = got.msg
        if newest is not None:
            people = self._people_of(newest)
            with self._lock:
                self._people = people
                self._known_ids = sorted(p.id for p in people)
            self._tracks_at = now
            self._tracks_stamp_ns = newest.header.stamp_ns
            self._frame_id = newest.header.frame_id or "map"
            out.append(self._step(now, self._frame_id, newest.header.stamp_ns))
        elif now - self._last_command_at >= 1.0 / self.config.command_rate_hz:
            if self._tracks_at is None or now - self._tracks_at > self.config.tracks_timeout_s:
                with self._lock:
                    self._people, self._known_ids = [], []
            stamp = self._tracks_stamp_ns + (0 if self._tracks_at is None else int((now - self._tracks_at) * 1e9))
            out.append(self._step(now, self._frame_id, stamp))
        return out

    def deadline(self, now: float) -> float | None:
        return max(0.0, self._last_command_at + 1.0 / self.config.command_rate_hz - now)

    # ------------------------------------------------------------------ query
    def _reply(self, error: str = "") -> AttentionReply:
        c = self.chooser
        return AttentionReply(header=Header(stamp_ns=time.time_ns(), frame_id="map", source=self.name), mode=c.mode,
                              requested_id=c.requested_id, following_id=c.following_id, known_ids=list(self._known_ids),
                              error=error)

    def _answer(self, _key: str, params: dict[str, str]) -> list[AttentionReply]:
        with self._lock:
            raw = params.get("target")
            if raw is None:
                return [self._reply()]
            try:
                mode, track_id = parse_target(raw)
            except ValueError as exc:
                self.counters.count("bad_requests")
                self._log.warning("bad_request", "attention request refused: %s", exc)
                return [self._reply(f"malformed request: {exc}")]
            if mode == "id" and track_id not in self._known_ids:
                self.counters.count("unknown_target_ids")
                self._log.warning("unknown_id", "asked to look at unknown track ID %d", track_id)
                known = ", ".join(map(str, self._known_ids)) or "none"
                return [self._reply(f"unknown track ID {track_id}: the tracks now are {known}")]
            self.chooser.request(mode, track_id)  # type: ignore[arg-type]
            log.info("attention: now looking at %s", raw)
            return [self._reply()]
