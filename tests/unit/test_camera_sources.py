"""The camera node's OpenCV backend and calibrations: a folder, a video file, what is not a video,
a device that does not open; ROS camera_calibration and OpenCV calibration files; a rough model
from a field of view."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from services.camera.calibration_file import load_calibration
from services.camera.core.calibration import CalibrationError, from_fov, scaled
from services.camera.core.opencv import OpenCvSource, describe_source
from services.camera.core.sources import SourceError


def _images(folder: Path, n: int = 5, size: tuple[int, int] = (48, 64)) -> list[np.ndarray]:
    folder.mkdir(parents=True, exist_ok=True)
    out = []
    for k in range(n):
        rgb = np.zeros((*size, 3), np.uint8)
        rgb[:, :, 0] = 40 * k
        rgb[5:10, 5 + k:15 + k, 1] = 255
        cv2.imwrite(str(folder / f"{k:04d}.png"), cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
        out.append(rgb)
    (folder / "notes.txt").write_text("not an image")
    return out


def test_a_folder_of_images_plays_in_name_order(tmp_path: Path) -> None:
    sent = _images(tmp_path / "frames")
    src = OpenCvSource(str(tmp_path / "frames"), fps=7.5)
    assert src.is_file and src.fps == 7.5 and describe_source(str(tmp_path / "frames")) == "folder"
    got = [src.read() for _ in range(6)]
    assert got[-1] is None
    assert [c.index for c in got[:-1]] == [1, 2, 3, 4, 5]
    # OpenCV's BGR order, said so, pixel for pixel (png)
    assert all(c.order == "bgr8" and np.array_equal(c.rgb[..., ::-1], s) for c, s in zip(got, sent))
    assert all(c.stamp_ns is None and c.depth is None for c in got[:-1])


def test_a_video_file_plays_with_its_own_rate(tmp_path: Path) -> None:
    path = tmp_path / "clip.avi"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 12.0, (64, 48))
    for k in range(8):
        frame = np.full((48, 64, 3), 30 * k, np.uint8)
        writer.write(frame)
    writer.release()
    src = OpenCvSource(str(path), fps=30.0)
    assert src.is_file and abs(src.fps - 12.0) < 1e-6
    frames = []
    while (c := src.read()) is not None:
        frames.append(c)
    assert [c.index for c in frames] == list(range(1, 9))
    # an MJPG video's frames pass on as the JPEGs they are: the receivers decode them
    assert frames[3].rgb is None and frames[3].size == (48, 64) and frames[3].jpeg[:2] == b"\xff\xd8"
    decoded = cv2.imdecode(np.frombuffer(frames[3].jpeg, np.uint8), cv2.IMREAD_COLOR)
    assert abs(int(decoded.mean()) - 90) <= 3
    src.close()
    raw = OpenCvSource(str(path), passthrough=False)  # or decoded here, in OpenCV's BGR order
    first = raw.read()
    assert first is not None and first.jpeg is None and first.order == "bgr8" and first.rgb.shape == (48, 64, 3)
    raw.close()


def test_a_folder_of_jpegs_passes_them_on(tmp_path: Path) -> None:
    folder = tmp_path / "jpegs"
    folder.mkdir()
    ok, jpg = cv2.imencode(".jpg", np.full((30, 40, 3), 128, np.uint8))
    (folder / "a.jpg").write_bytes(jpg.tobytes())
    cv2.imwrite(str(folder / "b.jpg"), np.full((30, 40), 50, np.uint8))  # grey: decoded, to colour
    src = OpenCvSource(str(folder))
    a, b = src.read(), src.read()
    assert a.jpeg == jpg.tobytes() and a.size == (30, 40)
    assert b.jpeg is None and b.rgb.shape == (30, 40, 3)


def test_what_cannot_be_opened_is_one_clear_error(tmp_path: Path) -> None:
    bogus = tmp_path / "notes.mp4"
    bogus.write_bytes(b"this is not a video" * 100)
    with pytest.raises(SourceError, match="not a video"):
        OpenCvSource(str(bogus))
    with pytest.raises(SourceError, match="no such file"):
        OpenCvSource(str(tmp_path / "missing.mp4"))
    (tmp_path / "empty").mkdir()
    with pytest.raises(SourceError, match="no image"):
        OpenCvSource(str(tmp_path / "empty"))
    with pytest.raises(SourceError, match="does not open"):
        OpenCvSource("97")  # no such V4L2 device on any test machine


ROS_YAML = """image_width: 640
image_height: 480
camera_name: head
camera_matrix:
  rows: 3
  cols: 3
  data: [600.5, 0, 321.2, 0, 601.5, 241.7, 0, 0, 1]
distortion_model: plumb_bob
distortion_coefficients:
  rows: 1
  cols: 5
  data: [0.1, -0.2, 0.001, 0.002, 0.05]
rectification_matrix:
  rows: 3
  cols: 3
  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]
projection_matrix:
  rows: 3
  cols: 4
  data: [600.5, 0, 321.2, 0, 0, 601.5, 241.7, 0, 0, 0, 1, 0]
"""


def test_ros_camera_calibration_yaml(tmp_path: Path) -> None:
    path = tmp_path / "head.yaml"
    path.write_text(ROS_YAML)
    intr = load_calibration(path)
    assert (intr.width, intr.height, intr.distortion_model) == (640, 480, "plumb_bob")
    assert intr.K[0, 0] == 600.5 and intr.K[1, 2] == 241.7 and list(intr.D) == [0.1, -0.2, 0.001, 0.002, 0.05]
    half = scaled(intr, 320, 240)
    assert half.K[0, 0] == pytest.approx(300.25) and half.K[1, 2] == pytest.approx(120.85)
    with pytest.raises(CalibrationError, match="aspect"):
        scaled(intr, 320, 320)
    path.write_text(ROS_YAML.replace("camera_matrix", "camera_matrx"))
    with pytest.raises(CalibrationError, match="camera_matrix"):
        load_calibration(path)


def test_opencv_filestorage_calibration(tmp_path: Path) -> None:
    path = tmp_path / "cam.yaml"
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    fs.write("image_width", 1280)
    fs.write("image_height", 720)
    fs.write("camera_matrix", np.array([[900.0, 0, 640], [0, 900.0, 360], [0, 0, 1]]))
    fs.write("distortion_coefficients", np.array([[0.01, -0.02, 0.0, 0.0, 0.003]]))
    fs.release()
    intr = load_calibration(path)
    assert (intr.width, intr.height) == (1280, 720) and intr.K[0, 0] == 900.0 and len(intr.D) == 5


def test_a_field_of_view_gives_rough_intrinsics() -> None:
    intr = from_fov(640, 480, 90.0)
    assert intr.rough and intr.K[0, 0] == pytest.approx(320.0) and intr.K[1, 2] == 240.0
    with pytest.raises(CalibrationError):
        from_fov(640, 480, 200.0)
