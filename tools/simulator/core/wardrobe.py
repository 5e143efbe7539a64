"""Clothing palettes: distinct outfits, drawn per seed."""

from __future__ import annotations

import numpy as np

from tools.simulator.core.body import Clothing

__all__ = ["OUTFITS", "SKINS", "draw_outfits", "person_height"]

OUTFITS: tuple[Clothing, ...] = (
    Clothing((0.75, 0.1, 0.1), (0.15, 0.2, 0.4), description="red sweater, blue jeans"),
    Clothing(
        (0.1, 0.45, 0.2),
        (0.2, 0.18, 0.16),
        "stripes",
        (0.92, 0.92, 0.85),
        description="green-white striped shirt, brown trousers",
    ),
    Clothing((0.95, 0.85, 0.2), (0.1, 0.1, 0.12), long_sleeves=False, description="yellow t-shirt, black trousers"),
    Clothing((0.15, 0.3, 0.75), (0.6, 0.55, 0.45), description="blue hoodie, beige chinos"),
    Clothing(
        (0.92, 0.92, 0.9),
        (0.12, 0.12, 0.3),
        "stripes",
        (0.1, 0.15, 0.45),
        description="white-navy striped top, navy trousers",
    ),
    Clothing((0.45, 0.2, 0.5), (0.3, 0.3, 0.32), long_sleeves=False, description="purple t-shirt, grey trousers"),
    Clothing((0.95, 0.5, 0.1), (0.2, 0.3, 0.2), description="orange jacket, olive trousers"),
    Clothing(
        (0.1, 0.1, 0.1),
        (0.55, 0.1, 0.15),
        "stripes",
        (0.85, 0.85, 0.85),
        description="black-grey striped top, burgundy skirt",
    ),
)

SKINS: tuple[tuple[float, float, float], ...] = (
    (0.85, 0.67, 0.55),
    (0.72, 0.53, 0.4),
    (0.5, 0.35, 0.25),
    (0.9, 0.74, 0.62),
)
HAIRS: tuple[tuple[float, float, float], ...] = (
    (0.15, 0.1, 0.07),
    (0.45, 0.3, 0.15),
    (0.08, 0.07, 0.07),
    (0.7, 0.6, 0.4),
)


def _with_body(c: Clothing, skin: tuple[float, float, float], hair: tuple[float, float, float]) -> Clothing:
    return Clothing(c.top, c.bottom, c.pattern, c.stripe, c.long_sleeves, c.shoes, skin, hair, c.description)


def draw_outfits(
    rng: np.random.Generator, people: int, per_person: int = 1, alike: bool = False
) -> list[list[Clothing]]:
    """Wardrobes: ``per_person`` distinct outfits for each of ``people`` people, none shared,
    except that with ``alike`` the first two people start dressed the same."""
    order = rng.permutation(len(OUTFITS))
    need = people * per_person
    if need > len(OUTFITS):
        raise ValueError(f"{need} outfits asked for, only {len(OUTFITS)} exist")
    wardrobes: list[list[Clothing]] = []
    for p in range(people):
        skin, hair = SKINS[int(rng.integers(len(SKINS)))], HAIRS[int(rng.integers(len(HAIRS)))]
        wardrobes.append([_with_body(OUTFITS[order[p * per_person + k]], skin, hair) for k in range(per_person)])
    if alike and people >= 2:
        first = wardrobes[0][0]
        wardrobes[1][0] = _with_body(first, wardrobes[1][0].skin, wardrobes[1][0].hair)
    return wardrobes


def person_height(rng: np.random.Generator) -> float:
    """A height (m) in [1.5, 1.95], around 1.72."""
    return float(np.clip(rng.normal(1.72, 0.1), 1.5, 1.95))
