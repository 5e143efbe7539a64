"""Synthetic pedestrians for tests and benchmarks: a person drawn from an outfit.

A :class:`Outfit` fixes what identifies a person (skin, hair, shirt, trousers, shoes).
:func:`render_person` draws one view of it on a random textured background with pose
jitter, sensor noise and an optional illumination change, so tests can compare the
same outfit across views and lightings against different outfits.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

__all__ = ["Illumination", "Outfit", "random_outfit", "render_person"]

Colour = tuple[int, int, int]


@dataclass(frozen=True)
class Outfit:
    """RGB colours of one synthetic person."""

    skin: Colour
    hair: Colour
    shirt: Colour
    trousers: Colour
    shoes: Colour = (30, 30, 30)


@dataclass(frozen=True)
class Illumination:
    """A lighting change: per-channel gains (colour temperature) times a global gain, then gamma."""

    gain: float = 1.0
    rgb_gains: tuple[float, float, float] = (1.0, 1.0, 1.0)
    gamma: float = 1.0

    def apply(self, image: np.ndarray) -> np.ndarray:
        """(H, W, 3) uint8 RGB -> relit (H, W, 3) uint8 RGB."""
        x = image.astype(np.float32) / 255.0 * self.gain * np.asarray(self.rgb_gains, np.float32)
        x = np.clip(x, 0.0, 1.0) ** self.gamma
        return (x * 255.0 + 0.5).astype(np.uint8)


def random_outfit(rng: np.random.Generator) -> Outfit:
    """A random, plausible outfit: saturated or neutral clothes, a skin and a hair tone."""

    def cloth() -> Colour:
        if rng.random() < 0.35:  # black, grey, white
            v = int(rng.integers(20, 235))
            return (v, v, v)
        hsv = np.array([rng.integers(0, 180), rng.integers(110, 255), rng.integers(70, 240)], np.uint8)
        r, g, b = cv2.cvtColor(hsv.reshape(1, 1, 3), cv2.COLOR_HSV2RGB)[0, 0]
        return (int(r), int(g), int(b))

    skins = [(235, 200, 170), (200, 150, 110), (150, 100, 70), (95, 65, 45)]
    hairs = [(20, 15, 10), (90, 60, 30), (200, 170, 90), (120, 120, 120)]
    return Outfit(skin=skins[rng.integers(len(skins))], hair=hairs[rng.integers(len(hairs))],
                  shirt=cloth(), trousers=cloth())


def render_person(outfit: Outfit, rng: np.random.Generator, size: tuple[int, int] = (128, 64),
                  illumination: Illumination | None = None, noise: float = 4.0) -> np.ndarray:
    """One view of ``outfit`` as an (H, W, 3) uint8 RGB crop of ``size`` (H, W).

    The person fills most of the crop (as a detector box would); position, width, leg
    stride and arm swing jitter per call; the background is random low-frequency, mostly neutral texture.
    """
    h, w = size
    # Floors and walls: mostly neutral tones with a slight tint, in soft patches.
    grey = rng.uniform(70, 200, size=(4, 2, 1))
    tint = rng.normal(0, 12, size=(4, 2, 3))
    small = np.clip(grey + tint, 0, 255).astype(np.float32)
    img = cv2.resize(small, (w, h), interpolation=cv2.INTER_CUBIC)
    cx = w / 2 + rng.normal(0, 0.04 * w)
    s = 1.0 + rng.normal(0, 0.04)
    top = 0.04 * h + rng.normal(0, 0.01 * h)

    def rect(x0: float, y0: float, x1: float, y1: float, colour: Colour) -> None:
        cv2.rectangle(img, (int(x0), int(y0)), (int(x1), int(y1)), colour, thickness=-1)

    head_r = 0.075 * h * s
    head_c = (int(cx), int(top + head_r))
    cv2.ellipse(img, head_c, (int(head_r * 0.8), int(head_r)), 0, 0, 360, outfit.skin, -1)
    hair_c = (head_c[0], int(top + 0.5 * head_r))
    cv2.ellipse(img, hair_c, (int(head_r * 0.85), int(head_r * 0.6)), 0, 180, 360, outfit.hair, -1)
    neck = top + 2 * head_r
    torso_w = 0.42 * w * s
    hip = neck + 0.36 * h * s
    rect(cx - torso_w / 2, neck, cx + torso_w / 2, hip, outfit.shirt)
    swing = rng.normal(0, 0.03 * h)
    arm_w = 0.1 * w * s
    for side in (-1, 1):
        ax = cx + side * (torso_w / 2 + arm_w / 2)
        rect(ax - arm_w / 2, neck + 0.02 * h, ax + arm_w / 2, hip - 0.02 * h + side * swing, outfit.shirt)
        rect(ax - arm_w / 2, hip - 0.02 * h + side * swing, ax + arm_w / 2, hip + 0.03 * h + side * swing, outfit.skin)
    stride = abs(rng.normal(0.08, 0.04)) * w
    leg_w = 0.17 * w * s
    foot = min(h - 2.0, hip + 0.48 * h * s)
    for side in (-1, 1):
        lx = cx + side * (leg_w / 2 + stride / 2)
        rect(lx - leg_w / 2, hip, lx + leg_w / 2, foot - 0.04 * h, outfit.trousers)
        rect(lx - leg_w / 2, foot - 0.04 * h, lx + leg_w / 2 + side * 0.03 * w, foot, outfit.shoes)
    img += np.asarray(rng.normal(0.0, noise, img.shape), np.float32)
    blurred = np.asarray(cv2.GaussianBlur(img, (3, 3), 0.7))
    out = np.clip(blurred, 0, 255).astype(np.uint8)
    return illumination.apply(out) if illumination is not None else out
