"""A person's stature as a cue (a soft biometric of RGB-D Re-ID, Barbosa et al. 2012): the robust
profile's tracks learn how tall their person stands, and a detection of someone taller or shorter
weighs against the track.

The depth detector measures the top of a standing person's points above the floor (a detection's
``stature_m``: the simulator's people to 1-3 cm; unknown when the head leaves the image or they
sit). Clothes do not change it, so it tells apart two people whom appearance cannot (one who steps
into the place another just left), while a person who changes clothes in view keeps their track.

* A track's ``est`` is the running mean of its confident standing detections' statures over ``n``
  of them (at most ``window``: an exponential mean after that); from ``min_samples`` on, a
  measurement farther than ``gate_m`` from it (a raised arm, a head bent down) does not change it.
* The log-odds that detection d is track t: the measurement under the track's stature,
  ``N(h; est, noise^2 (1 + 1 / n))``, against a stranger's from the population,
  ``N(h; population_mean_m, population_sd_m^2 + noise^2)``, clipped to ``clip``, times ``weight``.
  Both sides are mixed alike with the measurements that are not the stature: ``outlier_low`` of
  them up to ``low_range_m`` lower (a tall person on a high seat still passes as standing, a head
  bent or hidden), ``outlier_high`` up to ``high_range_m`` higher (a raised arm, a hat), uniform
  there (for a stranger, a population's sd wider). A lower measurement thus says little, a higher
  one much: someone taller than the track's person is someone else. 0 where either side does not
  know (no measurement, fewer than ``min_samples``): no information.

Pure numpy.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from services.tracker.core.cues.base import Cue, Pairing
from services.tracker.core.tracks import ArrayColumns

if TYPE_CHECKING:
    from services.tracker.core.tracks import RobustTrackerState, TrackTable

__all__ = ["StatureColumns", "StatureCue", "StatureParams", "log_odds", "observe", "stature_of"]

#: Any measurement from 0 to 3 m at all, 1 in 100 (a merged cluster, a lamp), for both hypotheses.
_BACKGROUND = 0.01 / 3.0


@dataclass(frozen=True)
class StatureParams:
    """The stature cue's settings (the module doc; the README's *Settings*, ``robust.stature``);
    ``population_*``: adults', men and women together."""

    noise_m: float = 0.03
    population_mean_m: float = 1.70
    population_sd_m: float = 0.10
    outlier_low: float = 0.3
    low_range_m: float = 0.6
    outlier_high: float = 0.05
    high_range_m: float = 0.3
    gate_m: float = 0.15
    min_samples: int = 3
    window: int = 50
    clip: float = 3.0
    weight: float = 1.0

    def __post_init__(self) -> None:
        if not (self.noise_m > 0 and self.population_sd_m > 0 and self.gate_m > 0 and self.low_range_m > 0
                and self.high_range_m > 0 and self.outlier_low > 0 and self.outlier_high > 0
                and self.outlier_low + self.outlier_high < 1 and self.min_samples >= 1
                and self.window >= self.min_samples and self.clip > 0 and self.weight >= 0):
            raise ValueError("need noise_m, population_sd_m, gate_m, low_range_m, high_range_m, clip > 0, outlier_low, "
                             "outlier_high > 0 with a sum below 1, 1 <= min_samples <= window and weight >= 0")


@functools.lru_cache(maxsize=8)
def _constants(p: StatureParams) -> tuple[float, float, float, float, float]:
    """(inlier share, low and high outliers' densities, a stranger's variance and its Gaussian's
    normaliser): what every frame's log-odds need of ``p``."""
    inlier = 1.0 - p.outlier_low - p.outlier_high
    pop_var = p.population_sd_m ** 2 + p.noise_m ** 2
    return (inlier, p.outlier_low / p.low_range_m, p.outlier_high / p.high_range_m, pop_var,
            inlier / math.sqrt(2 * math.pi * pop_var))


def _outliers(d: np.ndarray, spread: float, p: StatureParams, low: float, high: float) -> np.ndarray:
    """The density of the measurements that are not the stature at ``d`` = measurement - stature:
    ``low`` up to ``low_range_m`` below, ``high`` up to ``high_range_m`` above, each range
    ``spread`` wider at the same density (for a stranger: the plateau of the ranges convolved
    with the population's spread); plus the background."""
    below = np.where(d >= -p.low_range_m - spread, low, 0.0) * (d <= spread)
    above = np.where(d <= p.high_range_m + spread, high, 0.0) * (d >= -spread)
    return below + above + _BACKGROUND


def log_odds(heights: np.ndarray, est: np.ndarray, n: np.ndarray, p: StatureParams) -> np.ndarray | None:
    """(N, T) weighted log-odds of detection statures ``heights`` (N,; NaN: unknown) under the
    tracks' estimates ``est`` (T,) from ``n`` (T,) measurements; None where no pair has both."""
    known = np.isfinite(heights)
    learnt = n >= p.min_samples
    if not known.any() or not learnt.any():
        return None
    every_known, every_learnt = bool(known.all()), bool(learnt.all())
    inlier, low, high, pop_var, pop_norm = _constants(p)
    h = heights if every_known else np.where(known, heights, p.population_mean_m)
    var = p.noise_m ** 2 * (1.0 + 1.0 / np.maximum(n, 1))  # (T,): the measurement's and the estimate's
    d = h[:, None] - (est if every_learnt else np.where(learnt, est, p.population_mean_m))[None, :]
    same = (inlier / np.sqrt(2 * math.pi * var)) * np.exp(-0.5 * d * d / var) + _outliers(d, 0.0, p, low, high)
    dp = h - p.population_mean_m
    other = pop_norm * np.exp(-0.5 * dp * dp / pop_var) + _outliers(dp, p.population_sd_m, p, low, high)
    out = np.log(same / other[:, None])
    np.minimum(out, p.clip, out=out)
    np.maximum(out, -p.clip, out=out)
    out *= p.weight
    if not every_known:
        out[~known] = 0.0
    if not every_learnt:
        out[:, ~learnt] = 0.0
    return out


def observe(est: np.ndarray, n: np.ndarray, tracks: np.ndarray, heights: np.ndarray,
            p: StatureParams) -> tuple[np.ndarray, np.ndarray]:
    """New (``est``, ``n``) after the tracks ``tracks`` (K,) were matched with detections of
    statures ``heights`` (K,; NaN: unknown, no change); distinct tracks."""
    use = np.isfinite(heights)
    if not use.any():
        return est, n
    t, h = tracks[use], heights[use]
    m, k = est[t], n[t]
    keep = (k < p.min_samples) | (np.abs(h - np.where(k > 0, m, h)) <= p.gate_m)
    t, h, m, k = t[keep], h[keep], m[keep], k[keep]
    est, n = est.copy(), n.copy()
    k1 = np.minimum(k + 1, p.window)
    est[t] = np.where(k > 0, m + (h - m) / k1, h)
    n[t] = k1
    return est, n

NAME = "stature"


@dataclass
class StatureColumns(ArrayColumns):
    """``est`` (T,) each track's stature (m) and ``n`` (T,) how many measurements it holds."""

    est: np.ndarray = field(default_factory=lambda: np.zeros(0))
    n: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))

    def rows(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        return np.zeros(k), np.zeros(k, np.int64)

    def merge(self, j: int, old: int) -> None:
        n_old, n_new = int(self.n[old]), int(self.n[j])
        if n_old:  # the measurements of both, weighed by their counts
            self.est[j] = (self.est[old] * n_old + self.est[j] * n_new) / (n_old + n_new)
            self.n[j] = n_old + n_new

    def clear(self, j: int) -> None:
        self.n[j] = 0


def stature_of(t: TrackTable, j: int) -> tuple[float, int]:
    """Track ``j``'s stature and its count of measurements (0, 0: none)."""
    cols = t.extra.get(NAME)
    n = int(cols.n[j]) if cols is not None else 0  # type: ignore[attr-defined]
    return (float(cols.est[j]) if n else 0.0), n  # type: ignore[union-attr]


class StatureCue(Cue):
    """The log-odds of each detection's stature under the track's (:func:`log_odds`);
    a matched track learns its confident detection's stature (a forgotten person's learns none),
    a new track starts with its detection's."""

    name = NAME

    def __init__(self, params: StatureParams) -> None:
        self.params = params

    def columns(self) -> StatureColumns:
        return StatureColumns()

    def log_odds(self, pairing: Pairing, state: RobustTrackerState) -> np.ndarray | None:
        statures = pairing.frame.statures
        if statures is None:
            return None
        cols: StatureColumns = state.tracks.extra[NAME]  # type: ignore[assignment]
        return log_odds(statures, cols.est, cols.n, self.params)

    def learn(self, pairing: Pairing, state: RobustTrackerState, rows: np.ndarray) -> None:
        statures, t = pairing.frame.statures, state.tracks
        if statures is None or not rows.shape[1]:
            return
        d_idx, t_idx = rows
        ok = pairing.confident[d_idx] & ~np.array([t.forgotten[j] for j in t_idx.tolist()], bool)
        cols: StatureColumns = t.extra[NAME]  # type: ignore[assignment]
        cols.est, cols.n = observe(cols.est, cols.n, t_idx[ok], statures[d_idx][ok], self.params)

    def born(self, pairing: Pairing, state: RobustTrackerState, first: int, dets: np.ndarray) -> None:
        statures = pairing.frame.statures
        if statures is None:
            return
        cols: StatureColumns = state.tracks.extra[NAME]  # type: ignore[assignment]
        h = statures[dets]  # the new rows' arrays are this frame's own (the table's append made them)
        known = np.flatnonzero(np.isfinite(h))
        cols.est[first + known], cols.n[first + known] = h[known], 1
