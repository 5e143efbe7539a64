"""Schema validation and the image helpers."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError

from common.messages.samples import camera_info, rgbd_frame
from common.messages.schemas import AppearanceThresholds, CameraInfo, Embeddings, Header, Image, ModelCard, RGBDFrame, Transform

H = Header(stamp_ns=1, frame_id="camera", seq=1, source="head")


@pytest.mark.parametrize("encoding", ["rgb8", "bgr8", "jpeg", "png"])
def test_colour_images_come_back_in_rgb_order(encoding: str) -> None:
    rgb = np.zeros((8, 10, 3), np.uint8)
    rgb[..., 0] = 200  # red
    src = rgb[..., ::-1] if encoding == "bgr8" else rgb
    img = Image.from_array(src, encoding, H)  # type: ignore[arg-type]
    out = img.to_array()
    assert out.shape == (8, 10, 3) and (img.height, img.width) == (8, 10)
    assert abs(int(out[..., 0].mean()) - 200) <= 2 and out[..., 2].max() <= 2


def test_depth_in_millimetres_and_metres_agree() -> None:
    mm = np.array([[0, 1500], [2000, 65535]], np.uint16)
    m = np.array([[np.nan, 1.5], [2.0, 65.535]], np.float32)
    a = Image.from_array(mm, "16UC1", H).depth_m()
    b = Image.from_array(m, "32FC1", H).depth_m()
    c = Image.from_array(mm, "png", H).depth_m()
    np.testing.assert_allclose(a, b, rtol=1e-6, equal_nan=True)
    np.testing.assert_allclose(c, b, rtol=1e-6, equal_nan=True)
    assert np.isnan(a[0, 0])


def test_colour_image_is_not_depth() -> None:
    with pytest.raises(ValueError, match="not a depth image"):
        Image.from_array(np.zeros((2, 2, 3), np.uint8), "rgb8", H).depth_m()


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"encoding": "rgb8", "dtype": "uint16", "shape": (2, 2, 3), "data": bytes(24)}, "needs dtype uint8"),
        ({"encoding": "rgb8", "dtype": "uint8", "shape": (2, 2), "data": bytes(4)}, "needs 3 channel"),
        ({"encoding": "mono8", "dtype": "uint8", "shape": (0, 2), "data": b""}, "positive sizes"),
        ({"encoding": "jpeg", "dtype": "uint8", "shape": (2, 2, 3), "data": b""}, "has no data"),
    ],
)
def test_inconsistent_images_are_refused(kwargs: dict, message: str) -> None:
    with pytest.raises(ValidationError, match=message):
        Image(header=H, **kwargs)


def test_corrupt_jpeg_fails_to_decode_clearly() -> None:
    img = Image(header=H, encoding="jpeg", dtype="uint8", shape=(2, 2, 3), data=b"not a jpeg")
    with pytest.raises(ValueError, match="could not be decoded"):
        img.to_array()


def test_camera_info_checks() -> None:
    cam = camera_info()
    with pytest.raises(ValidationError, match="focal lengths"):
        CameraInfo(header=H, width=640, height=480, K=np.zeros((3, 3)))
    with pytest.raises(ValidationError, match="plumb_bob takes"):
        CameraInfo(header=H, width=640, height=480, K=cam.K, D=[0.1, 0.2])
    with pytest.raises(ValidationError, match="K must be finite"):
        CameraInfo(header=H, width=640, height=480, K=np.full((3, 3), np.nan))


def test_rgbd_frame_checks_sizes_and_kinds() -> None:
    f = rgbd_frame(32, 24)
    with pytest.raises(ValidationError, match="differs from rgb"):
        RGBDFrame(header=H, rgb=f.rgb, depth=Image.from_array(np.zeros((5, 5), np.uint16), "16UC1", H), camera_info=f.camera_info)
    with pytest.raises(ValidationError, match="not 16UC1"):
        RGBDFrame(header=H, rgb=f.rgb, depth=f.rgb, camera_info=f.camera_info)


def test_transform_quaternion_is_normalised_and_checked() -> None:
    t = Transform(parent_frame="map", child_frame="odom", stamp_ns=0, translation=[0, 0, 0], rotation_xyzw=[0, 0, 0, 1.1])
    assert np.isclose(np.linalg.norm(t.rotation_xyzw), 1.0)
    with pytest.raises(ValidationError, match="unit quaternion"):
        Transform(parent_frame="map", child_frame="odom", stamp_ns=0, translation=[0, 0, 0], rotation_xyzw=[0, 0, 0, 0])
    with pytest.raises(ValidationError, match="both 'map'"):
        Transform(parent_frame="map", child_frame="map", stamp_ns=0, translation=[0, 0, 0], rotation_xyzw=[0, 0, 0, 1])


def test_embeddings_must_match_their_model_card() -> None:
    card = ModelCard(name="m", dim=4)
    with pytest.raises(ValidationError, match="dimension 3"):
        Embeddings(header=H, model=card, indices=[0], vectors=np.zeros((1, 3), np.float32))
    with pytest.raises(ValidationError, match="duplicate"):
        Embeddings(header=H, model=card, indices=[1, 1], vectors=np.zeros((2, 4), np.float32))
    with pytest.raises(ValidationError, match="must be below"):
        AppearanceThresholds(t_lower=0.7, t_upper=0.3, t_recover=0.4)
