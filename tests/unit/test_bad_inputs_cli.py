"""Every offline command on a bad input file: exit 2, one or two lines naming the file, no traceback.

The inputs: a missing file, a directory, an empty file, a binary file, a file of another kind
(a wrong header) and a file of the right kind with a bad value on its line 3, which the message
must name (images, recordings, launch files and transform lists have no line to name: their
message names the file, or the entry). Each command gets the bad file at one of its inputs; the
others are good.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import pytest

from perception.cli import main

KINDS = ("missing", "directory", "empty", "binary", "wrong-header", "bad-value")

K = [500.0, 0.0, 320.0, 0.0, 500.0, 240.0, 0.0, 0.0, 1.0]
GOOD_CAMERA = {"width": 640, "height": 480, "K": K, "D": [0.0] * 5, "distortion_model": "plumb_bob",
               "frame_id": "head_optical"}
DETECTION_LINE = {"image": "f0001.png", "width": 640, "height": 480,
                  "detections": [{"bbox_xyxy": [100, 100, 200, 400], "score": 0.8, "person_id": 1}]}
BINARY = bytes(range(256)) * 4 + b"\xff\xfe\x00\x81"


def _jsonl_bad_value() -> str:
    good = json.dumps(DETECTION_LINE)
    bad = json.dumps({**DETECTION_LINE, "detections": [{"bbox_xyxy": [100, "wide", 200, 400], "score": 0.8,
                                                         "person_id": 2}]})
    return f"{good}\n{good}\n{bad}\n"


#: Per input format: (file name, content of a file of another kind, content with a bad value on line 3).
FORMATS: dict[str, tuple[str, str | bytes, str | bytes]] = {
    "image": ("in.png", "frame,stamp,x,y,z,score\n", b"\x89PNG\r\n\x1a\n" + b"\x00" * 40),
    "jsonl": ("in.jsonl", "frame,stamp,x,y,z,score\n0,0,1,1,1,0.9\n", _jsonl_bad_value()),
    "camera": ("cam.yaml", "frame,stamp,x,y,z,score\n",
               "width: 640\nheight: 480\nK: [500, 0, 320, 0, 500, 240, 0, 0, oops]\n"),
    "track-csv": ("in.csv", "a,b,c\n1,2,3\n",
                  "frame,stamp,x,y,z,score\n0,0.0,1,1,1,0.9\n1,0.1,abc,1,1,0.9\n"),
    "gt-csv": ("in.csv", "a,b,c\n1,2,3\n", "frame,id,x,y,z\n0,1,1,1,1\n1,1,abc,1,1\n"),
    "mot": ("gt.txt", "frame,stamp,x,y,z,score\n", "1,1,10,10,20,60,1\n2,1,10,10,20,60,1\n3,1,abc,10,20,60,1\n"),
    "settings": ("settings.yaml", "frame,stamp,x,y,z,score\n", "{section}:\n  {ok}\n  {bad}\n"),
    "topic-map": ("topics.yaml", "frame,stamp,x,y,z,score\n", "tf: [/tf]\nodom: [/odom]\npair_tolerance_ms: -1\n"),
    "transforms": ("tf.yaml", "frame,stamp,x,y,z,score\n", "- parent_frame: map\n  child_frame: head_optical\n"
                   "  translation: [0, 0, oops]\n"),
    "launch": ("launch.yaml", "frame,stamp,x,y,z,score\n", "services:\n  - name: a\n    command: [1, 2]\n"),
    "recording": ("in.mcap", "frame,stamp,x,y,z,score\n", b"\x89MCAP0\r\n" + b"\x01" * 64),
}


def _good_jsonl(tmp: Path) -> Path:
    p = tmp / "inputs" / "good.jsonl"  # beside the image it names
    p.write_text(json.dumps(DETECTION_LINE) + "\n")
    return p


def _good_depth(tmp: Path) -> Path:
    p = tmp / "depth.png"
    cv2.imwrite(str(p), np.full((480, 640), 2000, np.uint16))
    return p


def _good_camera(tmp: Path) -> Path:
    p = tmp / "good-cam.json"
    p.write_text(json.dumps(GOOD_CAMERA))
    return p


def _good_tracks(tmp: Path) -> Path:
    p = tmp / "good.csv"
    p.write_text("frame,id,x,y,z\n0,1,1,1,1\n")
    return p


#: command -> (input format, argv builder from the bad path and a folder for other files).
COMMANDS: dict[str, tuple[str, Callable[[Path, Path], list[str]]]] = {
    "detect": ("image", lambda bad, tmp: ["detect", str(bad)]),
    "localize --camera-info": ("camera", lambda bad, tmp: [
        "localize", "--camera-info", str(bad), "--depth", str(_good_depth(tmp)), "--detections", str(_good_jsonl(tmp))]),
    "localize --detections": ("jsonl", lambda bad, tmp: [
        "localize", "--camera-info", str(_good_camera(tmp)), "--depth", str(_good_depth(tmp)),
        "--detections", str(bad)]),
    "embed": ("jsonl", lambda bad, tmp: ["embed", str(bad)]),
    "calibrate-embedder": ("jsonl", lambda bad, tmp: ["calibrate-embedder", "--detections", str(bad)]),
    "track": ("track-csv", lambda bad, tmp: ["track", "--detections", str(bad), "--output", str(tmp / "t.csv")]),
    "evaluate": ("gt-csv", lambda bad, tmp: ["evaluate", "--gt", str(bad), "--tracks", str(_good_tracks(tmp))]),
    "inspect": ("recording", lambda bad, tmp: ["inspect", str(bad)]),
    "export-foxglove": ("recording", lambda bad, tmp: ["export-foxglove", str(bad), str(tmp / "out.mcap")]),
    "replay": ("recording", lambda bad, tmp: ["replay", str(bad), "--no-progress"]),
    "localize --depth": ("image", lambda bad, tmp: [
        "localize", "--camera-info", str(_good_camera(tmp)), "--depth", str(bad), "--detections", str(_good_jsonl(tmp))]),
    "localize --transforms": ("transforms", lambda bad, tmp: [
        "localize", "--camera-info", str(_good_camera(tmp)), "--depth", str(_good_depth(tmp)),
        "--detections", str(_good_jsonl(tmp)), "--transforms", str(bad)]),
    "evaluate --tracks": ("gt-csv", lambda bad, tmp: ["evaluate", "--gt", str(_good_tracks(tmp)), "--tracks", str(bad)]),
    "replay --topic-map": ("topic-map", lambda bad, tmp: ["replay", str(bad), "--topic-map", str(bad)]),
    "simulate --service-config": ("settings:simulator", lambda bad, tmp: [
        "simulate", "--service-config", str(bad), "--snapshot", str(tmp / "s.png")]),
    "doctor --recording": ("recording", lambda bad, tmp: ["doctor", "--recording", str(bad)]),
    "launch --dry-run": ("launch", lambda bad, tmp: ["launch", str(bad), "--dry-run"]),
    "track --service-config": ("settings:tracker", lambda bad, tmp: [
        "track", "--detections", str(_good_track_csv(tmp)), "--output", str(tmp / "t.csv"), "--service-config", str(bad)]),
    "detect --service-config": ("settings:detector", lambda bad, tmp: [
        "detect", str(tmp / "inputs" / "f0001.png"), "--service-config", str(bad)]),
    "embed --service-config": ("settings:embedder", lambda bad, tmp: [
        "embed", str(_good_jsonl(tmp)), "--service-config", str(bad)]),
    "calibrate-localizer --detections": ("jsonl", lambda bad, tmp: [
        "calibrate-localizer", "--detections", str(bad), "--ground-truth", str(_good_mot(tmp))]),
    "calibrate-localizer --ground-truth": ("mot", lambda bad, tmp: [
        "calibrate-localizer", "--detections", str(_good_jsonl(tmp)), "--ground-truth", str(bad)]),
}

#: A settings file per section: a good line 2 and a bad value on line 3.
SETTINGS_LINES = {"tracker": ("n_init: 3", "frame_period_s: -5"), "detector": ("backend: hog", "camera: ''"),
                  "embedder": ("backend: colour", "camera: ''"), "simulator": ("fps: 15", "width: -3")}


def _good_mot(tmp: Path) -> Path:
    p = tmp / "good-gt.txt"
    p.write_text("1,1,100,100,100,300,1\n")
    return p


def _good_track_csv(tmp: Path) -> Path:
    p = tmp / "dets.csv"
    p.write_text("frame,stamp,x,y,z,score\n0,0.0,1,1,1,0.9\n")
    return p


def _make(kind: str, fmt: str, folder: Path) -> Path:
    fmt, _, section = fmt.partition(":")
    name, wrong, bad_value = FORMATS[fmt]
    if section:
        ok, bad = SETTINGS_LINES[section]
        bad_value = str(bad_value).format(section=section, ok=ok, bad=bad)
    path = folder / name
    if kind == "missing":
        return path
    if kind == "directory":
        path.mkdir()
        return path
    content: str | bytes = {"empty": b"", "binary": BINARY, "wrong-header": wrong, "bad-value": bad_value}[kind]
    if isinstance(content, str):
        path.write_text(content)
    else:
        path.write_bytes(content)
    return path


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_bad_input_exits_2_with_one_line(command: str, kind: str, tmp_path: Path,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    fmt, argv = COMMANDS[command]
    inputs = tmp_path / "inputs"
    inputs.mkdir()
    # the image the detection lines name, beside them
    cv2.imwrite(str(inputs / "f0001.png"), np.random.default_rng(0).integers(0, 255, (480, 640, 3), np.uint8))
    bad = _make(kind, fmt, inputs)
    code = main(argv(bad, tmp_path))
    out, err = capsys.readouterr()
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == 2, f"exit {code}; stderr:\n{err}"
    assert "Traceback" not in err + out
    assert 1 <= len(lines) <= 2, err
    assert bad.name in err, err
    if kind == "bad-value" and fmt.partition(":")[0] not in ("image", "recording", "launch", "transforms"):
        assert ":3" in err or "line 3" in err, err


@pytest.mark.parametrize("command", ["status", "forget", "detector", "router"])
@pytest.mark.parametrize("endpoint", ["192.168.1.10:7447", "tpc/192.168.1.10:7447"])
def test_endpoint_without_protocol_is_one_line(command: str, endpoint: str,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    """A ``--connect`` endpoint of the wrong form: the expected form, no pydantic text or link."""
    argv = [command, "--connect", endpoint] + (["1"] if command == "forget" else [])
    assert main(argv) == 2
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, err
    assert "--connect" in err and "tcp/192.168.1.10:7447" in err, err
    assert "pydantic" not in err and "validation error" not in err and "Traceback" not in err
