"""perception doctor offline: the pure checks on hand-made facts, the collector on encoded
payloads (invalid frames included), and --recording on a simulated MCAP file."""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from common.messages.codec import encode
from common.messages.keys import Keys
from common.messages.schemas import Header, ServiceStatus
from perception.cli import main as cli_main
from tools.doctor.collect import Observer
from tools.doctor.core.checks import exit_code, render, run_checks, to_dicts
from tools.doctor.core.facts import (
    Check,
    NodeFacts,
    Observation,
)
from tests.helpers.doctor_facts import N, S, T0, healthy
from tools.simulator.config import SimulatorConfig
from tools.simulator.source import SimulatedStream

def node(obs: Observation, service: str) -> NodeFacts:
    return next(n for n in obs.nodes if n.service == service)


def the(checks: list[Check], name: str) -> Check:
    found = [c for c in checks if c.name == name]
    assert len(found) == 1, f"no single check {name!r} in {[c.name for c in checks]}"
    return found[0]


def test_a_healthy_pipeline_passes_every_check() -> None:
    checks = run_checks(healthy())
    assert [c for c in checks if c.status != "ok"] == []
    assert exit_code(checks) == 0
    sections = {c.section for c in checks}
    assert sections == {"Streams", "Camera", "Transforms", "Clocks", "Chain", "Config"}
    text = render(checks, "perception doctor: test")
    assert "✓ frames/head" in text and "all checks pass" in text and "✗" not in text
    assert the(checks, "frames → tracks (head)").figure == (
        "frames 24 → detections 24 → localized 24 → embeddings 24 → tracks 24")


def _float_mm(o: Observation) -> None:
    for f in o.frames["head"]:
        f.depth_encoding = "32FC1"


def _half_size(o: Observation) -> None:
    for f in o.frames["head"]:
        f.depth_hw = (120, 160)


def _zero_k(o: Observation) -> None:
    for f in o.frames["head"]:
        f.K = np.zeros((3, 3))


def _no_odom_edge(o: Observation) -> None:
    o.edges = [e for e in o.edges if e.child != "base_link"]
    node(o, "localizer").counters["dropped_no_transform"] = N
    o.stages["head"]["localized"] = {}
    o.stages["head"]["tracks"] = {}


def _static_once(o: Observation) -> None:
    o.edges = [e for e in o.edges if not e.static]
    o.streams["tf_static"].count = 0


def _old_stamps(o: Observation) -> None:
    o.offsets_ns["head"] = [5 * S + 20_000_000] * N


def _embedder_stopped(o: Observation) -> None:
    o.nodes = [n for n in o.nodes if n.service != "embedder"]
    del o.streams["embeddings/head"]
    o.stages["head"]["embeddings"] = {}
    o.cards = []
    o.position_only = N
    node(o, "tracker").counters["position_only_timeout"] = N


def _tracker_model(o: Observation) -> None:
    t = node(o, "tracker")
    t.settings["embedding_model"] = "trinet"
    t.counters["dropped_wrong_model"] = N
    o.track_models = ["trinet"]
    o.position_only = N


def _camera_mismatch(o: Observation) -> None:
    t = node(o, "tracker")
    t.settings["camera"] = "front"
    t.subscribes = ["localized/front", "embeddings/front"]
    t.counters["received"] = 0
    o.streams["tracks"].count = 0
    o.stages["head"]["tracks"] = {}


def _embedder_failed(o: Observation) -> None:
    e = node(o, "embedder")
    e.state, e.alive, e.exit_status = "failed", False, 2
    e.error = "perception: error: ONNX model file not found: /models/reid.onnx"
    e.counters = {}
    del o.streams["embeddings/head"]
    o.stages["head"]["embeddings"] = {}
    node(o, "tracker").counters["position_only_frames"] = N


FAULTS: dict[str, tuple[Callable[[Observation], None], str, str, str]] = {
    # fault: (mutation, the check that fails, in its figure, in its fix)
    "depth in float millimetres": (_float_mm, "depth unit (head)", "millimetres stored as floats", "divide the depth by 1000"),
    "depth half the colour size": (_half_size, "depth registered (head)", "depth 160x120, colour 320x240",
                                   "register depth to the colour camera"),
    "zero K": (_zero_k, "camera info (head)", "K is all zeros", "calibration"),
    "no odom -> base_link": (_no_odom_edge, "chain map ← camera", "missing odom → base_link", "publish odom → base_link"),
    "static transforms once": (_static_once, "static transforms", "no tf_static in 3.0 s", "republish static transforms"),
    "stamps 5 s old": (_old_stamps, "frame stamps (head)", "stamped 5.0 s before they arrive", "synchronise"),
    "embedder stopped": (_embedder_stopped, "embedder", "not running", "perception embedder"),
    "tracker for another model": (_tracker_model, "embedding model", "the tracker takes trinet",
                                  "set the tracker's embedding_model to colour"),
    "camera name mismatch": (_camera_mismatch, "camera names", "tracker front",
                             "set the tracker's camera to head"),
    "embedder failed": (_embedder_failed, "embedder", "ONNX model file not found", "fix what the error says"),
}


@pytest.mark.parametrize("fault", FAULTS)
def test_each_fault_fails_its_line_with_its_hint(fault: str) -> None:
    mutate, name, figure, fix = FAULTS[fault]
    obs = healthy()
    mutate(obs)
    checks = run_checks(obs)
    check = the(checks, name)
    assert check.status == "fail", check
    assert figure in check.figure and fix in check.fix, check
    assert exit_code(checks) == 2


def test_a_failed_node_shows_its_error_and_the_trackers_position_only_counter() -> None:
    obs = healthy()
    _embedder_failed(obs)
    check = the(run_checks(obs), "embedder")
    assert check.figure.startswith("FAILED (exit status 2, not restarted): perception: error: ONNX model file")
    assert "tracker position_only_frames=24, position_only_timeout=0" in check.figure


def test_the_chain_names_the_first_stage_that_loses_frames_and_its_counted_reason() -> None:
    obs = healthy()
    _no_odom_edge(obs)
    chain = the(run_checks(obs), "frames → tracks (head)")
    assert chain.status == "fail"
    assert "localizer passes 0 of" in chain.figure and "no_transform (24 dropped by the localizer)" in chain.figure
    obs = healthy()
    _camera_mismatch(obs)
    chain = the(run_checks(obs), "frames → tracks (head)")
    assert "the tracker listens to localized/front, not localized/head" in chain.figure


def test_depth_units_are_judged_by_their_values() -> None:
    obs = healthy()
    for f in obs.frames["head"]:
        f.depth_encoding, f.depth_sample = "32FC1", f.depth_sample / 1000.0  # type: ignore[operator]
    assert the(run_checks(obs), "depth unit (head)").status == "ok"
    obs = healthy()
    for f in obs.frames["head"]:
        f.depth_sample = np.round(f.depth_sample / 1000.0)  # type: ignore[operator]
    check = the(run_checks(obs), "depth unit (head)")
    assert check.status == "fail" and "metres stored as integers" in check.figure


def test_a_fixed_camera_needs_no_dynamic_transforms() -> None:
    obs = healthy()
    del obs.streams["tf"]
    obs.edges = [dataclasses.replace(e, static=True) for e in obs.edges]
    checks = run_checks(obs)
    assert [c for c in checks if c.status != "ok"] == []
    assert "tf_static" in the(checks, "tf").figure


def test_a_camera_placed_on_the_floor_by_its_homography_needs_no_depth_and_no_transforms() -> None:
    obs = healthy()
    for key in ("tf", "tf_static"):
        del obs.streams[key]
    obs.edges = []
    obs.frames = {"head": [dataclasses.replace(f, depth_hw=None, depth_encoding="", depth_sample=None)
                           for f in obs.frames["head"]]}
    broken = run_checks(obs)  # a camera without depth or transforms, as far as the doctor knows: failures
    assert {c.name for c in broken if c.status != "ok"} >= {"tf", "depth registered (head)", "chain map ← camera"}
    obs.floor_cameras, obs.floor_camera_frames = ["head"], ["camera"]  # its people came with a floor view
    checks = run_checks(obs)
    assert [c for c in checks if c.status != "ok"] == []
    assert "homography" in the(checks, "tf").figure and "homography" in the(checks, "chain map ← camera").figure


def test_the_collector_notes_cameras_placed_by_a_floor_homography() -> None:
    from common.messages.schemas import FloorCameraView, LocalizedDetections

    observer = Observer()
    for k, floor in enumerate((None, FloorCameraView(image_to_frame=np.eye(3), width=640, height=480))):
        observer.message("localized/head", LocalizedDetections(header=Header(stamp_ns=T0 + k, frame_id="map"),
                                                               camera_frame="head_optical", floor_view=floor), T0 + k)
    obs = observer.observation(3.0)
    assert (obs.floor_cameras, obs.floor_camera_frames) == (["head"], ["head_optical"])


def test_a_warning_gives_exit_status_1_and_a_replay_explains_old_stamps() -> None:
    obs = healthy()
    _old_stamps(obs)
    obs.nodes.append(NodeFacts("replay", "pc-9"))
    checks = run_checks(obs)
    assert the(checks, "frame stamps (head)").status == "warn"
    assert exit_code(checks) == 1


def test_json_form_holds_every_field() -> None:
    obs = healthy()
    _zero_k(obs)
    rows = to_dicts(run_checks(obs))
    row = next(r for r in rows if r["name"] == "camera info (head)")
    assert set(row) == {"section", "name", "status", "figure", "fix"} and row["status"] == "fail"
    json.dumps(rows)


# ------------------------------------------------------------------ the collector


def _observe(fault: str | None, frames: int = 6) -> Observation:
    keys = Keys(robot="offline")
    stream = SimulatedStream(SimulatorConfig(width=160, height=120, fps=8, start_ns=T0, faults=[fault] if fault else []),
                             keys)
    observer = Observer()
    for seq in range(frames):
        _, pairs = stream.messages(seq)
        for key, msg in pairs:
            observer.payload(key, encode(msg), stream.stamp_ns(seq) + 30_000_000)
    return observer.observation(1.0)


@pytest.mark.parametrize(("fault", "name", "figure"), [
    (None, "camera info (head)", "160x120, fx 131.2 fy 131.2"),
    ("zero-k", "camera info (head)", "K is all zeros"),
    ("depth-half-size", "depth registered (head)", "depth 80x60, colour 160x120"),
    ("depth-float-mm", "depth unit (head)", "millimetres stored as floats"),
])
def test_the_collector_reads_frames_the_nodes_refuse(fault: str | None, name: str, figure: str) -> None:
    obs = _observe(fault)
    frames = obs.streams["frames/head"]
    assert frames.count == 6 and frames.invalid == (6 if fault in ("zero-k", "depth-half-size") else 0)
    check = the(run_checks(obs), name)
    assert figure in check.figure and check.status == ("ok" if fault is None else "fail"), check
    assert obs.offsets_ns["head"] == [30_000_000] * 6  # read from invalid frames too


def test_the_collector_follows_the_transform_tree_and_status_counters() -> None:
    obs = _observe("no-odom-edge")
    assert {(e.parent, e.child) for e in obs.edges} == {("map", "odom"), ("base_link", "head_link"),
                                                        ("head_link", "camera")}
    observer = Observer()
    for uptime, dropped in ((5.0, 3), (8.0, 10)):
        observer.status(ServiceStatus(header=Header(stamp_ns=T0), name="localizer", instance="pc-1", uptime_s=uptime,
                                      received=int(uptime * 10), extra={"dropped_no_transform": dropped},
                                      publishes=["pp/robot/perception/v1/localized/head"]))
    observer.liveliness("localizer", "pc-1", True)
    n = observer.observation(3.0).nodes[0]
    assert (n.window_s, n.counters["dropped_no_transform"], n.counters["received"]) == (3.0, 7, 30)
    assert n.publishes == ["localized/head"] and n.alive


def test_doctor_judges_a_recording(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    run = tmp_path / "run.mcap"
    assert cli_main(["simulate", "--output", str(run), "--fault", "depth-float-mm", "--duration", "2", "--fps", "5",
                     "--width", "160", "--height", "120"]) == 0
    capsys.readouterr()
    assert cli_main(["doctor", "--recording", str(run), "--json"]) == 2
    report = json.loads(capsys.readouterr().out)
    rows = {r["name"]: r for r in report["checks"]}
    assert rows["depth unit (head)"]["status"] == "fail"
    assert rows["chain map ← camera"]["status"] == "ok" and rows["static transforms"]["status"] == "ok"
    assert rows["detector"]["status"] == "warn"  # a recording holds no liveliness, and this one no status
    assert report["source"].startswith(f"recording {run}")


def test_doctor_says_what_is_wrong_with_an_unreadable_recording(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(b"not a recording")
    assert cli_main(["doctor", "--recording", str(bad)]) == 2
    assert "bad.mcap" in capsys.readouterr().err



def test_a_camera_node_that_lost_its_stream_is_named() -> None:
    from tools.doctor.core.checks import run_checks as _run
    from tools.doctor.core.facts import NodeFacts as _Node
    from tools.doctor.core.facts import Observation as _Obs

    cam = _Node("camera", "pc-1", settings={"camera": "head", "source": "rtsp://10.0.0.5/stream"},
                counters={"connected": 0, "stream_lost": 1, "reopen_failed": 3}, window_s=5.0)
    (line,) = [c for c in _run(_Obs(duration_s=5.0, nodes=[cam])) if c.name == "frames/head"]
    assert line.status == "fail" and "lost its source 'rtsp://10.0.0.5/stream'" in line.figure
    assert "reopens" in line.fix


def test_traffic_under_another_robot_name_is_named() -> None:
    from tools.doctor.core.checks import run_checks as _run
    from tools.doctor.core.facts import Observation as _Obs

    obs = _Obs(duration_s=5.0, other_robots={"pp/mbot": ["detector", "simulator", "tracker"]})
    (line,) = [c for c in _run(obs) if c.name == "frames/head"]
    assert line.status == "fail" and "pp/mbot (detector, simulator, tracker)" in line.figure
    assert "--robot mbot" in line.fix and "--key-prefix" not in line.fix
    other = _Obs(duration_s=5.0, other_robots={"lab/r2": ["tracker"]})
    (line,) = [c for c in _run(other) if c.name == "tracks"]
    assert "--robot r2 --key-prefix lab" in line.fix


def test_people_placed_at_an_impossible_height_name_the_mount() -> None:
    import numpy as np

    from tools.doctor.core.checks import run_checks as _run
    from tools.doctor.core.facts import EdgeFacts as _Edge
    from tools.doctor.core.facts import Observation as _Obs

    rng = np.random.default_rng(0)
    d = rng.uniform(1.5, 6.0, 60)
    edges = [_Edge("base_link", "head_link", True), _Edge("head_link", "camera", True)]

    def line(z: np.ndarray, camera_z: float = 1.2, up: float = 0.97) -> tuple[str, str, str]:
        people = [(float(zi), float(di), "camera", camera_z, 10.0, up) for zi, di in zip(z, d)]
        (c,) = [c for c in _run(_Obs(duration_s=5.0, people=people, edges=edges)) if c.name.startswith("people's")]
        return c.status, c.figure, c.fix

    assert line(0.9 + rng.normal(0, 0.05, 60))[0] == "ok"
    # the mount said 0.5 m higher than it is: the camera too is placed 0.5 m higher
    status, figure, fix = line(1.4 + rng.normal(0, 0.05, 60), camera_z=1.7)
    assert status == "fail" and "1.4" in figure and "height in head_link → camera or base_link → head_link" in fix
    status, figure, fix = line(0.9 - d * np.tan(np.radians(30)))  # the camera's pitch 30 degrees off
    assert status == "fail" and "farther" in figure and "30°" in fix
    status, figure, fix = line(2 * 1.2 - 0.9 + rng.normal(0, 0.05, 60))  # mirrored about the camera
    assert status == "fail" and "above the camera" in figure and "upside down" in fix
    status, figure, fix = line(0.9 + rng.normal(0, 0.05, 60), up=-0.97)  # the transform rolled 180 degrees
    assert status == "fail" and "image's up" in figure and "rolled 180°" in fix


def test_a_depth_floor_that_disagrees_with_the_transforms_names_the_pitch() -> None:
    from tools.doctor.core.checks import run_checks as _run
    from tools.doctor.core.facts import EdgeFacts as _Edge
    from tools.doctor.core.facts import NodeFacts as _Node
    from tools.doctor.core.facts import Observation as _Obs

    det = _Node("detector", "pc-1", counters={"floor_disagrees": 20, "frames_processed": 24}, window_s=3.0,
                last={"floor_transforms_height_m": 1.22, "floor_transforms_tilt_deg": 37.0,
                      "floor_depth_height_m": 1.21, "floor_depth_tilt_deg": 7.0})
    obs = _Obs(duration_s=3.0, nodes=[det], edges=[_Edge("head_link", "camera", True)])
    (line,) = [c for c in _run(obs) if c.name == "floor (detector)"]
    assert line.status == "fail" and "20 of 24 frames" in line.figure and "pitch looks +30° off" in line.fix
    assert "height" not in line.fix.split(":")[1]  # 1 cm is not a height error
    det.counters["floor_disagrees"] = 2
    assert not [c for c in _run(obs) if c.name == "floor (detector)"]
