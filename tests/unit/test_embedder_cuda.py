"""The ONNX embedder on a CUDA GPU: it runs where onnxruntime-gpu and an NVIDIA GPU are
present and is skipped elsewhere (CI has no GPU). On a GPU it checks that the session
really runs on CUDA (onnxruntime falls back to the CPU silently when CUDA's libraries do
not load), and that the descriptors match the CPU's for the same crops."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

ort = pytest.importorskip("onnxruntime")
pytest.importorskip("onnx")

from services.embedder.core.onnx_model import OnnxEmbedder, OnnxParams  # noqa: E402
from tests.fixtures.embedder_onnx_models import conv_model, projection_model  # noqa: E402
from tests.fixtures.embedder_synthetic import random_outfit, render_person  # noqa: E402

CUDA = "CUDAExecutionProvider"
CPU = "CPUExecutionProvider"

pytestmark = pytest.mark.skipif(CUDA not in ort.get_available_providers(),
                                reason="needs onnxruntime-gpu with an NVIDIA GPU (CUDAExecutionProvider is "
                                       f"not among {ort.get_available_providers()})")


def _crops(n: int) -> list[np.ndarray]:
    rng = np.random.default_rng(3)
    return [render_person(random_outfit(rng), rng, size=(int(h), int(h) // 2))
            for h in rng.integers(60, 220, size=n)]


@pytest.fixture(scope="module")
def reid_net(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return conv_model(tmp_path_factory.mktemp("cuda") / "reid_like.onnx")


def test_the_session_runs_on_cuda(reid_net: Path) -> None:
    gpu = OnnxEmbedder(OnnxParams(path=str(reid_net), providers=(CUDA, CPU)))
    assert gpu.providers[0] == CUDA, gpu.providers


def test_default_providers_take_the_gpu(reid_net: Path) -> None:
    """No --providers: TensorRT if it loads, else CUDA; never the CPU on a GPU machine."""
    auto = OnnxEmbedder(OnnxParams(path=str(reid_net)))
    assert auto.providers[0] in ("TensorrtExecutionProvider", CUDA), auto.providers


@pytest.mark.parametrize("n", [1, 7, 16])
def test_descriptors_match_the_cpu(reid_net: Path, n: int) -> None:
    crops = _crops(n)
    gpu = OnnxEmbedder(OnnxParams(path=str(reid_net), providers=(CUDA, CPU))).embed(crops)
    cpu = OnnxEmbedder(OnnxParams(path=str(reid_net), providers=(CPU,))).embed(crops)
    assert gpu.shape == cpu.shape == (n, 512)
    assert np.all(np.isfinite(gpu))
    cosine = np.sum(gpu * cpu, axis=1) / (np.linalg.norm(gpu, axis=1) * np.linalg.norm(cpu, axis=1))
    assert cosine.min() > 0.9999, cosine  # TF32 convolutions may differ in the last digits, not more
    assert np.abs(gpu - cpu).max() < 1e-2


def test_preprocessing_is_exact_on_cuda(tmp_path: Path) -> None:
    """The identity projection returns the network input itself: resize, channel order and
    normalisation are the same on the GPU (the projection is a plain MatMul in fp32)."""
    path = projection_model(tmp_path / "identity.onnx", 16, 8)
    params = dict(path=str(path), input_size=(16, 8), normalize=False)
    crop = _crops(1)
    gpu = OnnxEmbedder(OnnxParams(**params, providers=(CUDA, CPU)))  # type: ignore[arg-type]
    cpu = OnnxEmbedder(OnnxParams(**params, providers=(CPU,)))  # type: ignore[arg-type]
    assert gpu.providers[0] == CUDA
    np.testing.assert_allclose(gpu.embed(crop), cpu.embed(crop), atol=2e-2)


def test_fixed_batch_graph_in_chunks_on_cuda(tmp_path: Path) -> None:
    path = projection_model(tmp_path / "fixed.onnx", 16, 8, np.eye(3 * 16 * 8, 32, dtype=np.float32), batch=4)
    crops = _crops(10)
    gpu = OnnxEmbedder(OnnxParams(path=str(path), input_size=(16, 8), providers=(CUDA, CPU)))
    cpu = OnnxEmbedder(OnnxParams(path=str(path), input_size=(16, 8), providers=(CPU,)))
    assert gpu.fixed_batch == 4
    np.testing.assert_allclose(gpu.embed(crops), cpu.embed(crops), atol=1e-3)
