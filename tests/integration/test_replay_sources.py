"""ROS conversion, bag and MCAP sources, the recorder, the replay engine (in memory) and CLI errors."""

from __future__ import annotations

import json
import subprocess
import sys
import threading
from pathlib import Path
from types import SimpleNamespace as NS
from typing import Any

import cv2
import numpy as np
import pytest

from common.messages.codec import decode_any
from common.messages.keys import RELIABLE, Keys
from common.transport.memory import MemoryBus
from common.messages.samples import example_messages, rgbd_frame
from common.messages.schemas import RGBDFrame, TransformBatch
from tests.fixtures.replay_bags import MAP_ODOM_XYZ, STATIC_XYZ, SyntheticRun, write_bag
from tools.replay import rosconv
from tools.replay.bag_source import BagOptions
from tools.replay.core.timeline import TimeWindow
from tools.replay.engine import ReplayOptions, Replayer
from tools.replay.recorder import McapRecorder
from tools.replay.sources import McapSource, SourceError, open_source

KEYS = Keys()
FRAMES = KEYS.frames("head")


def _ros_image(arr: np.ndarray, enc: str, big: bool = False, pad: int = 0) -> NS:
    h, w = arr.shape[:2]
    a = arr.astype(arr.dtype.newbyteorder(">")) if big else arr
    rows = np.ascontiguousarray(a).reshape(h, -1).view(np.uint8)
    rows = np.concatenate([rows, np.zeros((h, pad), np.uint8)], 1)
    return NS(header=NS(stamp=NS(sec=3, nanosec=7), frame_id="/cam"), height=h, width=w, encoding=enc,
              is_bigendian=int(big), step=rows.shape[1], data=rows.reshape(-1))


@pytest.mark.parametrize("enc", ["rgb8", "bgr8", "mono8", "16UC1", "32FC1"])
def test_ros_image_encodings_with_padding_and_byte_order(enc: str) -> None:
    rng = np.random.default_rng(1)
    dtype = {"16UC1": np.uint16, "32FC1": np.float32}.get(enc, np.uint8)
    shape = (6, 5, 3) if enc in ("rgb8", "bgr8") else (6, 5)
    arr = (rng.random(shape) * 200).astype(dtype)
    for big in (False, True):
        img = rosconv.image(_ros_image(arr, enc, big=big, pad=3), "head", seq=4)
        assert img.encoding == enc and img.header.stamp_ns == 3_000_000_007 and img.header.frame_id == "cam"
        expected = arr[..., ::-1] if enc == "bgr8" else arr
        np.testing.assert_array_equal(img.to_array(), expected)


def test_unsupported_image_encoding_is_named() -> None:
    with pytest.raises(rosconv.ConversionError, match="'yuv422' is not supported"):
        rosconv.image(_ros_image(np.zeros((2, 2, 2), np.uint8), "yuv422"), "head")
    short = _ros_image(np.zeros((4, 4), np.uint16), "16UC1")
    short.data = short.data[:10]
    with pytest.raises(rosconv.ConversionError, match="only 10 bytes"):
        rosconv.image(short, "head")


def test_compressed_images() -> None:
    rgb = np.zeros((8, 10, 3), np.uint8)
    rgb[:, :5] = (255, 0, 0)
    for ext in (".jpg", ".png"):
        ok, buf = cv2.imencode(ext, rgb[..., ::-1])
        msg = NS(header=NS(stamp=NS(sec=1, nanosec=0), frame_id="c"), format="bgr8; jpeg compressed bgr8", data=buf.ravel())
        img = rosconv.compressed_image(msg, "head")
        assert img.encoding == ("jpeg" if ext == ".jpg" else "png") and img.shape == (8, 10, 3)
        assert np.abs(img.to_array().astype(int) - rgb).mean() < 10  # jpeg is lossy at the edge
    bad = NS(header=NS(stamp=NS(sec=1, nanosec=0), frame_id="c"), format="16UC1; compressedDepth", data=buf.ravel())
    with pytest.raises(rosconv.ConversionError, match="compressed depth"):
        rosconv.compressed_image(bad, "head")


def test_tf_and_odometry_conversion() -> None:
    def ts(parent: str, child: str, x: float, w: float = 1.0) -> NS:
        return NS(header=NS(stamp=NS(sec=2, nanosec=0), frame_id=parent), child_frame_id=child,
                  transform=NS(translation=NS(x=x, y=0.0, z=0.0), rotation=NS(x=0.0, y=0.0, z=0.0, w=w)))

    batch, bad = rosconv.tf_message(NS(transforms=[ts("/map", "/odom", 1.0), ts("a", "a", 0.0)]), static=True)
    assert bad == 1 and len(batch.transforms) == 1
    t = batch.transforms[0]
    assert (t.parent_frame, t.child_frame, t.static, t.stamp_ns) == ("map", "odom", True, 2_000_000_000)
    with pytest.raises(rosconv.ConversionError, match="none of the 1"):
        rosconv.tf_message(NS(transforms=[ts("a", "b", 0.0, w=0.0)]), static=False)
    odom = NS(header=NS(stamp=NS(sec=5, nanosec=0), frame_id="odom"), child_frame_id="base_footprint",
              pose=NS(pose=NS(position=NS(x=1.0, y=2.0, z=0.0), orientation=NS(x=0.0, y=0.0, z=0.0, w=1.0))))
    ob = rosconv.odometry(odom)
    assert (ob.transforms[0].parent_frame, ob.transforms[0].child_frame) == ("odom", "base_footprint")
    np.testing.assert_allclose(ob.transforms[0].translation, [1, 2, 0])


def _items(path: Path, **kw: Any) -> tuple[list[Any], Any]:
    with open_source(path, BagOptions(**kw)) as src:
        return list(src.items()), src


@pytest.mark.parametrize("kind", ["ros1", "ros2-sqlite3", "ros2-mcap"])
def test_bag_conversion_content(tmp_path: Path, kind: str) -> None:
    run = SyntheticRun(frames=6, rgb_encoding="bgr8" if kind == "ros1" else "rgb8",
                       depth_encoding="32FC1" if kind == "ros2-mcap" else "16UC1", row_padding=2)
    path = write_bag(tmp_path / ("run.bag" if kind == "ros1" else "run"), run, kind)  # type: ignore[arg-type]
    items, src = _items(path)
    assert "/chatter" in src.skipped and not src.problems
    frames = [it.message for it in items if it.key == FRAMES]
    assert [f.header.stamp_ns for f in frames] == [run.stamp(i) for i in range(6)]
    for i, f in enumerate(frames):
        assert isinstance(f, RGBDFrame) and f.header.seq == i and f.header.source == "head"
        np.testing.assert_array_equal(f.rgb.to_array(), run.rgb(i))
        np.testing.assert_allclose(f.depth.depth_m(), np.where(run.depth_mm(i) > 0, run.depth_mm(i) / 1000, np.nan), rtol=1e-6)
        np.testing.assert_allclose(f.camera_info.K, run.K())
    static = [it.message for it in items if it.key == KEYS.tf_static()]
    assert len(static) == 1 and static[0].transforms[0].static
    np.testing.assert_allclose(static[0].transforms[0].translation, STATIC_XYZ)
    tf = [it.message for it in items if it.key == KEYS.tf()]
    odom = [b.transforms[0] for b in tf if b.transforms[0].parent_frame == "odom"]
    maps = [b.transforms[0] for b in tf if b.transforms[0].parent_frame == "map"]
    assert [o.child_frame for o in odom] == ["base_link"] * 6 and len(maps) == 6
    np.testing.assert_allclose([o.translation[0] for o in odom], [run.odom_x(i) for i in range(6)])
    np.testing.assert_allclose(maps[0].translation, MAP_ODOM_XYZ)


def test_bag_topic_flags_and_unknown_image_encoding(tmp_path: Path) -> None:
    run = SyntheticRun(frames=3)
    path = write_bag(tmp_path / "odd.bag", run, "ros1", rgb_topic="/front/rgb", depth_topic="/front/depth",
                     info_topic="/front/info")
    items, src = _items(path, cameras={"front": {"rgb": "/front/rgb", "depth": "/front/depth", "camera_info": "/front/info"}})
    assert len([it for it in items if it.key == KEYS.frames("front")]) == 3
    items, src = _items(path, cameras={"front": {"rgb": "/front/rgb", "depth": "/front/info"}})
    assert "cannot be the depth stream" in src.skipped["/front/info"]


def test_a_ros2_mcap_file_without_its_folder_is_read_as_a_bag(tmp_path: Path) -> None:
    run = SyntheticRun(frames=4)
    folder = write_bag(tmp_path / "run", run, "ros2-mcap")
    (mcap_file,) = folder.glob("*.mcap")
    bare = tmp_path / "bare.mcap"
    bare.write_bytes(mcap_file.read_bytes())
    with open_source(bare) as src:
        assert src.summary().format == "ROS 2 bag"
        assert len([it for it in src.items() if it.key == FRAMES]) == 4


def _record(path: Path, msgs: list[tuple[str, Any, int]]) -> None:
    with McapRecorder(path, key_exprs=[KEYS.all()], writer_version="test") as rec:
        for key, msg, log_ns in msgs:
            rec.write(key, msg, log_ns)


def test_mcap_record_is_self_describing_and_reads_back(tmp_path: Path) -> None:
    from mcap.reader import make_reader

    msgs = [(KEYS.frames("head"), rgbd_frame(32, 24, seq=i, stamp_ns=10**18 + i * 10**8), 10**18 + i * 10**8 + 5)
            for i in range(3)] + [(KEYS.tf(), m, 10**18 + 7) for m in example_messages(10**18 + 1) if isinstance(m, TransformBatch)]
    _record(tmp_path / "r.mcap", msgs)
    with (tmp_path / "r.mcap").open("rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None
        schemas = {s.name: s for s in summary.schemas.values()}
        assert set(schemas) == {"perception.RGBDFrame", "perception.TransformBatch"}
        assert schemas["perception.RGBDFrame"].encoding == "jsonschema"
        assert "camera_info" in json.loads(schemas["perception.RGBDFrame"].data)["properties"]
        channels = {c.topic: c for c in summary.channels.values()}
        assert channels[FRAMES].message_encoding == "msgpack" and channels[FRAMES].metadata["schema_version"] == "1"
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
        assert json.loads(meta["perception"]["schema_versions"])["perception.RGBDFrame"] == 1
        stamps = [(m.publish_time, m.log_time) for _, c, m in reader.iter_messages() if c.topic == FRAMES]
        assert stamps == [(10**18 + i * 10**8, 10**18 + i * 10**8 + 5) for i in range(3)]
    with open_source(tmp_path / "r.mcap") as src:
        got = [(it.key, decode_any(it.encoded())) for it in src.items()]
        summary = src.summary()
    assert sorted(got, key=lambda kv: kv[1].header.stamp_ns) == sorted(((k, m) for k, m, _ in msgs), key=lambda kv: kv[1].header.stamp_ns)
    assert {s.name: s.count for s in summary.streams} == {FRAMES: 3, KEYS.tf(): 1}


def test_replay_engine_in_memory_orders_by_stamp_and_selects(tmp_path: Path) -> None:
    # recorded out of stamp order (derived message received late), plus a static transform
    stamps = [10**18 + i * 10**7 for i in range(10)]
    msgs = [(FRAMES, rgbd_frame(16, 12, seq=i, stamp_ns=s), s + 10**6) for i, s in enumerate(stamps)]
    msgs.insert(5, msgs.pop(2))
    _record(tmp_path / "r.mcap", msgs)
    bus = MemoryBus()
    sub = bus.transport().subscribe(KEYS.all(), None, RELIABLE)

    def replay(**kw: Any) -> list[int]:
        with open_source(tmp_path / "r.mcap") as src:
            Replayer(bus.transport(), src, ReplayOptions(wait_subscribers_s=0, **kw)).run(threading.Event())
        out = []
        while (r := sub.try_recv()) is not None:
            out.append(r.msg.header.stamp_ns)
        return out

    assert replay(rate=None) == stamps
    assert replay(rate=None, window=TimeWindow(0.025, 0.055)) == stamps[3:6]
    assert replay(rate=None, loop=False, remap=[("pp/robot", "pp/other")]) == []  # remapped away from our sub
    other = bus.transport().subscribe("pp/other/**", None, RELIABLE)
    replay(rate=None, remap=[("pp/robot", "pp/other")])
    assert other.stats.received == 10


def test_loop_replays_until_stopped(tmp_path: Path) -> None:
    # Paced at recorded speed (10 ms apart): as fast as possible, an endless loop would
    # overflow the subscriber's bounded FIFO before a loaded test process reads it.
    stamps = [10**18 + i * 10**7 for i in range(5)]
    _record(tmp_path / "r.mcap", [(FRAMES, rgbd_frame(16, 12, seq=i, stamp_ns=s), s) for i, s in enumerate(stamps)])
    bus = MemoryBus()
    sub = bus.transport().subscribe(FRAMES, None, RELIABLE)
    stop = threading.Event()
    with open_source(tmp_path / "r.mcap") as src:
        replayer = Replayer(bus.transport(), src, ReplayOptions(rate=1.0, loop=True, wait_subscribers_s=0))
        worker = threading.Thread(target=replayer.run, args=(stop,))
        worker.start()
        got: list[int] = []
        while len(got) < 12 and (r := sub.recv(timeout=30)) is not None:
            got.append(r.msg.header.stamp_ns)
        stop.set()
        worker.join(timeout=30)
    assert not worker.is_alive()
    assert got[:12] == (stamps * 3)[:12]
    assert replayer.stats.passes >= 2


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "perception", *args], capture_output=True, text=True, timeout=60)


def _assert_clean_error(proc: subprocess.CompletedProcess[str], path: Path, problem: str) -> None:
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr
    assert f"perception: error: {path}" in proc.stderr and problem in proc.stderr, proc.stderr


def test_cli_errors_name_the_file_and_the_problem(tmp_path: Path) -> None:
    # the error cases that fail before any Zenoh session is opened, one subprocess each
    missing = tmp_path / "nope.mcap"
    _assert_clean_error(_cli("inspect", str(missing)), missing, "no such file")
    corrupt = tmp_path / "corrupt.mcap"
    corrupt.write_bytes(b"\x89MCAP0\r\n" + bytes(range(256)) * 4)
    _assert_clean_error(_cli("replay", str(corrupt)), corrupt, "MCAP")
    junk = tmp_path / "junk.bag"
    junk.write_bytes(b"hello world, not a bag")
    _assert_clean_error(_cli("inspect", str(junk)), junk, "unknown file format")
    from rosbags.rosbag2 import Writer as Writer2
    from rosbags.typesys import Stores, get_typestore

    empty = tmp_path / "empty"
    with Writer2(empty, version=9) as w2:
        w2.add_connection("/camera/rgb/image_raw", "sensor_msgs/msg/Image", typestore=get_typestore(Stores.ROS2_HUMBLE))
    _assert_clean_error(_cli("replay", str(empty)), empty, "no messages")
    cut_bag = write_bag(tmp_path / "cut.bag", SyntheticRun(frames=3), "ros1")
    cut_bag.write_bytes(cut_bag.read_bytes()[:3000])
    _assert_clean_error(_cli("inspect", str(cut_bag)), cut_bag, "not a readable ROS bag")
    # a recording whose channels are not msgpack: nothing to replay, named encoding
    from mcap.writer import Writer

    other = tmp_path / "json.mcap"
    with other.open("wb") as f:
        w = Writer(f)
        w.start()
        ch = w.register_channel(topic="/x", message_encoding="json", schema_id=0)
        w.add_message(ch, log_time=1, data=b"{}", publish_time=1)
        w.finish()
    _assert_clean_error(_cli("replay", str(other)), other, "message encoding 'json'")


def test_truncated_mcap_is_reported_after_the_readable_part(tmp_path: Path) -> None:
    msgs = [(FRAMES, rgbd_frame(64, 48, seq=i, stamp_ns=10**18 + i * 10**7), 10**18 + i * 10**7) for i in range(20)]
    from mcap.writer import CompressionType, Writer  # small chunks so the cut keeps some of them

    path = tmp_path / "cut.mcap"
    with path.open("wb") as f:
        w = Writer(f, chunk_size=20_000, compression=CompressionType.NONE)
        w.start()
        sid = w.register_schema("perception.RGBDFrame", "jsonschema", b"{}")
        ch = w.register_channel(FRAMES, "msgpack", sid)
        from common.messages.codec import encode

        for _, m, t in msgs:
            w.add_message(ch, t, encode(m), m.header.stamp_ns)
        w.finish()
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    got = []
    with McapSource(path) as src, pytest.raises(SourceError, match="truncated") as err:
        for it in src.items():
            got.append(it)
    assert str(path) in str(err.value)
    assert 0 < len(got) < 20
    assert [decode_any(it.encoded()) for it in got] == [m for _, m, _ in msgs[: len(got)]]
    proc = _cli("inspect", str(path))
    assert proc.returncode == 0 and "truncated" in proc.stdout, proc.stdout + proc.stderr


def test_topic_map_file_and_flags(tmp_path: Path) -> None:
    from common.runtime.config import ConfigError
    from tools.replay.config import load_topic_map

    path = tmp_path / "topics.yaml"
    path.write_text("cameras:\n  front:\n    rgb: /front/rgb\n    depth: /front/depth\nodom: []\npair_tolerance_ms: 30\n")
    cfg = load_topic_map(path, "front", {"camera_info": "/front/info", "tf": ["/tf", "/tf2"]})
    assert cfg.camera_dict() == {"front": {"rgb": "/front/rgb", "depth": "/front/depth", "camera_info": "/front/info"}}
    assert cfg.list_dict() == {"tf": ["/tf", "/tf2"], "odom": []} and cfg.pair_tolerance_ms == 30
    path.write_text("cameras:\n  front:\n    colour: /front/rgb\n")
    with pytest.raises(ConfigError, match="colour"):
        load_topic_map(path, "front", {})
    path.write_text("cameras:\n  front:\n    rgb: front/rgb\n")
    with pytest.raises(ConfigError, match="must start with '/'"):
        load_topic_map(path, "front", {})
