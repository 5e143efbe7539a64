"""sensor_msgs/msg/LaserScan on the ROS 2 wire: CDR written byte by byte from the OMG CDR rules
(XCDR1, as rmw_zenoh's Fast CDR writes it) read back by the ros2 node's decoder, agreeing with
rosbags' serializer (the one zenoh-ros2-sdk publishes with), and the checks that make a scan
usable or name what is wrong with it."""

from __future__ import annotations

import struct

import numpy as np
import pytest

from common.messages.codec import decode, encode
from common.messages.schemas import LaserScan
from services.ros2.core.scans import ScanError, checked_scan
from services.ros2.core.types import CdrError, known_hashes, types_of

T = types_of()
TYPE = "sensor_msgs/msg/LaserScan"
STAMP = 1_700_000_000_123_456_789


def _cdr(frame_id: str, geometry: tuple[float, ...], ranges: list[float], intensities: list[float],
         big: bool = False) -> bytes:
    """A LaserScan in classic CDR by hand: the encapsulation header (00 01 little endian, 00 00 big),
    then every field aligned to its size from the start of the body."""
    e = ">" if big else "<"
    body = bytearray()

    def align(n: int) -> None:
        body.extend(b"\0" * (-len(body) % n))

    body += struct.pack(e + "iI", STAMP // 10**9, STAMP % 10**9)  # builtin_interfaces/Time
    name = frame_id.encode() + b"\0"
    body += struct.pack(e + "I", len(name)) + name  # a string: its length with the NUL, the bytes, the NUL
    align(4)
    body += struct.pack(e + "7f", *geometry)  # angle_min .. range_max
    for seq in (ranges, intensities):  # float32[]: a uint32 count, the items
        align(4)
        body += struct.pack(e + "I", len(seq)) + struct.pack(e + f"{len(seq)}f", *seq)
    return (b"\x00\x00" if big else b"\x00\x01") + b"\x00\x00" + bytes(body)


GEOMETRY = (-1.5, 1.5, 0.75, 1e-4, 0.1, 0.05, 30.0)  # five beams: -1.5, -0.75, 0, 0.75, 1.5 rad
RANGES = [1.0, float("nan"), float("inf"), 0.01, 2.5]  # a return, no return twice, one below range_min, a return


def _msg(**fields: object) -> object:
    base = dict(header=T.header(STAMP, "laser"), angle_min=-1.5, angle_max=1.5, angle_increment=0.75,
                time_increment=1e-4, scan_time=0.1, range_min=0.05, range_max=30.0,
                ranges=np.array(RANGES, np.float32), intensities=np.zeros(0, np.float32))
    base.update(fields)
    return T.cls(TYPE)(**base)


@pytest.mark.parametrize("frame_id", ["laser", "base_laser_link", ""])
def test_hand_written_cdr_is_rosbags_cdr_and_decodes(frame_id: str) -> None:
    ours = _cdr(frame_id, GEOMETRY, RANGES, [100.0, 0.0, 0.0, 7.0, 50.0])
    theirs = T.serialize(_msg(header=T.header(STAMP, frame_id), intensities=np.array([100, 0, 0, 7, 50], np.float32)),
                         TYPE)
    assert ours == theirs
    msg = T.deserialize(ours, TYPE)
    assert (msg.header.frame_id, msg.header.stamp.sec, msg.header.stamp.nanosec) == (frame_id, STAMP // 10**9,
                                                                                     STAMP % 10**9)
    assert (msg.angle_min, msg.angle_increment, msg.range_max) == pytest.approx((-1.5, 0.75, 30.0))
    np.testing.assert_array_equal(msg.ranges, np.array(RANGES, np.float32))  # NaN and inf kept as sent
    assert msg.intensities.tolist() == [100.0, 0.0, 0.0, 7.0, 50.0]


def test_big_endian_cdr_and_no_intensities() -> None:
    msg = T.deserialize(_cdr("laser", GEOMETRY, RANGES, [], big=True), TYPE)
    assert msg.ranges[0] == 1.0 and msg.ranges[4] == 2.5 and len(msg.intensities) == 0
    scan = LaserScan.from_ros(checked_scan(msg), "front", 3)
    assert scan.intensities is None and scan.header.source == "front" and scan.header.seq == 3


def test_truncated_or_garbage_cdr_is_a_cdr_error() -> None:
    good = _cdr("laser", GEOMETRY, RANGES, [])
    for bad in (good[:30], good[:-4], b"\x00\x01\x00\x00" + b"\xff" * 12, b"\x07\x07\x00\x00" + good[4:]):
        with pytest.raises(CdrError):
            T.deserialize(bad, TYPE)


def test_one_hash_in_every_distribution() -> None:
    assert list(known_hashes(TYPE).values()) == ["jazzy, kilted, rolling"]


def test_a_good_scan_becomes_this_projects_laser_scan_beam_for_beam() -> None:
    msg = T.deserialize(_cdr("/laser", GEOMETRY, RANGES, []), TYPE)
    assert checked_scan(msg) is msg
    scan = LaserScan.from_ros(checked_scan(msg), "front", 1)
    assert (scan.header.stamp_ns, scan.header.frame_id) == (STAMP, "laser")
    np.testing.assert_array_equal(scan.ranges, np.array(RANGES, np.float32))
    back = decode(LaserScan, encode(scan))  # and on this project's wire, NaN and inf still as sent
    np.testing.assert_array_equal(back.ranges, np.array(RANGES, np.float32))


def test_a_clockwise_scan_is_the_same_beams_counter_clockwise() -> None:
    ranges = np.array([1.0, 2.0, 3.0, 4.0, 5.0], np.float32)
    cw = _msg(angle_min=1.5, angle_max=-1.5, angle_increment=-0.75, ranges=ranges,
              intensities=np.arange(5, dtype=np.float32))
    ccw = checked_scan(cw)
    assert (ccw.angle_min, ccw.angle_max, ccw.angle_increment) == pytest.approx((-1.5, 1.5, 0.75))
    assert ccw.ranges.tolist() == [5.0, 4.0, 3.0, 2.0, 1.0] and ccw.intensities.tolist() == [4, 3, 2, 1, 0]
    # each beam keeps its direction: the original's beam i at 1.5 - 0.75 i
    for i, r in enumerate(ranges):
        j = ccw.ranges.tolist().index(r)
        assert ccw.angle_min + j * ccw.angle_increment == pytest.approx(1.5 - 0.75 * i)
    # the last beam was measured last: the stamp moves to it, and time runs backwards over the beams
    stamp = ccw.header.stamp.sec * 10**9 + ccw.header.stamp.nanosec
    assert stamp == STAMP + 4 * 100_000 and ccw.time_increment == pytest.approx(-1e-4)
    assert cw.ranges.tolist() == ranges.tolist()  # the message received is left alone
    assert LaserScan.from_ros(ccw, "front").angle_increment == pytest.approx(0.75)


@pytest.mark.parametrize("fields, reason", [
    (dict(ranges=np.zeros(0, np.float32)), "scan_empty"),
    (dict(angle_increment=0.0), "scan_increment"),
    (dict(angle_increment=float("nan")), "scan_not_finite"),
    (dict(range_max=float("inf")), "scan_not_finite"),
    (dict(range_min=5.0, range_max=1.0), "scan_range_limits"),
    (dict(range_min=-0.1), "scan_range_limits"),
    (dict(ranges=np.ones(9, np.float32)), "scan_length"),
    (dict(ranges=np.ones(2, np.float32)), "scan_length"),
    (dict(angle_min=1.5, angle_max=-1.5), "scan_length"),
    (dict(intensities=np.ones(3, np.float32)), "scan_intensities"),
])
def test_an_unusable_scan_names_its_problem(fields: dict[str, object], reason: str) -> None:
    with pytest.raises(ScanError) as err:
        checked_scan(_msg(**fields))
    assert err.value.reason == reason and str(err.value)


def test_one_beam_more_or_less_is_what_drivers_do() -> None:
    for n in (4, 5, 6):  # angle_max as the last beam's angle, or one past it
        checked_scan(_msg(ranges=np.ones(n, np.float32)))
