"""``perception localize`` (offline) and the start-up checks of ``perception localizer``."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from common.geometry.transforms import PinholeCamera, RigidTransform
from perception.cli import main
from services.localizer.core import homography_from_camera
from tests.fixtures.localizer_synthetic import Person, person_box, render_depth

K = [525.0, 0.0, 319.5, 0.0, 525.0, 239.5, 0.0, 0.0, 1.0]
D = [-0.28, 0.09, 0.001, -0.0005, -0.01]
PEOPLE = [Person((0.2, 0.1, 2.5)), Person((-1.5, 0.0, 4.0))]
MOUNT = "base_link:camera:0.1,0,1.2:-0.5,0.5,-0.5,0.5"


@pytest.fixture
def setup(tmp_path: Path) -> dict[str, Path]:
    cam = PinholeCamera(np.array(K).reshape(3, 3), 640, 480, np.array(D))
    depth = np.round(render_depth(cam, PEOPLE) * 1000).astype(np.uint16)
    cv2.imwrite(str(tmp_path / "f0001.png"), depth)
    (tmp_path / "cam.json").write_text(
        json.dumps(
            {"width": 640, "height": 480, "K": K, "D": D, "distortion_model": "plumb_bob", "frame_id": "head_optical"}
        )
    )
    boxes = [person_box(cam, p).tolist() for p in PEOPLE] + [[700, 0, 800, 100]]
    line = {
        "image": "images/f0001.jpg",
        "width": 640,
        "height": 480,
        "detections": [{"bbox_xyxy": b, "score": 0.8} for b in boxes],
    }
    (tmp_path / "dets.jsonl").write_text(json.dumps(line) + "\n\n" + json.dumps({**line, "detections": []}) + "\n")
    return {
        "dir": tmp_path,
        "depth": tmp_path / "f0001.png",
        "cam": tmp_path / "cam.json",
        "dets": tmp_path / "dets.jsonl",
    }


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, list[dict], str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, [json.loads(line) for line in out.splitlines() if line.strip()] if code == 0 else [], err


def test_camera_frame_positions(setup: dict[str, Path], capsys: pytest.CaptureFixture[str]) -> None:
    code, lines, _ = run(
        capsys,
        "localize",
        "--depth",
        str(setup["depth"]),
        "--camera-info",
        str(setup["cam"]),
        "--detections",
        str(setup["dets"]),
        "--body-half-depth",
        "0",  # the synthetic people are flat cut-outs at their centre's depth
    )
    assert code == 0 and len(lines) == 2
    first = lines[0]
    assert first["frame_id"] == "head_optical" == first["camera_frame"]
    assert [d["index"] for d in first["detections"]] == [0, 1]
    for d, p in zip(first["detections"], PEOPLE):
        assert np.linalg.norm(np.array(d["position"]) - p.center) < 0.01
        assert np.array(d["cov"]).shape == (3, 3)
    assert first["rejected"] == {"outside_image": 1} and first["rejected_indices"] == {"2": "outside_image"}
    assert lines[1]["detections"] == []


def test_transforms_to_a_target_frame(setup: dict[str, Path], capsys: pytest.CaptureFixture[str]) -> None:
    tfile = setup["dir"] / "tf.json"
    tfile.write_text(
        json.dumps(
            [
                {
                    "parent_frame": "map",
                    "child_frame": "base_link",
                    "translation": [2, 1, 0],
                    "rotation_xyzw": [0, 0, 0.7071068, 0.7071068],
                }
            ]
        )
    )
    code, lines, _ = run(
        capsys,
        "localize",
        "--depth",
        str(setup["dir"]),
        "--camera-info",
        str(setup["cam"]),
        "--detections",
        str(setup["dets"]),
        "--transform",
        MOUNT.replace("camera", "head_optical"),
        "--transforms",
        str(tfile),
        "--body-half-depth",
        "0",
    )
    assert code == 0
    mount = RigidTransform.from_quat(np.array([0.1, 0, 1.2]), np.array([-0.5, 0.5, -0.5, 0.5]))
    world = RigidTransform.from_quat(np.array([2.0, 1.0, 0.0]), np.array([0, 0, 0.7071068, 0.7071068])) @ mount
    d = lines[0]["detections"][0]
    assert lines[0]["frame_id"] == "map"
    assert np.allclose(d["position"], world.apply(np.array(PEOPLE[0].center)), atol=0.01)
    assert d["body_center_z"] == pytest.approx(1.2 - 0.1, abs=0.01)  # 0.1 m below the optical axis


@pytest.mark.parametrize(
    ("flag", "value", "message"),
    [
        ("--depth", "{dir}/missing.png", "does not exist"),
        ("--camera-info", "{dir}/bad.json", "cannot be parsed"),
        ("--camera-info", "{dir}/missing.json", "does not exist"),
        ("--camera-info", "{dir}/list.json", "must hold a mapping"),
        ("--transform", "base_link:camera", "PARENT:CHILD"),
        ("--transform", MOUNT, "no transform chain"),  # the camera frame is head_optical: no chain to map
        ("--detections", "{dir}/garbage.jsonl", "not JSON"),
        ("--depth", "{dir}/small.png", "the camera info says 640x480"),
        ("--percentile", "150", "percentile"),
    ],
)
def test_bad_inputs_exit_2_with_a_message(
    setup: dict[str, Path], capsys: pytest.CaptureFixture[str], flag: str, value: str, message: str
) -> None:
    (setup["dir"] / "bad.json").write_text("{not json")
    (setup["dir"] / "list.json").write_text("[640, 480]")
    (setup["dir"] / "garbage.jsonl").write_text('{"detections": []}\nnope\n')
    cv2.imwrite(str(setup["dir"] / "small.png"), np.zeros((240, 320), np.uint16))
    args = {"--depth": str(setup["depth"]), "--camera-info": str(setup["cam"]), "--detections": str(setup["dets"])}
    args[flag] = value.format(dir=setup["dir"])
    code, _, err = run(capsys, "localize", *[x for kv in args.items() for x in kv])
    assert code == 2
    assert err.startswith("perception: error:") and message in err


def test_service_rejects_bad_settings_at_start(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["localizer", "--percentile", "150", "--connect", "tcp/127.0.0.1:1"]) == 2
    assert "percentile" in capsys.readouterr().err
    cfg = tmp_path / "deploy.yaml"
    cfg.write_text("localizer:\n  min_depth_m: 4\n  max_depth_m: 2\n")
    assert main(["localizer", "--service-config", str(cfg), "--connect", "tcp/127.0.0.1:1"]) == 2
    assert "min_depth_m" in capsys.readouterr().err
    cfg.write_text("localizer:\n  typo_field: 1\n")
    assert main(["localizer", "--service-config", str(cfg)]) == 2
    assert "typo_field" in capsys.readouterr().err
    missing = tmp_path / "missing.json"
    assert main(["localizer", "--floor-homography", str(missing), "--connect", "tcp/127.0.0.1:1"]) == 2
    assert "does not exist" in capsys.readouterr().err


# ------------------------------------------------------------------------- without depth


def floor_setup(tmp_path: Path, feet: np.ndarray) -> tuple[Path, Path, PinholeCamera, RigidTransform]:
    """A pinhole camera mounted as MOUNT (1.2 m up, looking along base_link's x) and a detections
    file whose boxes stand on ``feet`` (N, 3) of base_link, plus a box cut off by the lower edge."""
    cam = PinholeCamera(np.array(K).reshape(3, 3), 640, 480)
    mount = RigidTransform.from_quat(np.array([0.1, 0, 1.2]), np.array([-0.5, 0.5, -0.5, 0.5]))
    px = cam.project(mount.inverse().apply(feet))
    boxes = [[u - 20, v - 150, u + 20, v] for u, v in px.tolist()] + [[100, 300, 160, 480]]
    (tmp_path / "cam.json").write_text(json.dumps({"width": 640, "height": 480, "K": K, "frame_id": "camera"}))
    line = {"image": "f0001.jpg", "width": 640, "height": 480, "detections": [{"bbox_xyxy": b} for b in boxes]}
    (tmp_path / "dets.jsonl").write_text(json.dumps(line) + "\n")
    return tmp_path / "cam.json", tmp_path / "dets.jsonl", cam, mount


def test_without_depth_through_the_transforms(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    feet = np.array([[3.0, 0.5, 0.0], [6.0, -1.0, 0.0]])
    cam, dets, _, mount = floor_setup(tmp_path, feet)
    code, [line], _ = run(capsys, "localize", "--camera-info", str(cam), "--detections", str(dets),
                          "--transform", MOUNT, "--target-frame", "base_link")
    assert code == 0 and line["depth"] is None and line["frame_id"] == "base_link"
    assert line["rejected"] == {"foot_outside_image": 1}
    got = [d["position"] for d in line["detections"]]
    assert np.allclose(got, feet + [0.0, 0.0, 0.9], atol=1e-3)
    assert np.allclose([d["position_camera"] for d in line["detections"]],
                       mount.inverse().apply(feet + [0.0, 0.0, 0.9]), atol=1e-3)
    assert [d["valid_pixels"] for d in line["detections"]] == [0, 0]
    # without transforms there is no floor to put them on
    code, _, err = run(capsys, "localize", "--camera-info", str(cam), "--detections", str(dets))
    assert code == 2 and "--floor-homography" in err


def test_without_depth_through_a_homography(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    feet = np.array([[3.0, 0.5, 0.0], [6.0, -1.0, 0.0]])
    cam_path, dets, cam, mount = floor_setup(tmp_path, feet)
    hom = homography_from_camera(cam, mount)
    (tmp_path / "h.json").write_text(json.dumps({"H": hom.H.tolist(), "image_size": [640, 480]}))
    code, [line], _ = run(capsys, "localize", "--camera-info", str(cam_path), "--detections", str(dets),
                          "--floor-homography", str(tmp_path / "h.json"), "--max-floor-range", "5")
    assert code == 0 and line["frame_id"] == "map"
    assert line["rejected"] == {"foot_outside_image": 1, "beyond_floor_range": 1}
    [d] = line["detections"]
    assert np.allclose(d["position"], feet[0] + [0.0, 0.0, 0.9], atol=1e-3)
    assert d["depth_m"] == pytest.approx(mount.inverse().apply(feet[0])[2], abs=1e-3)
    # HOG's boxes reach 3.7 % of their height below the feet: --detector hog takes that off the foot
    # point, 150 px boxes 5.55 px up, so the person lands farther from the camera (a box reaching below
    # the feet puts them too near)
    code, [line], _ = run(capsys, "localize", "--camera-info", str(cam_path), "--detections", str(dets),
                          "--floor-homography", str(tmp_path / "h.json"), "--max-floor-range", "5", "--detector", "hog")
    [e] = line["detections"]
    assert e["pixel"][1] == pytest.approx(d["pixel"][1] - 0.037 * 150, abs=1e-6)
    assert 0.03 < e["depth_m"] - d["depth_m"] < 0.5
    (tmp_path / "h.json").write_text(json.dumps({"H": hom.H.tolist(), "image_size": [640, 360]}))
    code, _, err = run(capsys, "localize", "--camera-info", str(cam_path), "--detections", str(dets),
                       "--floor-homography", str(tmp_path / "h.json"))
    assert code == 2 and "another aspect ratio" in err
