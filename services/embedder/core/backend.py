"""What every descriptor backend provides, and cropping boxes out of an image."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, Protocol

import numpy as np

__all__ = ["Backend", "Card", "EmbedderError", "crop_boxes"]


class EmbedderError(Exception):
    """A backend cannot be built or run (missing model file, unsupported graph, bad settings)."""


@dataclass(frozen=True)
class Card:
    """What a backend produces: travels as ``ModelCard`` with every Embeddings message.

    ``thresholds`` are the recommended tracker thresholds ``(t_lower, t_upper, t_recover)``
    on this model's distance scale, or None when nobody calibrated them yet.
    """

    name: str
    dim: int
    metric: Literal["euclidean", "cosine"] = "euclidean"
    input_size: tuple[int, int] | None = None
    normalized: bool = False
    thresholds: tuple[float, float, float] | None = None


class Backend(Protocol):
    """``embed(crops) -> (N, dim) float32``: one row per (h, w, 3) uint8 RGB crop, in order."""

    @property
    def card(self) -> Card: ...

    def embed(self, crops: list[np.ndarray]) -> np.ndarray: ...


def crop_boxes(image: np.ndarray, boxes_xyxy: np.ndarray) -> tuple[list[np.ndarray], np.ndarray]:
    """Cut boxes out of an image, clamped to it.

    ``image`` is (H, W, 3); ``boxes_xyxy`` is (N, 4) float pixel corners (x0, y0, x1, y1).
    Box edges are rounded outwards (floor / ceil) and clamped to the image. Boxes that
    are empty after clamping (zero area, inverted, entirely outside, non-finite) are
    skipped. Returns the crops (views into ``image``) and the (K,) int indices of the
    boxes they came from.
    """
    boxes = np.asarray(boxes_xyxy, dtype=np.float64).reshape(-1, 4)
    h, w = image.shape[:2]
    finite = np.all(np.isfinite(boxes), axis=1)
    safe = np.where(finite[:, None], boxes, 0.0)
    x0 = np.clip(np.floor(safe[:, 0]), 0, w).astype(np.int64)
    y0 = np.clip(np.floor(safe[:, 1]), 0, h).astype(np.int64)
    x1 = np.clip(np.ceil(safe[:, 2]), 0, w).astype(np.int64)
    y1 = np.clip(np.ceil(safe[:, 3]), 0, h).astype(np.int64)
    keep = np.flatnonzero(finite & (x1 > x0) & (y1 > y0))
    crops = [image[y0[i]:y1[i], x0[i]:x1[i]] for i in keep]
    return crops, keep
