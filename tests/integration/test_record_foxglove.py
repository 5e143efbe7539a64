"""``perception record --foxglove``: while recording live streams from a real router, the same
messages also go into an MCAP file in Foxglove's well-known schemas, read back here with the
``mcap`` reader; bad paths fail before anything is recorded."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from common.runtime.cli_util import CliError
from common.messages.keys import Delivery, Keys
from common.transport.router_process import RouterProcess
from common.transport.zenoh import ZenohTransport
from tests.fixtures.viewer_scene import scene_messages
from tests.helpers.recording import stop_recording, wait_recorded

pytest.importorskip("foxglove", reason="Foxglove needs foxglove-sdk (the 'view' extra)")

KEYS = Keys(robot="recordfox")
FIFO = Delivery(latest=False, queue=4096, congestion="block")
TIMEOUT = 90.0
FRAMES = 8
#: Foxglove topic -> its schema name, or "json" for the messages written as JSON; one message per scene frame each
#: (the robot's map: one, the scene sends it on its first frame)
EXPECTED = {
    "/camera/image": "foxglove.CompressedImage",
    "/camera/annotations": "foxglove.ImageAnnotations",
    "/people": "foxglove.SceneUpdate",
    "/tf": "foxglove.FrameTransforms", "/map": "foxglove.Grid",
    "/perception/tracks": "json", "/perception/detections": "json", "/perception/localized": "json",
    "/perception/status": "json",
}


def _record(*args: str) -> list[str]:
    return [sys.executable, "-m", "perception", "-q", "record", "--robot", KEYS.robot, *args]


def _mcap_counts(path: Path) -> tuple[dict[str, int], dict[str, str]]:
    """Messages per topic and each topic's schema name ("json" for JSON messages), as the ``mcap`` reader sees them."""
    from mcap.reader import make_reader

    counts: dict[str, int] = {}
    schemas: dict[str, str] = {}
    with path.open("rb") as f:
        for schema, channel, _message in make_reader(f).iter_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            schemas[channel.topic] = "json" if channel.message_encoding == "json" else schema.name if schema else ""
    return counts, schemas


@pytest.mark.zenoh
def test_record_writes_the_live_streams_in_foxglove_schemas_too(tmp_path: Path, router: RouterProcess,
                                                                 zenoh_client: Callable[[], ZenohTransport]) -> None:
    out, fox = tmp_path / "run.mcap", tmp_path / "run-foxglove.mcap"
    recorder = subprocess.Popen(_record("--output", str(out), "--foxglove", str(fox), "--connect", router.endpoint),
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        client = zenoh_client()
        pubs: dict[str, Any] = {key: client.publisher(key, type(msg), FIFO)  # type: ignore[arg-type]
                                for key, msg in scene_messages(0, 0.0, KEYS)}
        for p in pubs.values():
            assert p.wait_for_subscribers(TIMEOUT), "the recorder did not subscribe"
        sent: dict[str, int] = {}
        for seq in range(FRAMES):
            for key, msg in scene_messages(seq, seq / 15, KEYS):
                pubs[key].put(msg)
                sent[key] = sent.get(key, 0) + 1
        assert wait_recorded(client, KEYS, sum(sent.values()), TIMEOUT) >= sum(sent.values())
        stdout, stderr = stop_recording(recorder, TIMEOUT)
    finally:
        if recorder.poll() is None:
            recorder.kill()
            recorder.wait()
    assert recorder.returncode == 0, stderr
    assert f"into {fox}" in stdout, stdout

    native, _ = _mcap_counts(out)  # the replayable recording is unchanged: every message, msgpack
    assert native == sent, native
    counts, schemas = _mcap_counts(fox)  # embeddings have no Foxglove topic
    assert schemas == EXPECTED, schemas
    assert counts == {topic: 1 if topic == "/map" else FRAMES for topic in EXPECTED}, counts  # the map: once


def test_bad_foxglove_paths_fail_before_recording(tmp_path: Path) -> None:
    out, fox = tmp_path / "run.mcap", tmp_path / "fox.mcap"
    fox.write_bytes(b"")
    a_file = tmp_path / "a-file"
    a_file.write_text("not a folder")
    cases = {
        "exists (--force to overwrite it)": ["--output", str(out), "--foxglove", str(fox)],
        "are the same file": ["--output", str(out), "--foxglove", str(out)],
        "does not exist": ["--output", str(out), "--foxglove", str(a_file / "fox.mcap")],
        "is a folder": ["--output", str(out), "--foxglove", str(tmp_path), "--force"],
    }
    for message, args in cases.items():
        res = subprocess.run(_record(*args, "--duration", "0"), capture_output=True, text=True, timeout=60,
                             check=False)
        assert res.returncode == 2 and message in res.stderr, (args, res.stderr)
        assert "Traceback" not in res.stderr
        assert not out.exists(), args  # nothing was recorded
    assert fox.read_bytes() == b""  # an existing file is kept without --force


def test_a_foxglove_file_that_cannot_be_written_is_a_clear_error(tmp_path: Path) -> None:
    from tools.replay.export_foxglove_cli import open_foxglove_mcap

    with pytest.raises(CliError, match="cannot be written"):
        open_foxglove_mcap(tmp_path)  # a folder in the file's place
