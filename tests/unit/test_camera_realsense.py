"""The realsense backend on a recording made here with the SDK's own software device and
recorder: every frame played back once, pixels, intrinsics and stamps as written, None at the end;
and the errors a user meets (a file that is not a recording, no camera)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

rs = pytest.importorskip("pyrealsense2", reason="pyrealsense2 (the 'realsense' extra) is not installed: "
                                                "pip install 'people-perception[realsense]'")

from services.camera.core.realsense import RealSenseSource, intrinsics_from_rs  # noqa: E402
from services.camera.core.sources import SourceError  # noqa: E402

W, H, N = 64, 48, 10
FX, FY, CX, CY = 50.0, 51.0, 31.5, 23.5
T0_MS, PERIOD_MS = 1_700_000_000_000.0, 1000.0 / 30


def _intrinsics(model: str) -> rs.intrinsics:
    intr = rs.intrinsics()
    intr.width, intr.height, intr.fx, intr.fy, intr.ppx, intr.ppy = W, H, FX, FY, CX, CY
    intr.model = getattr(rs.distortion, model)
    intr.coeffs = [0.0] * 5
    return intr


def _frames() -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Colour: random pixels. Depth: one value a frame (1000, 1100, ... mm), so that each aligned
    depth image tells which depth frame it came from."""
    rng = np.random.default_rng(7)
    colours = [rng.integers(0, 256, size=(H, W, 3), dtype=np.uint8) for _ in range(N)]
    depths = [np.full((H, W), 1000 + 100 * i, dtype=np.uint16) for i in range(N)]
    return colours, depths


def _record(path: Path, colours: list[np.ndarray], depths: list[np.ndarray], *, depth_first: bool = True,
            colour_after_ms: float = 0.0, model: str = "none") -> None:
    """A depth + colour recording of ``colours`` and ``depths`` at 30 fps, both streams with the
    same intrinsics and no offset between them, stamped in the host's clock; frame i of depth at
    T0 + i periods, of colour ``colour_after_ms`` later, written depth then colour or the reverse."""
    dev = rs.software_device()
    depth_sensor, colour_sensor = dev.add_sensor("Depth"), dev.add_sensor("Color")
    depth_sensor.add_read_only_option(rs.option.depth_units, 0.001)

    def stream(kind: rs.stream, fmt: rs.format, bpp: int, uid: int) -> rs.video_stream:
        vs = rs.video_stream()
        vs.type, vs.index, vs.uid, vs.width, vs.height, vs.fps, vs.bpp, vs.fmt = kind, 0, uid, W, H, 30, bpp, fmt
        vs.intrinsics = _intrinsics(model)
        return vs

    depth_profile = depth_sensor.add_video_stream(stream(rs.stream.depth, rs.format.z16, 2, 0)).as_video_stream_profile()
    colour_profile = colour_sensor.add_video_stream(
        stream(rs.stream.color, rs.format.rgb8, 3, 1)).as_video_stream_profile()
    identity = rs.extrinsics()
    identity.rotation, identity.translation = [1, 0, 0, 0, 1, 0, 0, 0, 1], [0, 0, 0]
    depth_profile.register_extrinsics_to(colour_profile, identity)
    recorder = rs.recorder(str(path), dev)
    sink = rs.syncer()
    depth_sensor.open(depth_profile)
    colour_sensor.open(colour_profile)
    depth_sensor.start(sink)
    colour_sensor.start(sink)
    sent = []  # the SDK reads the pixels after on_video_frame returns: keep them alive
    for i, (colour, depth) in enumerate(zip(colours, depths)):
        pair = [(depth_sensor, depth_profile, depth, 2, 0.0), (colour_sensor, colour_profile, colour, 3, colour_after_ms)]
        for sensor, profile, pixels, bpp, after in pair if depth_first else pair[::-1]:
            frame = rs.software_video_frame()  # a fresh one each time: the SDK keeps a reference
            frame.pixels, frame.bpp, frame.stride = pixels, bpp, W * bpp
            frame.timestamp, frame.domain = T0_MS + i * PERIOD_MS + after, rs.timestamp_domain.system_time
            frame.frame_number, frame.profile = i + 1, profile
            sensor.on_video_frame(frame)
            sent.append(frame)
    for sensor in (depth_sensor, colour_sensor):
        sensor.stop()
        sensor.close()
    recorder.pause()
    del recorder  # the recorder writes the file out when it goes


@pytest.fixture(scope="module")
def frames() -> tuple[list[np.ndarray], list[np.ndarray]]:
    return _frames()


@pytest.mark.parametrize("depth_first,colour_after_ms", [(True, 0.0), (False, 0.0), (True, 8.0), (False, -8.0)])
def test_a_recording_plays_every_frame_once(tmp_path: Path, frames, depth_first: bool, colour_after_ms: float) -> None:
    colours, depths = frames
    path = tmp_path / "rec.db3"
    _record(path, colours, depths, depth_first=depth_first, colour_after_ms=colour_after_ms)
    source = RealSenseSource(str(path))
    try:
        assert source.is_file and source.fps == 30.0 and source.depth_scale == pytest.approx(0.001)
        assert source.intrinsics is not None
        assert (source.intrinsics.width, source.intrinsics.height) == (W, H)
        np.testing.assert_allclose(source.intrinsics.K, [[FX, 0, CX], [0, FY, CY], [0, 0, 1]])
        assert source.intrinsics.distortion_model == "none" and not source.intrinsics.D.any()
        captures = []
        while (capture := source.read()) is not None:
            captures.append(capture)
        assert source.read() is None  # and stays at the end
    finally:
        source.close()
    assert [c.index for c in captures] == list(range(1, N + 1))
    for capture, colour, depth in zip(captures, colours, depths):
        assert capture.rgb.dtype == np.uint8 and capture.rgb.shape == (H, W, 3)
        np.testing.assert_array_equal(capture.rgb, colour)
        # millimetres, from the depth frame of the same instant. rs.align maps each depth pixel
        # through float32 deprojection and projection: even where that is the identity (same
        # intrinsics, no offset) rounding leaves a few pixels without depth (0), never another value.
        assert capture.depth is not None and capture.depth.dtype == np.uint16
        assert set(np.unique(capture.depth)) <= {0, int(depth[0, 0])}
        assert (capture.depth == depth).mean() > 0.85
    stamps = [c.stamp_ns for c in captures]
    assert stamps == [int(round((T0_MS + i * PERIOD_MS + colour_after_ms) * 1e6)) for i in range(N)]
    assert all(b > a for a, b in zip(stamps, stamps[1:]))


def test_a_slow_reader_still_gets_every_frame(tmp_path: Path, frames) -> None:
    """The player is not real time: it waits for the reader instead of dropping frames."""
    import time

    colours, depths = frames
    path = tmp_path / "rec.db3"
    _record(path, colours, depths)
    source = RealSenseSource(str(path))
    try:
        time.sleep(0.5)  # time passing is the point: a real-time player would have played it all by now
        got = []
        while (capture := source.read()) is not None:
            got.append(capture.rgb)
    finally:
        source.close()
    assert len(got) == N and all(np.array_equal(a, b) for a, b in zip(got, colours))


def test_close_in_the_middle_of_a_recording(tmp_path: Path, frames) -> None:
    colours, depths = frames
    path = tmp_path / "rec.db3"
    _record(path, colours, depths)
    source = RealSenseSource(str(path))
    assert source.read() is not None
    source.close()  # the player is blocked on a full queue of frames no one reads: it must not hang
    source.close()
    assert source.read() is None


def test_brown_conrady_is_plumb_bob() -> None:
    intr = _intrinsics("inverse_brown_conrady")
    intr.coeffs = [0.1, -0.2, 0.003, 0.004, 0.05]
    got = intrinsics_from_rs(intr)
    assert got.distortion_model == "plumb_bob"
    np.testing.assert_allclose(got.D, [0.1, -0.2, 0.003, 0.004, 0.05], rtol=1e-6)
    assert intrinsics_from_rs(_intrinsics("none")).distortion_model == "none"


@pytest.mark.parametrize("name", ["junk.bag", "junk.db3"])
def test_a_file_that_is_not_a_recording(tmp_path: Path, name: str) -> None:
    path = tmp_path / name
    path.write_bytes(b"not a RealSense recording at all\n" * 10)
    with pytest.raises(SourceError, match="not a RealSense recording"):
        RealSenseSource(str(path))


def test_a_missing_file(tmp_path: Path) -> None:
    with pytest.raises(SourceError, match="no such file"):
        RealSenseSource(str(tmp_path / "nope.bag"))


def test_a_serial_that_is_not_connected() -> None:
    if len(rs.context().query_devices()):
        with pytest.raises(SourceError, match="no RealSense device with serial number 0000nope"):
            RealSenseSource("", serial="0000nope")
    else:
        with pytest.raises(SourceError, match="no RealSense device is connected"):
            RealSenseSource("", serial="0000nope")


def test_close_from_another_thread_ends_a_waiting_read(tmp_path: Path, frames) -> None:
    """The node may close the source on shutdown while its reading thread is in read()."""
    import threading
    import time

    colours, depths = frames
    path = tmp_path / "rec.db3"
    _record(path, colours, depths)
    source = RealSenseSource(str(path))
    got = []
    closer = threading.Timer(0.1, source.close)
    closer.start()
    try:
        while (capture := source.read()) is not None:
            got.append(capture)
            time.sleep(0.05)  # a slow reader: the close comes in the middle of the recording
    finally:
        closer.join()
        source.close()
    assert 0 < len(got) < N
