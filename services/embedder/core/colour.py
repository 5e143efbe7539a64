"""The ``colour`` descriptor: striped, foreground-weighted colour histograms and a colour profile, 224-D.

Design (the TU Ilmenau framework, §3.2.3, and Basso/Munaro, §5.2, use colour histograms of
the person for re-identification; this one needs no training; the parts are those known to
work for hand-made Re-ID features: body-part stripes, light-robust colour, foreground
weighting):

* Every crop is resized to :data:`CROP_H` x :data:`CROP_W` (64 x 32) pixels.
* **Lighting robustness.** A grey-world white balance first scales R, G and B so the
  crop averages grey, which undoes most of a colour-temperature change (warm lamps,
  daylight). Hue and saturation do not change when the light gets brighter or dimmer
  (a common gain on R, G, B), so coloured pixels are binned on hue x saturation only.
  Grey, black and white pixels have no reliable hue; they go to *achromatic* bins on a
  value scale first divided by the crop's median value, so a global gain cancels there
  too. A pixel is split smoothly between the two groups by its saturation (ramp 0.3 to
  0.5) and its value (ramp 0.05 to 0.15), and hue is soft-binned (linear interpolation
  between the two nearest of 8 circular bins).
* **Stripes.** The crop is cut into 6 horizontal stripes: head (top 16 %), then five
  down the torso and legs (to 30, 45, 60, 80 and 100 %). Each stripe gets 32 bins
  (8 hue x 3 saturation + 8 achromatic value), normalised to sum 1: 6 x 32 = 192 values.
* **Colour profile.** 8 horizontal bands, each described by the weighted mean of its
  intensity (divided by the crop's median intensity, so a global gain cancels) and
  its two chromaticities r/(r+g+b), g/(r+g+b) (which a global gain leaves alone) and
  the spread of its intensity: 8 x 4 = 32 values. Histograms say which colours, the
  profile says where, at a finer vertical step (where a jacket ends, light shoes).
* **Foreground weighting.** Pixels are weighted by a central elliptical profile, so the
  background at the sides and corners of the box counts less than the person. When a
  per-pixel mask is given (the embedder's depth mask), it multiplies these weights.
* **Distance.** Each stripe histogram is square-rooted (Euclidean distance between
  square-rooted histograms is the Hellinger distance), scaled by the stripe's weight
  (head 0.5, the others 1.0), the histogram part and the profile are each L2-normalised
  and weighted (1.0 and :attr:`ColourParams.profile_weight`) and the whole vector is
  L2-normalised. Distances lie in [0, 2].

Everything after the per-crop resize is vectorised over all crops of a frame.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import cv2
import numpy as np

from services.embedder.core.backend import Card

__all__ = ["COLOUR_THRESHOLDS", "CROP_H", "CROP_W", "DIM", "ColourDescriptor", "ColourParams"]

CROP_H = 64
CROP_W = 32
HUE_BINS = 8
SAT_BINS = 3
VALUE_BINS = 8
STRIPE_BINS = HUE_BINS * SAT_BINS + VALUE_BINS
#: Stripe boundaries as fractions of the box height: head, then torso and legs.
STRIPES = (0.0, 0.16, 0.30, 0.45, 0.60, 0.80, 1.0)
#: Bands of the colour profile and its values per band (intensity, r, g chromaticity, spread).
PROFILE_BANDS = 8
PROFILE_VALUES = 4
HIST_DIM = STRIPE_BINS * (len(STRIPES) - 1)
DIM = HIST_DIM + PROFILE_BANDS * PROFILE_VALUES
#: Recommended tracker thresholds (t_lower, t_upper, t_recover) on this descriptor's
#: Euclidean scale, from ``perception calibrate-embedder`` on pets09_dev ground-truth
#: crops (every 10th frame: 222 crops of 10 people, 2,787 same-person pairs 0.1 to 40 s
#: apart): it suggests 0.318 / 0.725 / 0.385 (pair AUC 0.874, rank-1 0.824). Rounded to
#: the safer side: t_lower under the 1 % stranger quantile, t_upper above the 99 %
#: same-person quantile.
COLOUR_THRESHOLDS = (0.31, 0.75, 0.38)


@dataclass(frozen=True)
class ColourParams:
    """Tunable knobs of the descriptor (the defaults are the documented, calibrated ones)."""

    stripe_weights: tuple[float, ...] = (0.5, 1.0, 1.0, 1.0, 1.0, 1.0)
    #: Saturation ramp (start, end) over which a pixel turns from achromatic to chromatic.
    sat_ramp: tuple[float, float] = (0.30, 0.50)
    #: Value ramp (start, end): very dark pixels have no reliable hue.
    val_ramp: tuple[float, float] = (0.05, 0.15)
    #: Ellipse semi-axes as fractions of the crop's half width / half height.
    ellipse: tuple[float, float] = (1.0, 1.1)
    #: Weight of pixels outside the ellipse (inside it rises to 1 at the centre line).
    background_weight: float = 0.15
    #: Divide value by this percentile of the crop's value before achromatic binning
    #: (None: bin the absolute value).
    value_percentile: float | None = 50.0
    #: Grey-world white balance: "crop" scales R, G, B so the whole crop averages grey,
    #: "border" uses only the crop's border (mostly background), "none" skips it.
    white_balance: Literal["crop", "border", "none"] = "crop"
    #: Exponent on the white-balance gains (0 = off, 1 = full correction).
    white_balance_strength: float = 1.0
    #: Relative value mapped onto the achromatic bins: [0, value_range].
    value_range: float = 1.0
    #: Weight of the colour profile against the histograms (0: histograms only).
    profile_weight: float = 1.0


def _ramp(x: np.ndarray, lo: float, hi: float) -> np.ndarray:
    return np.clip((x - lo) / (hi - lo), 0.0, 1.0)


class ColourDescriptor:
    """The ``colour`` backend: ``embed(crops, masks=None) -> (N, 224) float32``, rows L2-normalised.

    ``crops`` is a list of (h, w, 3) uint8 RGB arrays of any positive size; ``masks``,
    when given, one (h, w) float array in [0, 1] (or None) per crop that weights its pixels.
    """

    card = Card(name="colour", dim=DIM, metric="euclidean", input_size=(CROP_H, CROP_W),
                normalized=True, thresholds=COLOUR_THRESHOLDS)
    #: The embedder service may hand this backend per-pixel foreground masks.
    accepts_masks = True

    def __init__(self, params: ColourParams | None = None) -> None:
        self.params = p = params or ColourParams()
        if len(p.stripe_weights) != len(STRIPES) - 1:
            raise ValueError(f"stripe_weights needs {len(STRIPES) - 1} values, got {len(p.stripe_weights)}")
        ys, xs = np.mgrid[0:CROP_H, 0:CROP_W].astype(np.float32)
        u = (xs + 0.5 - CROP_W / 2) / (CROP_W / 2 * p.ellipse[0])
        v = (ys + 0.5 - CROP_H / 2) / (CROP_H / 2 * p.ellipse[1])
        r2 = u * u + v * v
        #: (H, W) float32 pixel weights: 1 on the centre line, falling to background_weight.
        self.mask = np.maximum(1.0 - r2, 0.0) * (1.0 - p.background_weight) + p.background_weight
        rows = (np.arange(CROP_H) + 0.5) / CROP_H
        #: (H,) stripe index of each row.
        self.stripe_of_row = np.searchsorted(np.asarray(STRIPES[1:-1]), rows, side="right")
        #: (H,) profile band of each row.
        self.band_of_row = (np.arange(CROP_H) * PROFILE_BANDS) // CROP_H
        self._stripe_w = np.asarray(p.stripe_weights, np.float32)
        #: (H, W) weights of the border (background) pixels for the white balance.
        self._border = (r2 > 1.0).astype(np.float32)

    def __call__(self, crops: list[np.ndarray]) -> np.ndarray:
        return self.embed(crops)

    def prepare(self, crop: np.ndarray) -> np.ndarray:
        """Resize one (h, w, C) crop (uint8 RGB, or a float mask) to (CROP_H, CROP_W, C)."""
        h, w = crop.shape[:2]
        interp = cv2.INTER_AREA if h >= CROP_H and w >= CROP_W else cv2.INTER_LINEAR
        return cv2.resize(np.ascontiguousarray(crop), (CROP_W, CROP_H), interpolation=interp)

    def embed(self, crops: list[np.ndarray], masks: Sequence[np.ndarray | None] | None = None) -> np.ndarray:
        if not crops:
            return np.zeros((0, DIM), np.float32)
        batch = np.stack([self.prepare(c) for c in crops])  # (N, H, W, 3) uint8
        weights = None
        if masks is not None:
            if len(masks) != len(crops):
                raise ValueError(f"got {len(masks)} masks for {len(crops)} crops")
            weights = np.ones((len(crops), CROP_H, CROP_W), np.float32)
            for i, m in enumerate(masks):
                if m is not None:
                    weights[i] = np.clip(self.prepare(np.asarray(m, np.float32)), 0.0, 1.0)
        return self.from_resized(batch, weights)

    def from_resized(self, batch: np.ndarray, weights: np.ndarray | None = None) -> np.ndarray:
        """Descriptors of (N, CROP_H, CROP_W, 3) uint8 RGB crops -> (N, DIM) float32.

        ``weights`` (N, CROP_H, CROP_W) in [0, 1] multiply the elliptical profile; a crop
        whose weights leave (almost) nothing is described with the profile alone.
        """
        n = batch.shape[0]
        p = self.params
        rgb = batch.astype(np.float32) * np.float32(1.0 / 255.0)
        weight = np.broadcast_to(self.mask, (n, CROP_H, CROP_W)).astype(np.float32)
        if weights is not None:
            masked = weight * weights
            enough = masked.sum(axis=(1, 2)) >= 0.02 * weight[0].sum()
            weight = np.where(enough[:, None, None], masked, weight)
        if p.white_balance != "none" and p.white_balance_strength > 0:
            wb = self._border if p.white_balance == "border" else np.ones_like(self._border)
            means = np.einsum("nhwc,hw->nc", rgb, wb) / wb.sum()  # (N, 3)
            gains = means.mean(axis=1, keepdims=True) / np.maximum(means, 1e-3)
            gains = np.clip(gains, 0.5, 2.0) ** p.white_balance_strength
            rgb = np.clip(rgb * gains[:, None, None, :].astype(np.float32), 0.0, 1.0)
        hist = self._histograms(rgb, weight)
        profile = self._profile(rgb, weight)
        desc = np.concatenate([hist, p.profile_weight * profile], axis=1)
        desc /= np.maximum(np.linalg.norm(desc, axis=1, keepdims=True), 1e-12)
        return desc.astype(np.float32)

    def _histograms(self, rgb: np.ndarray, weight: np.ndarray) -> np.ndarray:
        """(N, HIST_DIM) square-rooted, stripe-weighted, L2-normalised histograms."""
        n = rgb.shape[0]
        p = self.params
        tall = rgb.reshape(n * CROP_H, CROP_W, 3)
        hsv = cv2.cvtColor(tall, cv2.COLOR_RGB2HSV).reshape(n, CROP_H, CROP_W, 3)
        hue, sat, val = hsv[..., 0], hsv[..., 1], hsv[..., 2]  # degrees, [0,1], [0,1]

        chroma = _ramp(sat, *p.sat_ramp) * _ramp(val, *p.val_ramp)  # (N, H, W)
        w_chroma = weight * chroma
        w_achro = weight * (1.0 - chroma)
        stripes = len(STRIPES) - 1

        # Base offset of each pixel's stripe block: (N, H, W) int.
        stripe = np.broadcast_to(self.stripe_of_row[None, :, None], chroma.shape)
        block = (np.arange(n)[:, None, None] * stripes + stripe) * STRIPE_BINS

        # Chromatic: soft circular hue bins x hard saturation bins.
        hpos = hue * (HUE_BINS / 360.0) - 0.5
        h0 = np.floor(hpos)
        frac = hpos - h0
        h0 = h0.astype(np.int64) % HUE_BINS
        h1 = (h0 + 1) % HUE_BINS
        s_bin = np.minimum((sat * SAT_BINS).astype(np.int64), SAT_BINS - 1)
        total = n * stripes * STRIPE_BINS
        hist: np.ndarray = np.bincount((block + h0 * SAT_BINS + s_bin).ravel(), (w_chroma * (1 - frac)).ravel(), total)
        hist += np.bincount((block + h1 * SAT_BINS + s_bin).ravel(), (w_chroma * frac).ravel(), total)

        # Achromatic: soft bins of value relative to the crop's bright level.
        if p.value_percentile is None:
            rel = val
        else:
            bright = np.percentile(val.reshape(n, -1), p.value_percentile, axis=1)
            rel = val / np.maximum(bright, 1e-3)[:, None, None]
        vpos = np.clip(rel / p.value_range, 0.0, 1.0) * (VALUE_BINS - 1)
        v0 = np.minimum(np.floor(vpos).astype(np.int64), VALUE_BINS - 2)
        vfrac = vpos - v0
        base = block + HUE_BINS * SAT_BINS
        hist += np.bincount((base + v0).ravel(), (w_achro * (1 - vfrac)).ravel(), total)
        hist += np.bincount((base + v0 + 1).ravel(), (w_achro * vfrac).ravel(), total)

        hist = hist.reshape(n, stripes, STRIPE_BINS)
        hist /= np.maximum(hist.sum(axis=2, keepdims=True), 1e-12)
        desc = (np.sqrt(hist) * self._stripe_w[None, :, None]).reshape(n, HIST_DIM)
        return desc / np.maximum(np.linalg.norm(desc, axis=1, keepdims=True), 1e-12)

    def _profile(self, rgb: np.ndarray, weight: np.ndarray) -> np.ndarray:
        """(N, PROFILE_BANDS * PROFILE_VALUES) L2-normalised colour profile (see the module docstring)."""
        n = rgb.shape[0]
        total = rgb.sum(axis=3)  # (N, H, W)
        inten = total / 3.0
        median = np.median(inten.reshape(n, -1), axis=1)
        rel = np.clip(inten / np.maximum(median, 1e-3)[:, None, None], 0.0, 2.0)
        safe = np.maximum(total, 1e-3)
        r = rgb[..., 0] / safe * 3.0 - 1.0  # 0 for grey
        g = rgb[..., 1] / safe * 3.0 - 1.0
        band_w = np.zeros((n, PROFILE_BANDS), np.float32)
        np.add.at(band_w, (slice(None), self.band_of_row), weight.sum(axis=2))
        band_w = np.maximum(band_w, 1e-6)

        def band_mean(x: np.ndarray) -> np.ndarray:
            s = np.zeros((n, PROFILE_BANDS), np.float32)
            np.add.at(s, (slice(None), self.band_of_row), (weight * x).sum(axis=2))
            return s / band_w

        mean_rel = band_mean(rel)
        spread = np.sqrt(np.maximum(band_mean(rel * rel) - mean_rel ** 2, 0.0))
        prof = np.stack([mean_rel, band_mean(r), band_mean(g), spread], axis=2).reshape(n, -1)
        return prof / np.maximum(np.linalg.norm(prof, axis=1, keepdims=True), 1e-12)
