"""The optional orientation classifier on the crops (TU Ilmenau): the embedder attaches its
probabilities, the tracker turns them into the map frame and uses them for a person who
stands still."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from common.messages.schemas import CameraView, Embeddings, Header, LocalizedDetection, LocalizedDetections, ModelCard
from services.embedder.config import EmbedderConfig
from services.embedder.core.backend import EmbedderError
from services.embedder.core.orientation import OrientationClassifier, OrientationParams
from services.tracker.convert import orientations_for
from services.tracker.core.robust import RobustParams, RobustTracker
from services.tracker.core.types import FrameInput
from tests.fixtures.embedder_onnx_models import projection_model
from tests.fixtures.embedder_scene import BOX_GREEN, BOX_RED, detections, frame
from tests.helpers.embedder_rig import Rig

H, W = 16, 8


def red_green_model(path: Path) -> Path:
    """Scores bin 0 by the crop's mean red, bin 4 by its mean green (a stand-in for a trained net)."""
    p = np.zeros((3 * H * W, 8), np.float32)
    p[: H * W, 0] = 5.0 / (H * W)
    p[H * W : 2 * H * W, 4] = 5.0 / (H * W)
    return projection_model(path, H, W, p)


def test_the_embedder_attaches_each_crops_orientation(tmp_path: Path) -> None:
    path = red_green_model(tmp_path / "orientation.onnx")
    rig = Rig(EmbedderConfig.model_validate({"orientation": {"path": str(path), "input_size": [H, W]}}))
    f = frame(seq=1, stamp_ns=1_000_000_000)
    rig.frames.put(f)
    rig.dets.put(detections(f, [BOX_RED, BOX_GREEN]))
    rig.service.poll(0.0)
    [msg] = rig.received()
    assert msg.orientation is not None and msg.orientation.shape == (2, 8)
    np.testing.assert_allclose(msg.orientation.sum(axis=1), 1.0, rtol=1e-5)
    assert np.argmax(msg.orientation, axis=1).tolist() == [0, 4]  # red shirt: bin 0, green: bin 4


def test_a_model_that_does_not_output_eight_scores_is_refused(tmp_path: Path) -> None:
    path = projection_model(tmp_path / "five.onnx", H, W, np.zeros((3 * H * W, 5), np.float32))
    with pytest.raises(EmbedderError, match="8"):
        OrientationClassifier(OrientationParams(path=str(path), input_size=(H, W)))


def _loc(view: CameraView | None) -> LocalizedDetections:
    det = LocalizedDetection(index=0, bbox_xyxy=(0, 0, 10, 20), score=0.9, position=np.array([3.0, 0.0, 1.0]),
                             cov=np.eye(3) * 0.01, depth_m=3.0)
    return LocalizedDetections(header=Header(stamp_ns=1, frame_id="map"), detections=[det], view=view)


def test_camera_bins_turn_into_map_bins_with_the_cameras_heading() -> None:
    # a camera at the origin looking along +x: a person facing it faces -x, i.e. 180 degrees (map bin 4)
    look_x = np.eye(4)
    look_x[:3, :3] = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    view = CameraView(camera_to_frame=look_x, K=np.eye(3) * 500, width=640, height=480, max_range_m=8.0)
    probs = np.zeros((1, 8), np.float32)
    probs[0, 0] = 1.0  # facing the camera
    emb = Embeddings(header=Header(stamp_ns=1), model=ModelCard(name="c", dim=2), indices=np.array([0], np.int32),
                     vectors=np.zeros((1, 2), np.float32), orientation=probs)
    out = orientations_for(_loc(view), emb)
    assert out is not None and int(np.argmax(out[0])) == 4
    probs[0] = 0.0
    probs[0, 2] = 1.0  # 90 degrees anticlockwise from facing the camera: facing -y (270 degrees, map bin 6)
    assert int(np.argmax(orientations_for(_loc(view), emb)[0])) == 6  # type: ignore[index]
    assert orientations_for(_loc(None), emb) is None  # no camera view: the bins cannot be turned


def test_a_person_standing_still_takes_the_classifiers_orientation() -> None:
    trk = RobustTracker(RobustParams())
    evidence = np.full((1, 8), 0.02)
    evidence[0, 6] = 0.86
    for t in np.arange(0.0, 2.0, 0.1):
        trk.step(float(t), FrameInput.of(np.array([[3.0, 0.0, 1.1]]), aspects=np.array([2.7]), orientations=evidence))
    assert int(np.argmax(trk.tracks[0].orientation)) == 6 and trk.tracks[0].orientation[6] > 0.9
