"""A laser's scans in Foxglove's well-known ``foxglove.LaserScan`` (tools/foxglove/bridge.py):
the fields, where Foxglove puts each beam, no return as nothing drawn, and the message as the
SDK encodes it and an MCAP reader decodes it with the schema the file carries."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from common.messages.schemas import Header, LaserScan, LocalizedDetection, LocalizedDetections
from tools.foxglove.bridge import scan_fields, scan_topic

T0 = 1_700_000_000_123_456_789


def _scan(n: int = 9, intensities: bool = True, source: str = "front", frame: str = "front_laser") -> LaserScan:
    inc = math.radians(30)
    ranges = np.linspace(1.0, 5.0, n).astype(np.float32)
    ranges[[1, 3, 5, 7]] = [np.nan, np.inf, 0.01, 40.0]  # no returns: NaN, inf, below and above the limits
    return LaserScan(header=Header(stamp_ns=T0, frame_id=frame, seq=4, source=source),
                     angle_min=-2 * math.pi / 3, angle_max=-2 * math.pi / 3 + (n - 1) * inc + 1e-4,  # a rounded max
                     angle_increment=inc, time_increment=1e-4, scan_time=0.1, range_min=0.05, range_max=30.0,
                     ranges=ranges, intensities=np.arange(n, dtype=np.float32) * 10 if intensities else None)


def test_fields_place_each_beam_where_foxglove_draws_it() -> None:
    scan = _scan()
    f = scan_fields(scan)
    assert f["timestamp_ns"] == T0 and f["frame_id"] == "front_laser"
    n = len(f["ranges"])
    assert n == 9
    # Foxglove spaces the beams evenly from start_angle to end_angle: beam i at angle_min + i * increment
    foxglove_angles = f["start_angle"] + np.arange(n) * (f["end_angle"] - f["start_angle"]) / (n - 1)
    assert foxglove_angles == pytest.approx(scan.angle_min + np.arange(n) * scan.angle_increment, abs=1e-12)
    ranges = np.array(f["ranges"])
    assert np.isnan(ranges[[1, 3, 5, 7]]).all()  # no return: NaN, which Foxglove does not draw
    assert ranges[[0, 2, 4, 6, 8]] == pytest.approx([1.0, 2.0, 3.0, 4.0, 5.0])
    assert f["intensities"] == [10.0 * i for i in range(9)]
    assert scan_fields(_scan(intensities=False))["intensities"] == []
    assert scan_fields(_scan(frame=""))["frame_id"] == "laser"


def test_each_laser_has_its_own_topic() -> None:
    assert scan_topic(_scan(source="front")) == "/scans/front"
    assert scan_topic(_scan(source="rear")) == "/scans/rear"
    assert scan_topic(_scan(source="")) == "/scans/laser"


def _decoder(schema_name: str, data: bytes) -> Any:
    from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

    pool = descriptor_pool.DescriptorPool()
    for file in descriptor_pb2.FileDescriptorSet.FromString(data).file:
        pool.Add(file)
    return message_factory.GetMessageClass(pool.FindMessageTypeByName(schema_name)).FromString


def _check_decoded(msg: Any, scan: LaserScan) -> None:
    assert (msg.timestamp.seconds, msg.timestamp.nanos) == (T0 // 10**9, T0 % 10**9)
    assert msg.frame_id == "front_laser"
    assert (msg.pose.orientation.w, msg.pose.position.x) == (1.0, 0.0)
    assert msg.start_angle == pytest.approx(scan.angle_min)
    assert msg.end_angle == pytest.approx(scan.angle_min + 8 * scan.angle_increment)
    ranges = np.array(msg.ranges)
    assert len(ranges) == 9 and np.isnan(ranges[[1, 3, 5, 7]]).all()
    assert ranges[[0, 2, 4, 6, 8]] == pytest.approx([1.0, 2.0, 3.0, 4.0, 5.0])
    assert list(msg.intensities) == [10.0 * i for i in range(9)]


def test_the_sdks_message_decodes_to_the_fields() -> None:
    pytest.importorskip("foxglove", reason="Foxglove needs foxglove-sdk (the 'view' extra)")
    pytest.importorskip("google.protobuf", reason="decoding Foxglove's protobuf schemas needs protobuf")
    from foxglove import messages as m

    from tools.foxglove.bridge import FoxgloveBridge

    scan = _scan()
    schema = m.LaserScan.get_schema()
    assert (schema.name, schema.encoding) == ("foxglove.LaserScan", "protobuf")
    _check_decoded(_decoder(schema.name, schema.data)(FoxgloveBridge()._laser_scan(scan).encode()), scan)


def test_an_mcap_file_has_a_laserscan_channel_per_laser(tmp_path: Path) -> None:
    pytest.importorskip("foxglove", reason="Foxglove needs foxglove-sdk (the 'view' extra)")
    pytest.importorskip("google.protobuf", reason="decoding Foxglove's protobuf schemas needs protobuf")
    from mcap.reader import make_reader

    from tools.foxglove.bridge import FoxgloveMcap

    out = tmp_path / "scans.mcap"
    front, rear = _scan(), _scan(source="rear")
    with FoxgloveMcap(out) as mcap:
        for k in range(3):
            mcap.write("scans/front", front)
        mcap.write("scans/rear", rear)
        assert mcap.counts == {"/scans/front": 3, "/scans/rear": 1}
    seen: dict[str, list[Any]] = {}
    with out.open("rb") as f:
        for schema, channel, message in make_reader(f).iter_messages():
            assert schema is not None and schema.name == "foxglove.LaserScan" and channel.message_encoding == "protobuf"
            seen.setdefault(channel.topic, []).append(_decoder(schema.name, schema.data)(message.data))
            assert message.log_time == T0
    assert {t: len(v) for t, v in seen.items()} == {"/scans/front": 3, "/scans/rear": 1}
    _check_decoded(seen["/scans/front"][0], front)


def test_a_lasers_people_leave_the_cameras_view_for_the_boxes_alone() -> None:
    pytest.importorskip("foxglove", reason="Foxglove needs foxglove-sdk (the 'view' extra)")
    from tools.foxglove.bridge import FoxgloveBridge

    bridge = FoxgloveBridge()
    camera = object()
    bridge._view = camera  # type: ignore[assignment]  # as a camera's localized detections left it
    people = LocalizedDetections(header=Header(stamp_ns=T0, frame_id="map", source="front"), detector="laser-legs",
                                 detections=[LocalizedDetection(index=0, bbox_xyxy=(0, 0, 0, 0), score=0.8,
                                                                position=np.array([1.0, 2.0, 0.9]), cov=np.eye(3) * 0.01,
                                                                depth_m=2.2)])
    bridge.on_message("localized/front", people)
    assert bridge._view is camera
    assert bridge.counts == {"/perception/localized": 1}
