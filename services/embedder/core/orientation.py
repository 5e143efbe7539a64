"""An optional upper-body orientation classifier on the person crop (TU Ilmenau), any ONNX model.

The graph takes the crops as float32 (N, 3, H, W), like the Re-ID backends, and returns
(N, 8) scores of 8 orientation bins of 45 degrees *relative to the camera*: bin k means
the person faces the direction k * 45 degrees anticlockwise (seen from above) from
"towards the camera"; bin 0 faces the camera, bin 4 shows their back. The tracker turns
them into the map frame with the camera's pose. Scores become probabilities with a
softmax unless the model already outputs probabilities (``outputs: probabilities``).

The network is run through :class:`services.embedder.core.onnx_model.OnnxEmbedder`
(one batched call per frame, the same preprocessing settings), without its L2
normalisation.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from services.embedder.core.backend import EmbedderError
from services.embedder.core.onnx_model import IMAGENET_MEAN, IMAGENET_STD, OnnxEmbedder, OnnxParams

__all__ = ["BINS", "OrientationClassifier", "OrientationParams"]

BINS = 8


@dataclass(frozen=True)
class OrientationParams:
    path: str
    input_size: tuple[int, int] = (128, 64)
    channel_order: Literal["rgb", "bgr"] = "rgb"
    scale: float = 1.0 / 255.0
    mean: tuple[float, float, float] = IMAGENET_MEAN
    std: tuple[float, float, float] = IMAGENET_STD
    outputs: Literal["logits", "probabilities"] = "logits"


class OrientationClassifier:
    """``classify(crops) -> (N, 8)`` probabilities of each orientation bin (camera-relative)."""

    def __init__(self, params: OrientationParams) -> None:
        self.params = params
        self._net = OnnxEmbedder(OnnxParams(path=params.path, name="orientation", input_size=params.input_size,
                                            channel_order=params.channel_order, scale=params.scale, mean=params.mean,
                                            std=params.std, normalize=False))
        if self._net.card.dim != BINS:
            raise EmbedderError(f"{params.path}: an orientation model must output (N, {BINS}) scores, "
                                f"it outputs (N, {self._net.card.dim})")

    def classify(self, crops: list[np.ndarray]) -> np.ndarray:
        if not crops:
            return np.zeros((0, BINS), np.float32)
        scores = np.asarray(self._net.embed(crops), np.float64).reshape(len(crops), BINS)
        if self.params.outputs == "probabilities":
            p = np.clip(scores, 0.0, None)
        else:
            p = np.exp(scores - scores.max(axis=1, keepdims=True))
        total = p.sum(axis=1, keepdims=True)
        return np.where(total > 0, p / np.where(total > 0, total, 1.0), 1.0 / BINS).astype(np.float32)
