"""Legs and people in one 2-D scan: segment, describe, classify, pair.

A segment's leg probability comes from boosted trees over its shape (:mod:`.features`,
:mod:`.boost`), calibrated on the dev scans. Legs closer than ``pair_m`` are paired greedily,
the nearest pair first, into a person between them; a leg left alone is a person too, with a
wider covariance (the other leg is hidden or merged into the same segment). Positions are in
the scanner's frame.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from scipy.special import expit

from services.laser.core.boost import Boosted
from services.laser.core.features import MODEL_COLUMNS, NAMES, features
from services.laser.core.scan import ScanGeometry, beams
from services.laser.core.segments import centres, segment

__all__ = ["LegParams", "Legs", "People", "detect", "pair"]


@dataclass(frozen=True)
class LegParams:
    join_m: float = 0.13
    min_points: int = 3
    #: segments wider than this, or farther, are never legs (a wall, a table's edge)
    max_width_m: float = 0.8
    max_range_m: float = 8.0
    #: a leg's least probability to be reported
    min_probability: float = 0.2
    #: two legs closer than this are one person
    pair_m: float = 0.8
    #: the standard deviation of a person's position: a pair's centre, a lone leg (the other leg
    #: may be up to a stride away)
    pair_sigma_m: float = 0.12
    lone_sigma_m: float = 0.3

    def __post_init__(self) -> None:
        for name in ("join_m", "max_width_m", "max_range_m", "pair_m", "pair_sigma_m", "lone_sigma_m"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        if not 0 <= self.min_probability < 1:
            raise ValueError(f"min_probability must be in [0, 1), got {self.min_probability}")


@dataclass(frozen=True)
class Legs:
    """``xy`` (L, 2) each leg's centre (m), ``probability`` (L,) and its ``log_odds`` (which
    rank legs where the probability rounds to 1), ``width`` (L,) m, and ``beams``:
    each leg's beam indices; ``invalid`` the scan's invalid beams by reason."""

    xy: np.ndarray
    probability: np.ndarray
    log_odds: np.ndarray
    width: np.ndarray
    beams: list[np.ndarray] = field(default_factory=list)
    invalid: dict[str, int] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.probability)

    def only(self, keep: np.ndarray) -> Legs:
        """These legs but those ``keep`` (L,) is False for (the invalid beams' counts stay)."""
        if keep.all():
            return self
        idx = np.flatnonzero(keep)
        return replace(self, xy=self.xy[idx], probability=self.probability[idx],
                       log_odds=self.log_odds[idx], width=self.width[idx],
                       beams=[self.beams[i] for i in idx.tolist()])


@dataclass(frozen=True)
class People:
    """``xy`` (P, 2), ``cov`` (P, 2, 2), ``probability`` (P,) that it is a person, and ``legs``:
    the indices into :class:`Legs` of each one's legs (one or two)."""

    xy: np.ndarray
    cov: np.ndarray
    probability: np.ndarray
    legs: list[tuple[int, ...]]

    def __len__(self) -> int:
        return len(self.probability)


def detect(ranges: np.ndarray, geometry: ScanGeometry, model: Boosted, p: LegParams = LegParams()) -> Legs:
    """The legs in one scan's ``ranges``."""
    b = beams(ranges, geometry)
    seg = segment(b, p.join_m, p.min_points)
    x = features(b, seg)
    if not len(x):
        return Legs(np.zeros((0, 2)), np.zeros(0), np.zeros(0), np.zeros(0), [], b.invalid)
    width, distance = x[:, NAMES.index("width")], x[:, NAMES.index("distance")]
    log_odds = model.log_odds(x[:, MODEL_COLUMNS])
    log_odds[(width > p.max_width_m) | (distance > p.max_range_m)] = -np.inf
    prob = expit(log_odds)
    keep = np.flatnonzero(prob >= p.min_probability)
    return Legs(centres(b, seg)[keep], prob[keep], log_odds[keep], width[keep],
                [seg.beams_of(int(s)) for s in keep], b.invalid)


def pair(legs: Legs, p: LegParams = LegParams()) -> People:
    """People from ``legs``: the nearest pairs within ``pair_m`` first, then the lone legs.
    A pair's probability is that at least one of its legs is a leg (independent votes)."""
    n = len(legs)
    used = np.zeros(n, bool)
    groups: list[tuple[int, ...]] = []
    if n > 1:
        d = np.linalg.norm(legs.xy[:, None] - legs.xy[None], axis=2)
        i, j = np.triu_indices(n, 1)
        close = d[i, j] < p.pair_m
        for k in np.argsort(d[i, j][close], kind="stable"):
            a, b = int(i[close][k]), int(j[close][k])
            if not used[a] and not used[b]:
                used[a] = used[b] = True
                groups.append((a, b))
    groups += [(k,) for k in range(n) if not used[k]]
    groups.sort()
    if not groups:
        return People(np.zeros((0, 2)), np.zeros((0, 2, 2)), np.zeros(0), [])
    xy = np.array([legs.xy[list(g)].mean(axis=0) for g in groups])
    prob = np.array([1.0 - float(np.prod(1.0 - legs.probability[list(g)])) for g in groups])
    cov = np.array([_covariance(legs.xy[list(g)], p) for g in groups])
    return People(xy, cov, prob, groups)


def _covariance(xy: np.ndarray, p: LegParams) -> np.ndarray:
    """A pair: the prior spread plus half the legs' separation along the line between them (the
    torso is somewhere between the feet); a lone leg: round, ``lone_sigma_m``."""
    if len(xy) == 1:
        return np.eye(2) * p.lone_sigma_m ** 2
    d = xy[1] - xy[0]
    return np.eye(2) * p.pair_sigma_m ** 2 + np.outer(d, d) / 12.0


def in_frame(people: People, rotation: np.ndarray, translation: np.ndarray, z: float,
             z_sigma: float) -> tuple[np.ndarray, np.ndarray]:
    """``people``'s positions (P, 3) and covariances (P, 3, 3) in another frame: ``rotation``
    (3, 3) and ``translation`` (3,) map the scanner's frame into it; the height is not measured
    by a 2-D scan, so z is the prior ``z`` with standard deviation ``z_sigma`` (the TU Ilmenau
    framework gives its laser's people a prior height the same way)."""
    k = len(people)
    local = np.column_stack([people.xy, np.zeros(k)]) if k else np.zeros((0, 3))
    pos = local @ rotation.T + translation
    pos[:, 2] = z
    cov = np.zeros((k, 3, 3))
    cov[:, :2, :2] = people.cov
    cov = rotation @ cov @ rotation.T
    cov[:, 2, :] = 0.0
    cov[:, :, 2] = 0.0
    cov[:, 2, 2] = z_sigma ** 2
    return pos, cov
