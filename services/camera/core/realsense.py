"""The ``realsense`` backend: an Intel RealSense camera (colour plus depth aligned to it) or a
recording of one (``.bag``, or the ``.db3`` that librealsense 2.59's recorder writes), through
pyrealsense2. pyrealsense2 is imported inside the functions that need it, so this module imports
without it; a missing pyrealsense2 is a :class:`SourceError` when a source opens.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from pathlib import Path
from typing import Any

import numpy as np

from services.camera.core.sources import Capture, Intrinsics, SourceError, StreamLost

__all__ = ["RealSenseSource", "intrinsics_from_rs"]

#: A depth scale this close to 1 mm is millimetres: depth stays uint16 (the D400s' default).
_MM = 0.001
_MM_TOLERANCE = 1e-6
#: Frames a recording may deliver ahead of the reader (the player waits while this is full).
_QUEUE = 16
#: Colour frames read ahead while looking for the depth frame that goes with one.
_LOOKAHEAD = 32
_INSTALL = "pyrealsense2 is not installed: pip install 'people-perception[realsense]' (or pip install pyrealsense2)"
_NO_DEVICE = ("no RealSense device is connected: plug the camera into a USB 3 port, check that rs-enumerate-devices "
              "(or realsense-viewer) lists it, and on Linux install librealsense's udev rules "
              "(99-realsense-libusb.rules); or give a RealSense recording (.bag, .db3) as the source")


def _rs() -> Any:
    try:
        import pyrealsense2 as rs
    except ImportError as exc:
        raise SourceError(_INSTALL) from exc
    return rs


def intrinsics_from_rs(intr: Any) -> Intrinsics:
    """A pyrealsense2 ``intrinsics`` as :class:`Intrinsics`.

    brown_conrady, modified_brown_conrady and inverse_brown_conrady keep their five coefficients
    (k1, k2, p1, p2, k3: OpenCV's and ROS's plumb_bob order); modified and inverse differ from
    plumb_bob in how the coefficients apply, so for them plumb_bob is exact only when the
    coefficients are zero, as on the D400s' colour streams. kannala_brandt4 is ROS's equidistant
    (k1..k4); none is "none" with zero coefficients; ftheta has no counterpart here.
    """
    rs = _rs()
    K = np.array([[intr.fx, 0.0, intr.ppx], [0.0, intr.fy, intr.ppy], [0.0, 0.0, 1.0]], dtype=np.float64)
    coeffs = np.asarray(list(intr.coeffs), dtype=np.float64)
    model = intr.model
    if model in (rs.distortion.brown_conrady, rs.distortion.modified_brown_conrady,
                 rs.distortion.inverse_brown_conrady):
        name, D = "plumb_bob", coeffs[:5]
    elif model == rs.distortion.none:
        name, D = "none", np.zeros(5)
    elif model == rs.distortion.kannala_brandt4:
        name, D = "equidistant", coeffs[:4]
    else:
        raise SourceError(f"the colour stream's distortion model {model} has no ROS counterpart (plumb_bob, "
                          "equidistant or none); give a calibration file instead")
    return Intrinsics(int(intr.width), int(intr.height), K, D, name)


def _colour_rgb(rs: Any, frame: Any) -> np.ndarray:
    """The colour frame as an (H, W, 3) uint8 RGB array of its own (the frame's memory goes back to
    the SDK)."""
    data = np.asanyarray(frame.get_data())
    fmt = frame.get_profile().format()
    if fmt == rs.format.rgb8:
        return np.array(data, dtype=np.uint8, copy=True)
    if fmt == rs.format.bgr8:
        return np.ascontiguousarray(data[..., ::-1])
    if fmt == rs.format.rgba8:
        return np.ascontiguousarray(data[..., :3])
    if fmt == rs.format.bgra8:
        return np.ascontiguousarray(data[..., 2::-1])
    raise StreamLost(f"colour frame in format {fmt}, not rgb8/bgr8/rgba8/bgra8")


def _depth_array(frame: Any, scale: float) -> np.ndarray:
    """Aligned z16 depth as the Capture's convention: uint16 millimetres when the scale is 1 mm,
    else float32 metres with NaN where the camera has no depth."""
    raw = np.asanyarray(frame.get_data())
    if abs(scale - _MM) < _MM_TOLERANCE:
        return np.array(raw, dtype=np.uint16, copy=True)
    metres = raw.astype(np.float32) * np.float32(scale)
    metres[raw == 0] = np.nan
    return metres


def _timestamp_ns(frame: Any) -> int:
    return int(round(frame.get_timestamp() * 1e6))  # the SDK's timestamps are milliseconds


class RealSenseSource:
    """Colour (RGB) and depth aligned to it (``rs.align(rs.stream.color)``) from a RealSense.

    ``source``: a recording (``.bag``, ``.db3``) or ``""`` for a live camera, the one whose serial
    number is ``serial`` (``""``: the first one). ``width``, ``height``, ``fps``: the colour mode
    asked of a live camera (0: its default); ``depth_width``, ``depth_height``, ``depth_fps``: the
    depth mode (0: the colour's). A recording plays its own streams at its own rate: these are
    ignored for it. ``timeout_s``: how long ``read()`` waits for a frame before :class:`StreamLost`.

    Depth is uint16 millimetres when the device's depth scale is 1 mm (the D400s), else float32
    metres (the D405's 0.1 mm), NaN where there is none. ``intrinsics`` are the colour stream's
    (alignment keeps them), ``depth_scale`` the device's metres per depth unit.

    Stamps: a live camera's ``stamp_ns`` is the frame's own timestamp when the SDK gives it in the
    host's clock (timestamp domain ``system_time``, or ``global_time``: the camera's clock
    converted to the host's), else the host's time when the frame reached it (its
    ``time_of_arrival`` metadata, or ``time.time_ns()`` when ``read()`` got it). A recording's
    ``stamp_ns`` is its frames' recorded timestamps in ns (the recording camera's clock, whatever
    its domain). ``index`` counts the captures from 1.

    A recording plays in the SDK's player (``context.load_device``, what
    ``config.enable_device_from_file`` opens; it does not repeat), not in real time
    (``set_real_time(False)``): the player waits for ``read()``, so a reader as slow or as fast as
    it likes gets every colour frame once, with the depth frame nearest to it in time; the end of
    the recording: ``read()`` returns None. Not through ``rs.pipeline``: in non-real-time playback
    its syncer loses the first frames of the stream whose sensor starts second, and hands out a
    frameset per arriving frame (each colour frame twice, once with the previous depth frame).

    ``read()`` from one thread at a time; ``close()`` from any (``read()`` then returns None).
    """

    is_file: bool
    fps: float | None
    intrinsics: Intrinsics | None
    name: str

    def __init__(self, source: str = "", *, serial: str = "", width: int = 640, height: int = 480,
                 fps: float = 30.0, depth_width: int = 0, depth_height: int = 0, depth_fps: float = 0.0,
                 timeout_s: float = 5.0) -> None:
        self._rs = rs = _rs()
        self.source = source
        self.timeout_s = timeout_s
        self.is_file = bool(source)
        self.depth_scale: float | None = None
        self._index = 0
        self._align = rs.align(rs.stream.color)
        # live
        self._pipeline: Any = None
        self._last_colour: int | None = None
        # recording
        self._playback: Any = None
        self._sensors: list[Any] = []
        self._frames: deque[Any] = deque()
        self._frames_changed = threading.Condition()
        self._bounded = False  # the queue holds the player back only once the source is open
        self._closing = False
        self._colour: deque[Any] = deque()
        self._depth: deque[Any] = deque()
        self._ended = False
        self._has_depth = False
        if self.is_file:
            self._open_recording(Path(source).expanduser())
        else:
            self._open_device(serial, width, height, fps, depth_width or width, depth_height or height,
                              depth_fps or fps)

    # -- a live camera -------------------------------------------------------------------------

    def _open_device(self, serial: str, width: int, height: int, fps: float, depth_width: int,
                     depth_height: int, depth_fps: float) -> None:
        rs = self._rs
        devices = list(rs.context().query_devices())
        if not devices:
            raise SourceError(_NO_DEVICE)

        def info(dev: Any, what: Any) -> str:
            return dev.get_info(what) if dev.supports(what) else "?"

        found = [(info(d, rs.camera_info.serial_number), info(d, rs.camera_info.name)) for d in devices]
        if serial and serial not in [s for s, _ in found]:
            listed = ", ".join(f"{s} ({n})" for s, n in found)
            raise SourceError(f"no RealSense device with serial number {serial} is connected (connected: {listed}); "
                              "fix the serial setting, or leave it empty for the first device")
        serial = serial or found[0][0]
        model = dict(found)[serial]
        config = rs.config()
        config.enable_device(serial)
        config.enable_stream(rs.stream.color, width, height, rs.format.rgb8, int(round(fps)))
        config.enable_stream(rs.stream.depth, depth_width, depth_height, rs.format.z16, int(round(depth_fps)))
        pipeline = rs.pipeline()
        wanted = (f"colour {width}x{height} rgb8 and depth {depth_width}x{depth_height} z16 at "
                  f"{fps:g}/{depth_fps:g} fps")
        if not config.can_resolve(rs.pipeline_wrapper(pipeline)):
            raise SourceError(f"RealSense {model} {serial} cannot stream {wanted}: set width, height and fps (and "
                              "depth_width, depth_height, depth_fps) to modes that rs-enumerate-devices lists for it")
        try:
            profile = pipeline.start(config)
        except RuntimeError as exc:
            raise SourceError(f"RealSense {model} {serial} does not start ({exc}): is another program using it, "
                              "and is it on a USB 3 port?") from exc
        self._pipeline = pipeline
        try:
            colour = profile.get_stream(rs.stream.color).as_video_stream_profile()
            self.intrinsics = intrinsics_from_rs(colour.get_intrinsics())
            self.fps = float(colour.fps())
            self.depth_scale = float(profile.get_device().first_depth_sensor().get_depth_scale())
        except BaseException:
            self.close()
            raise
        self._has_depth = True
        self.name = f"RealSense {model} {serial}"

    def _read_live(self) -> Capture | None:
        rs = self._rs
        deadline = time.monotonic() + self.timeout_s
        while True:
            pipeline = self._pipeline
            if pipeline is None or self._closing:
                return None
            left_ms = int(max(deadline - time.monotonic(), 0.001) * 1000)
            try:
                frames = pipeline.wait_for_frames(left_ms)
            except RuntimeError as exc:
                if self._closing:
                    return None
                raise StreamLost(f"{self.name} stopped delivering frames ({exc})") from exc
            arrived_ns = time.time_ns()
            colour = frames.get_color_frame()
            # the pipeline's frameset repeats the colour frame when a depth frame alone arrives
            if not colour or colour.get_frame_number() == self._last_colour or not frames.get_depth_frame():
                if time.monotonic() >= deadline:
                    raise StreamLost(f"{self.name} delivered no new colour and depth frame in {self.timeout_s:g} s")
                continue
            self._last_colour = colour.get_frame_number()
            aligned = self._align.process(frames)
            colour, depth = aligned.get_color_frame(), aligned.get_depth_frame()
            if colour.get_frame_timestamp_domain() in (rs.timestamp_domain.system_time,
                                                       rs.timestamp_domain.global_time):
                stamp = _timestamp_ns(colour)
            elif colour.supports_frame_metadata(rs.frame_metadata_value.time_of_arrival):
                stamp = int(colour.get_frame_metadata(rs.frame_metadata_value.time_of_arrival)) * 1_000_000
            else:
                stamp = arrived_ns
            self._index += 1
            assert self.depth_scale is not None
            return Capture(_colour_rgb(rs, colour), _depth_array(depth, self.depth_scale), stamp, self._index)

    # -- a recording ---------------------------------------------------------------------------

    def _open_recording(self, path: Path) -> None:
        rs = self._rs
        if not path.is_file():
            raise SourceError(f"{path}: no such file; give a RealSense recording (.bag, .db3), or '' for a live "
                              "camera")
        try:
            playback = rs.context().load_device(str(path)).as_playback()
        except RuntimeError as exc:
            raise SourceError(f"{path}: not a RealSense recording ({exc}); record one with realsense-viewer or "
                              "rs-record, or use the opencv backend for a video file") from exc
        colour = depth = None
        for sensor in playback.query_sensors():
            for p in sensor.get_stream_profiles():
                if not p.is_video_stream_profile():
                    continue
                if p.stream_type() == rs.stream.color and (colour is None or p.format() == rs.format.rgb8):
                    colour = (sensor, p)
                elif p.stream_type() == rs.stream.depth and p.format() == rs.format.z16 and depth is None:
                    depth = (sensor, p)
        if colour is None:
            raise SourceError(f"{path}: the recording has no colour stream; record colour with it")
        if colour[1].format() not in (rs.format.rgb8, rs.format.bgr8, rs.format.rgba8, rs.format.bgra8):
            raise SourceError(f"{path}: the recording's colour is {colour[1].format()}, not rgb8, bgr8, rgba8 or "
                              "bgra8; record colour as rgb8 (realsense-viewer's default)")
        if depth is not None:
            sensor = depth[0]
            if sensor.is_depth_sensor():
                self.depth_scale = float(sensor.as_depth_sensor().get_depth_scale())
            elif sensor.supports(rs.option.depth_units):
                self.depth_scale = float(sensor.get_option(rs.option.depth_units))
            else:
                raise SourceError(f"{path}: the recording's depth stream has no depth units (metres per unit)")
        self._has_depth = depth is not None
        profile = colour[1].as_video_stream_profile()
        self.intrinsics = intrinsics_from_rs(profile.get_intrinsics())
        self.fps = float(profile.fps()) or None
        self.name = f"RealSense recording {path}"
        self._playback = playback
        playback.set_real_time(False)
        # The player starts reading when the first sensor starts: paused, no sensor misses frames
        # while the others start. Until resume() has returned the callback must not block: the
        # player's calls wait for its reading thread (10 s, then go on regardless).
        playback.pause()
        opened: dict[int, tuple[Any, list[Any]]] = {}
        for sensor, p in [colour] + ([depth] if depth is not None else []):
            opened.setdefault(id(sensor), (sensor, []))[1].append(p)
        try:
            for sensor, profiles in opened.values():
                sensor.open(profiles)
                self._sensors.append(sensor)
            for sensor, _ in opened.values():
                sensor.start(self._on_frame)
            playback.resume()
        except RuntimeError as exc:
            self.close()
            raise SourceError(f"{path}: the recording does not play ({exc})") from exc
        with self._frames_changed:
            self._bounded = True

    def _on_frame(self, frame: Any) -> None:
        """The SDK's threads hand each frame of the recording here. The player waits while this
        blocks, so a full queue holds it back instead of losing frames."""
        frame.keep()
        with self._frames_changed:
            while self._bounded and len(self._frames) >= _QUEUE and not self._closing:
                self._frames_changed.wait(0.1)
            if not self._closing:
                self._frames.append(frame)
                self._frames_changed.notify_all()

    def _take(self) -> bool:
        """One frame from the player into the colour or depth deque; False at the end."""
        rs = self._rs
        playback = self._playback
        deadline = time.monotonic() + self.timeout_s
        while True:
            if self._closing or playback is None:
                return False  # closed, from another thread too: the end
            # The player hands over every frame before it says stopped: stopped and nothing
            # queued is the end.
            stopped = playback.current_status() == rs.playback_status.stopped
            with self._frames_changed:
                if not self._frames:
                    self._frames_changed.wait(0.05)
                frame = self._frames.popleft() if self._frames else None
                self._frames_changed.notify_all()
            if frame is None:
                if stopped:
                    return False
                if time.monotonic() >= deadline:
                    raise StreamLost(f"{self.name}: the player delivered nothing in {self.timeout_s:g} s")
                continue
            if frame.get_profile().stream_type() == rs.stream.color:
                self._colour.append(frame)
            else:
                self._depth.append(frame)
            return True

    def _read_recording(self) -> Capture | None:
        rs = self._rs
        if self._closing:
            return None
        while not self._colour:
            if self._ended or not self._take():
                self._ended = True
                return None
        colour = self._colour.popleft()
        depth = None
        if self._has_depth:
            t = colour.get_timestamp()
            # read until a depth frame at or after the colour's time (or the end, or too far ahead)
            while (not self._ended and (not self._depth or self._depth[-1].get_timestamp() < t)
                   and len(self._colour) < _LOOKAHEAD):
                if not self._take():
                    self._ended = True
            if self._depth:
                nearest = min(range(len(self._depth)), key=lambda i: abs(self._depth[i].get_timestamp() - t))
                for _ in range(nearest):
                    self._depth.popleft()
                depth = self._depth[0]  # kept: the next colour frame may be nearest to it too
        self._index += 1
        stamp = _timestamp_ns(colour)
        if depth is None:
            return Capture(_colour_rgb(rs, colour), None, stamp, self._index)
        aligned = self._align.process(self._frameset(colour, depth))
        assert self.depth_scale is not None
        return Capture(_colour_rgb(rs, aligned.get_color_frame()),
                       _depth_array(aligned.get_depth_frame(), self.depth_scale), stamp, self._index)

    def _frameset(self, colour: Any, depth: Any) -> Any:
        """A frameset of the two frames, which ``rs.align`` needs (the SDK's syncer would pair them
        itself, but pairs each arriving frame with the other stream's latest, and drops the first
        frames of a recording in non-real-time playback)."""
        rs = self._rs
        out = rs.frame_queue(1)
        block = rs.processing_block(lambda _f, src: src.frame_ready(src.allocate_composite_frame([colour, depth])))
        block.start(out)
        block.invoke(colour)
        return out.wait_for_frame(int(self.timeout_s * 1000)).as_frameset()

    # -- Source --------------------------------------------------------------------------------

    def read(self) -> Capture | None:
        """The next colour frame with depth aligned to it; None at the end of a recording, and
        once the source is closed (from another thread too: a shutdown ends a waiting read)."""
        return self._read_recording() if self.is_file else self._read_live()

    def close(self) -> None:
        with self._frames_changed:
            self._closing = True
            self._frames_changed.notify_all()
        if self._pipeline is not None:
            pipeline, self._pipeline = self._pipeline, None
            try:
                pipeline.stop()
            except RuntimeError:
                pass
        if self._playback is not None or self._sensors:
            for sensor in self._sensors:
                for step in (sensor.stop, sensor.close):
                    try:
                        step()
                    except RuntimeError:
                        pass  # already stopped by the player at the end of the file
            self._sensors = []
            with self._frames_changed:
                self._frames.clear()
            # the colour and depth deques go with the source: a read() in another thread may be using them
            self._playback = None
