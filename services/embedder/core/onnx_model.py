"""The ``onnx`` backend: any Re-ID network exported to ONNX, run with onnxruntime.

The graph takes one float32 input (N, 3, H, W) and returns (N, D) (trailing singleton
dimensions such as (N, D, 1, 1) are flattened). All crops of a frame go through the
network in one batched call; a graph exported with a fixed batch size B is fed in
chunks of B, padded, with a warning at load time.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import cv2
import numpy as np

from services.embedder.core.backend import Card, EmbedderError

__all__ = ["IMAGENET_MEAN", "IMAGENET_STD", "PROVIDER_PREFERENCE", "OnnxEmbedder", "OnnxParams", "choose_providers"]

log = logging.getLogger(__name__)

IMAGENET_MEAN = (0.485, 0.456, 0.406)
IMAGENET_STD = (0.229, 0.224, 0.225)
#: Providers tried in this order when none are given: the fastest one available wins.
PROVIDER_PREFERENCE = ("TensorrtExecutionProvider", "CUDAExecutionProvider", "CPUExecutionProvider")


@dataclass(frozen=True)
class OnnxParams:
    """How to feed and read one ONNX Re-ID model.

    Pixels are scaled by ``scale`` (1/255 maps uint8 to [0, 1]), then ``(x - mean) / std``
    per channel in ``channel_order``. ``providers`` None picks TensorRT, CUDA, then CPU.
    """

    path: str
    name: str = ""
    input_size: tuple[int, int] = (256, 128)
    channel_order: Literal["rgb", "bgr"] = "rgb"
    scale: float = 1.0 / 255.0
    mean: tuple[float, float, float] = IMAGENET_MEAN
    std: tuple[float, float, float] = IMAGENET_STD
    normalize: bool = True
    metric: Literal["euclidean", "cosine"] = "euclidean"
    thresholds: tuple[float, float, float] | None = None
    providers: tuple[str, ...] | None = None
    intra_op_threads: int = 0
    provider_options: dict[str, dict[str, str]] = field(default_factory=dict)


def choose_providers(requested: tuple[str, ...] | None, available: list[str]) -> list[str]:
    """The execution providers to use: ``requested`` (checked), or the preferred available ones."""
    if requested:
        missing = [p for p in requested if p not in available]
        if missing:
            raise EmbedderError(f"execution provider(s) {missing} are not available in this onnxruntime; "
                                f"available: {available} (install onnxruntime-gpu for CUDA/TensorRT)")
        return list(requested)
    chosen = [p for p in PROVIDER_PREFERENCE if p in available]
    return chosen or list(available)


def _check_fallback(chosen: list[str], got: list[str], requested: bool) -> None:
    """onnxruntime drops an accelerator whose libraries do not load (CUDA, cuDNN, TensorRT) with
    a log line only and runs on what is left. Accelerators asked for by name none of which
    came up are an error; otherwise a lost one is a warning that names what is used."""
    lost = [name for name in chosen if name not in got and name != "CPUExecutionProvider"]
    if not lost:
        return
    hint = (f"onnxruntime could not start {lost} (their libraries did not load: CUDA 12/13 runtime and cuDNN 9 "
            f"for CUDA, libnvinfer for TensorRT; see onnxruntime's log above) and runs on {got}")
    if requested and not [name for name in got if name != "CPUExecutionProvider"]:
        raise EmbedderError(f"{hint}; install the libraries (pip install 'onnxruntime-gpu[cuda,cudnn]') or "
                            "leave out --providers to take what is available")
    log.warning("%s", hint)


class OnnxEmbedder:
    """Runs an ONNX Re-ID model on batches of crops; see :class:`OnnxParams`."""

    def __init__(self, params: OnnxParams) -> None:
        import onnxruntime as ort

        self.params = p = params
        path = Path(p.path).expanduser()
        if not path.is_file():
            raise EmbedderError(f"ONNX model file not found: {path} (give an existing file, or create the "
                                "bundled one with 'perception export-embedder')")
        if len(p.input_size) != 2 or min(p.input_size) <= 0:
            raise EmbedderError(f"input_size must be (H, W) with positive sizes, got {p.input_size}")
        if len(p.mean) != 3 or len(p.std) != 3 or min(p.std) <= 0:
            raise EmbedderError(f"mean and std need 3 values each, std positive; got {p.mean}, {p.std}")
        providers = choose_providers(p.providers, ort.get_available_providers())
        if any(name in providers for name in PROVIDER_PREFERENCE[:2]) and hasattr(ort, "preload_dlls"):
            # CUDA and cuDNN from pip (onnxruntime-gpu[cuda,cudnn], or PyTorch's) are not on the
            # loader's path: onnxruntime finds and loads them here (1.21 and later)
            try:
                ort.preload_dlls()
            except Exception as exc:  # a library it did not find: the provider check below names the outcome
                log.debug("onnxruntime.preload_dlls: %s", exc)
        options = ort.SessionOptions()
        options.intra_op_num_threads = p.intra_op_threads
        provider_args = [(name, p.provider_options.get(name, {})) for name in providers]
        try:
            self.session = ort.InferenceSession(str(path), options, providers=provider_args)
        except Exception as exc:  # onnxruntime raises its own, unexported exception types
            raise EmbedderError(f"onnxruntime could not load {path}: {exc}") from exc
        inputs, outputs = self.session.get_inputs(), self.session.get_outputs()
        if len(inputs) != 1:
            raise EmbedderError(f"{path.name}: expected one input (N, 3, H, W), the graph has {len(inputs)}")
        shape = list(inputs[0].shape)
        if len(shape) != 4:
            raise EmbedderError(f"{path.name}: input {inputs[0].name!r} has rank {len(shape)} {shape}; "
                                "a Re-ID model must take (N, 3, H, W)")
        if isinstance(shape[1], int) and shape[1] != 3:
            raise EmbedderError(f"{path.name}: input has {shape[1]} channels, expected 3 (N, 3, H, W)")
        for axis, want in ((2, p.input_size[0]), (3, p.input_size[1])):
            if isinstance(shape[axis], int) and shape[axis] != want:
                raise EmbedderError(f"{path.name}: the graph's input is {shape[2]}x{shape[3]} (H x W) but "
                                    f"input_size is {p.input_size[0]}x{p.input_size[1]}; set input_size to match")
        self.fixed_batch = shape[0] if isinstance(shape[0], int) and shape[0] > 0 else None
        if self.fixed_batch is not None:
            log.warning("%s has a fixed batch size of %d; crops are run in chunks of that size "
                        "(export with a dynamic batch axis to run a frame in one call)", path.name, self.fixed_batch)
        self.input_name = inputs[0].name
        self.output_name = outputs[0].name
        self.providers = self.session.get_providers()
        _check_fallback(providers, self.providers, requested=bool(p.providers))
        self._mean = (np.asarray(p.mean, np.float32) / np.float32(p.scale)).reshape(1, 1, 1, 3)
        self._inv_std = (np.float32(p.scale) / np.asarray(p.std, np.float32)).reshape(1, 1, 1, 3)
        probe = self._run(np.zeros((1, p.input_size[0], p.input_size[1], 3), np.uint8))
        dim = int(probe.shape[1])
        self.card = Card(name=p.name or path.stem, dim=dim, metric=p.metric,
                         input_size=(p.input_size[0], p.input_size[1]), normalized=p.normalize,
                         thresholds=p.thresholds)
        log.info("onnx embedder %s: %d-D, input %dx%d, providers %s", self.card.name, dim,
                 p.input_size[0], p.input_size[1], self.providers)

    def preprocess(self, batch: np.ndarray) -> np.ndarray:
        """(N, H, W, 3) uint8 RGB resized crops -> (N, 3, H, W) float32 network input."""
        x = batch.astype(np.float32)
        if self.params.channel_order == "bgr":
            x = x[..., ::-1]
        x = (x - self._mean) * self._inv_std
        return np.ascontiguousarray(x.transpose(0, 3, 1, 2))

    def _run(self, batch: np.ndarray) -> np.ndarray:
        x = self.preprocess(batch)
        n = x.shape[0]
        if self.fixed_batch is None:
            out = self.session.run([self.output_name], {self.input_name: x})[0]
        else:
            b = self.fixed_batch
            padded = np.concatenate([x, np.zeros((-n % b, *x.shape[1:]), np.float32)])
            out = np.concatenate([self.session.run([self.output_name], {self.input_name: padded[i:i + b]})[0]
                                  for i in range(0, len(padded), b)])[:n]
        out = np.asarray(out, dtype=np.float32)
        if out.ndim < 2 or out.shape[0] != n or (out.ndim > 2 and any(d != 1 for d in out.shape[2:])):
            raise EmbedderError(f"model output {self.output_name!r} has shape {out.shape}; expected ({n}, D)")
        return out.reshape(n, -1)

    def embed(self, crops: list[np.ndarray]) -> np.ndarray:
        """(N, D) float32 descriptors of (h, w, 3) uint8 RGB crops, one network call per batch."""
        h, w = self.params.input_size
        if not crops:
            return np.zeros((0, self.card.dim), np.float32)
        batch = np.stack([cv2.resize(np.ascontiguousarray(c), (w, h), interpolation=cv2.INTER_LINEAR)
                          for c in crops])
        out = self._run(batch)
        if self.params.normalize:
            out /= np.maximum(np.linalg.norm(out, axis=1, keepdims=True), 1e-12)
        return out
