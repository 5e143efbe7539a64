"""Depth cuts the background: a per-pixel mask of each box keeping the pixels near the person's depth.

The person's depth is the ``percentile``-th percentile of the valid depth pixels in the
box, as the localizer takes it (background behind the person is farther, so a low
percentile picks the person). Pixels within ``near_m`` in front of it and ``far_m``
behind it get weight 1, the rest 0; pixels without depth (0, NaN, out of range: hair,
black clothes and edges often have none) get ``unknown_weight``. The descriptor
multiplies its own foreground weights by the mask.

A box gets no mask, and is described unmasked, when it holds fewer than
``min_valid_pixels`` valid depth pixels (:data:`DEPTH_MISSING`) or when the mask keeps
fewer than ``min_kept_fraction`` of its pixels (:data:`MASK_EMPTY`); the caller counts
both.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["DEPTH_MISSING", "MASK_EMPTY", "DepthMaskParams", "apply_mask", "depth_masks"]

#: Fewer than ``min_valid_pixels`` valid depth pixels in the box.
DEPTH_MISSING = "depth_missing"
#: The mask keeps (almost) no pixel of the box.
MASK_EMPTY = "mask_empty"


@dataclass(frozen=True)
class DepthMaskParams:
    """Settings of :func:`depth_masks`; ``depth_unit_m`` scales integer depth images (uint16 mm)."""

    percentile: float = 25.0
    near_m: float = 0.4
    far_m: float = 0.6
    unknown_weight: float = 0.5
    min_valid_pixels: int = 20
    min_kept_fraction: float = 0.05
    min_depth_m: float = 0.3
    max_depth_m: float = 10.0
    depth_unit_m: float = 0.001

    def __post_init__(self) -> None:
        if not 0.0 <= self.percentile <= 100.0:
            raise ValueError(f"depth mask percentile must be in [0, 100], got {self.percentile}")
        if self.near_m < 0.0 or self.far_m <= 0.0:
            raise ValueError(f"depth mask near_m must be >= 0 and far_m > 0, got {self.near_m}, {self.far_m}")
        if not 0.0 <= self.unknown_weight <= 1.0:
            raise ValueError(f"depth mask unknown_weight must be in [0, 1], got {self.unknown_weight}")
        if self.min_valid_pixels < 1:
            raise ValueError(f"depth mask min_valid_pixels must be >= 1, got {self.min_valid_pixels}")


def _metres(crop: np.ndarray, params: DepthMaskParams) -> np.ndarray:
    """(h, w) float32 metres, NaN where there is no usable depth."""
    if np.issubdtype(crop.dtype, np.integer):
        m = crop.astype(np.float32) * np.float32(params.depth_unit_m)
        m[crop == 0] = np.nan
    else:
        m = crop.astype(np.float32, copy=True)
    with np.errstate(invalid="ignore"):
        m[~((m >= max(params.min_depth_m, 1e-9)) & (m <= params.max_depth_m))] = np.nan
    return m


def depth_masks(depth: np.ndarray, slices: list[tuple[int, int, int, int]],
                params: DepthMaskParams) -> tuple[list[np.ndarray | None], list[str | None]]:
    """One mask per box of ``depth`` (H, W) (uint16 in ``depth_unit_m``, or float metres).

    ``slices`` are the boxes as integer ``(x0, y0, x1, y1)`` pixel bounds inside the image
    (as :func:`services.embedder.core.backend.crop_boxes` cut them). Returns the masks,
    (h, w) float32 in [0, 1] or None, and per box None or the reason it has no mask.
    """
    masks: list[np.ndarray | None] = []
    reasons: list[str | None] = []
    for x0, y0, x1, y1 in slices:
        m = _metres(depth[y0:y1, x0:x1], params)
        valid = np.isfinite(m)
        if int(valid.sum()) < params.min_valid_pixels:
            masks.append(None)
            reasons.append(DEPTH_MISSING)
            continue
        person = float(np.percentile(m[valid], params.percentile))
        near = np.zeros(m.shape, bool)
        near[valid] = (m[valid] >= person - params.near_m) & (m[valid] <= person + params.far_m)
        mask = np.where(valid, near.astype(np.float32), np.float32(params.unknown_weight))
        if float(near.sum()) < params.min_kept_fraction * m.size:
            masks.append(None)
            reasons.append(MASK_EMPTY)
            continue
        masks.append(mask.astype(np.float32))
        reasons.append(None)
    return masks, reasons


def apply_mask(crop: np.ndarray, mask: np.ndarray | None, fill: int = 128) -> np.ndarray:
    """(h, w, 3) uint8 crop blended towards grey ``fill`` where (h, w) ``mask`` is below 1.

    For backends that take no mask (a network): the background they see becomes flat grey.
    """
    if mask is None:
        return crop
    m = np.asarray(mask, np.float32)[..., None]
    return (crop.astype(np.float32) * m + np.float32(fill) * (1.0 - m) + 0.5).astype(np.uint8)
