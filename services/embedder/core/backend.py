"""What every descriptor backend provides, and cropping boxes out of an image."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, Protocol

import numpy as np

__all__ = ["Backend", "Card", "EmbedderError", "box_slices", "crop_boxes"]


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


def box_slices(boxes_xyxy: np.ndarray, width: int, height: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Integer pixel bounds of boxes in a ``width`` x ``height`` image.

    ``boxes_xyxy`` is (N, 4) float pixel corners (x0, y0, x1, y1). Edges are rounded
    outwards (floor / ceil) and clamped to the image. Returns ``slices`` (N, 4) int64
    ``(x0, y0, x1, y1)``, ``usable`` (N,) bool: finite and not empty after clamping
    (zero area, inverted and entirely outside boxes are not), and ``clipped`` (N,) bool:
    usable boxes that reached outside the image by a pixel or more and were cut.
    """
    boxes = np.asarray(boxes_xyxy, dtype=np.float64).reshape(-1, 4)
    finite = np.all(np.isfinite(boxes), axis=1)
    safe = np.where(finite[:, None], boxes, 0.0)
    lo = np.floor(safe[:, :2])
    hi = np.ceil(safe[:, 2:])
    x0, y0 = np.clip(lo[:, 0], 0, width), np.clip(lo[:, 1], 0, height)
    x1, y1 = np.clip(hi[:, 0], 0, width), np.clip(hi[:, 1], 0, height)
    slices = np.column_stack([x0, y0, x1, y1]).astype(np.int64)
    usable = finite & (x1 > x0) & (y1 > y0)
    outside = (safe[:, 0] <= -1) | (safe[:, 1] <= -1) | (safe[:, 2] >= width + 1) | (safe[:, 3] >= height + 1)
    return slices, usable, usable & outside


def crop_boxes(image: np.ndarray, boxes_xyxy: np.ndarray) -> tuple[list[np.ndarray], np.ndarray]:
    """Cut boxes out of an image, clamped to it.

    ``image`` is (H, W, 3); ``boxes_xyxy`` is (N, 4) float pixel corners (x0, y0, x1, y1).
    Box edges are rounded outwards (floor / ceil) and clamped to the image. Boxes that
    are empty after clamping (zero area, inverted, entirely outside, non-finite) are
    skipped. Returns the crops (views into ``image``) and the (K,) int indices of the
    boxes they came from.
    """
    h, w = image.shape[:2]
    slices, usable, _ = box_slices(boxes_xyxy, w, h)
    keep = np.flatnonzero(usable)
    crops = [image[y0:y1, x0:x1] for x0, y0, x1, y1 in slices[keep]]
    return crops, keep
