"""The onnx backend with graphs built here: preprocessing, batching, index mapping, bad models."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

pytest.importorskip("onnx", reason="the onnx package builds the test graphs (pip install -e '.[test]')")

from services.embedder.core.backend import EmbedderError
from services.embedder.core.onnx_model import OnnxEmbedder, OnnxParams, choose_providers
from tests.fixtures.embedder_onnx_models import projection_model, rank3_model

H, W = 8, 4


@pytest.fixture(scope="module")
def identity_path(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return projection_model(tmp_path_factory.mktemp("onnx") / "identity.onnx", H, W)


class CountingSession:
    """Wraps an onnxruntime session and records the batch size of every run."""

    def __init__(self, session: object) -> None:
        self.session = session
        self.batches: list[int] = []

    def run(self, outputs: list[str], feeds: dict[str, np.ndarray]) -> list[np.ndarray]:
        self.batches.append(next(iter(feeds.values())).shape[0])
        return self.session.run(outputs, feeds)  # type: ignore[attr-defined]


def test_preprocessing_resize_channel_order_normalisation(identity_path: Path) -> None:
    rng = np.random.default_rng(0)
    crop = rng.integers(0, 256, size=(37, 19, 3), dtype=np.uint8)
    mean, std = (0.4, 0.5, 0.6), (0.2, 0.25, 0.3)
    for order in ("rgb", "bgr"):
        emb = OnnxEmbedder(OnnxParams(path=str(identity_path), input_size=(H, W), mean=mean, std=std,
                                      channel_order=order, normalize=False, providers=("CPUExecutionProvider",)))
        out = emb.embed([crop])
        resized = cv2.resize(crop, (W, H), interpolation=cv2.INTER_LINEAR).astype(np.float32) / 255.0
        if order == "bgr":
            resized = resized[..., ::-1]
        expected = ((resized - np.array(mean)) / np.array(std)).transpose(2, 0, 1).reshape(1, -1)
        np.testing.assert_allclose(out, expected, atol=1e-5)
    assert emb.card.dim == 3 * H * W and emb.card.input_size == (H, W) and emb.card.name == "identity"


def test_one_batched_call_per_frame_and_index_order(identity_path: Path) -> None:
    # on the CPU: a GPU's batched and single products differ in the last digits (TF32)
    emb = OnnxEmbedder(OnnxParams(path=str(identity_path), input_size=(H, W), normalize=True,
                                  providers=("CPUExecutionProvider",)))
    counting = CountingSession(emb.session)
    emb.session = counting  # type: ignore[assignment]
    colours = [(255, 0, 0), (0, 255, 0), (0, 0, 255), (255, 255, 0), (0, 0, 0)]
    crops = [np.full((10 + 7 * i, 5 + 3 * i, 3), c, np.uint8) for i, c in enumerate(colours)]
    out = emb.embed(crops)
    assert counting.batches == [5]
    assert out.shape == (5, 3 * H * W)
    np.testing.assert_allclose(np.linalg.norm(out, axis=1), 1.0, atol=1e-5)
    singles = np.concatenate([emb.embed([c]) for c in crops])
    np.testing.assert_allclose(out, singles, atol=1e-5)  # row i belongs to crop i
    assert counting.batches[1:] == [1] * 5
    assert emb.embed([]).shape == (0, 3 * H * W)


def test_fixed_batch_graph_runs_in_padded_chunks(tmp_path: Path) -> None:
    path = projection_model(tmp_path / "fixed.onnx", H, W, batch=2)
    emb = OnnxEmbedder(OnnxParams(path=str(path), input_size=(H, W), normalize=False))
    crops = [np.full((9, 9, 3), v, np.uint8) for v in (10, 90, 200)]
    out = emb.embed(crops)
    assert out.shape == (3, 3 * H * W)
    np.testing.assert_allclose(out[2], emb.embed([crops[2]])[0], atol=1e-5)


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(EmbedderError, match="not found.*export-embedder"):
        OnnxEmbedder(OnnxParams(path=str(tmp_path / "nope.onnx")))


def test_wrong_input_rank(tmp_path: Path) -> None:
    with pytest.raises(EmbedderError, match="rank 3"):
        OnnxEmbedder(OnnxParams(path=str(rank3_model(tmp_path / "r3.onnx"))))


def test_input_size_must_match_a_fixed_graph(identity_path: Path) -> None:
    with pytest.raises(EmbedderError, match="set input_size"):
        OnnxEmbedder(OnnxParams(path=str(identity_path), input_size=(256, 128)))


def test_not_an_onnx_file(tmp_path: Path) -> None:
    bad = tmp_path / "junk.onnx"
    bad.write_bytes(b"not a model")
    with pytest.raises(EmbedderError, match="could not load"):
        OnnxEmbedder(OnnxParams(path=str(bad)))


def test_provider_choice() -> None:
    avail = ["CUDAExecutionProvider", "CPUExecutionProvider", "AzureExecutionProvider"]
    assert choose_providers(None, avail) == ["CUDAExecutionProvider", "CPUExecutionProvider"]
    all_three = ["TensorrtExecutionProvider", *avail]
    assert choose_providers(None, all_three)[0] == "TensorrtExecutionProvider"
    assert choose_providers(("CPUExecutionProvider",), all_three) == ["CPUExecutionProvider"]
    with pytest.raises(EmbedderError, match="not available"):
        choose_providers(("CUDAExecutionProvider",), ["CPUExecutionProvider"])


def test_output_that_is_not_n_by_d(tmp_path: Path) -> None:
    from onnx import TensorProto, helper

    from tests.fixtures.embedder_onnx_models import _save

    graph = helper.make_graph(
        [helper.make_node("Identity", ["input"], ["output"])], "feature_map",
        [helper.make_tensor_value_info("input", TensorProto.FLOAT, ["N", 3, H, W])],
        [helper.make_tensor_value_info("output", TensorProto.FLOAT, ["N", 3, H, W])])
    path = _save(graph, tmp_path / "map.onnx")
    with pytest.raises(EmbedderError, match=r"expected \(1, D\)"):
        OnnxEmbedder(OnnxParams(path=str(path), input_size=(H, W)))


def test_an_accelerator_that_did_not_start_is_named() -> None:
    """onnxruntime drops a provider whose libraries do not load and says so only in its log."""
    from services.embedder.core.onnx_model import _check_fallback

    cuda, cpu = "CUDAExecutionProvider", "CPUExecutionProvider"
    _check_fallback([cuda, cpu], [cuda, cpu], requested=True)  # came up: nothing to say
    with pytest.raises(EmbedderError, match=r"could not start \['CUDAExecutionProvider'\].*runs on \['CPU"):
        _check_fallback([cuda, cpu], [cpu], requested=True)
    _check_fallback([cuda, cpu], [cpu], requested=False)  # picked by preference: a warning, not an error
    _check_fallback(["TensorrtExecutionProvider", cuda, cpu], [cuda, cpu], requested=True)  # CUDA stands in
