"""One metrics core: CLEAR MOT, identity (IDF1) and re-identification measures.

The core is fed, frame by frame, the ground-truth IDs, the hypothesis IDs and the
distance matrix between them. It knows nothing about boxes, metres or files: 3-D
Euclidean distances and 2-D ``1 - IoU`` distances go through the same code.

Matching follows py-motmetrics's ``MOTAccumulator`` (Bernardin and Stiefelhagen 2008):

1. A pair is *valid* when its distance is finite and within the threshold
   (``d <= threshold`` when ``inclusive``, ``d < threshold`` otherwise).
2. Every ground-truth object whose last matched hypothesis is present in this frame
   keeps it while the pair is valid (objects visited in input order).
3. The remaining objects and hypotheses are matched by a minimum-cost assignment over
   the valid pairs (invalid pairs priced so that the most valid pairs are matched
   first, then the cheapest). A match whose object was last matched to another
   hypothesis is an ID switch; it is also a *recall error* (seed 000, §V-C) when its
   hypothesis had earlier been matched to a different object.
4. Unmatched objects are misses, unmatched hypotheses false positives.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field, fields
from typing import Iterable

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import linear_sum_assignment

__all__ = ["ClearMot", "ClearMotAccumulator", "FrameEvents", "evaluate_frames", "gate_distances", "solve_assignment"]

MOSTLY_TRACKED = 0.8
MOSTLY_LOST = 0.2


def gate_distances(dist: ArrayLike, threshold: float, inclusive: bool = True) -> NDArray[np.float64]:
    """Copy of ``dist`` (N, M) float64 with NaN wherever a pair may not be matched."""
    d = np.array(dist, dtype=np.float64, copy=True)
    with np.errstate(invalid="ignore"):
        too_far = d > threshold if inclusive else d >= threshold
    d[too_far | ~np.isfinite(d)] = np.nan
    return d


def solve_assignment(cost: NDArray[np.float64]) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Minimum-cost assignment over the finite entries of ``cost`` (N, M).

    Non-finite entries get a price higher than any ``min(N, M)`` finite edges together,
    so a solution never trades a valid pair for a cheaper arrangement with fewer pairs;
    they are then dropped from the result. Returns (rows, cols), rows ascending.
    """
    valid = np.isfinite(cost)
    if not valid.any():
        empty = np.empty(0, dtype=np.intp)
        return empty, empty
    c = float(np.abs(cost[valid]).max()) + 1.0
    priced = np.where(valid, cost, 2.0 * min(cost.shape) * c + 1.0)
    rows, cols = linear_sum_assignment(priced)
    keep = valid[rows, cols]
    return rows[keep], cols[keep]


@dataclass(frozen=True)
class FrameEvents:
    """What one frame produced. Pairs are (gt_id, hyp_id, distance)."""

    matches: list[tuple[int, int, float]]
    switches: list[tuple[int, int, float]]
    recall_errors: list[tuple[int, int, float]]
    misses: list[int]
    false_positives: list[int]


@dataclass(frozen=True)
class ClearMot:
    """Counts of one evaluation (one sequence, or several combined).

    ``matches`` counts continued or new correspondences that are not ID switches, so
    ``objects == matches + id_switches + misses``. ``consistency_counts`` is seed 001's
    histogram: per GT person the matched-frame counts of each hypothesis ID, sorted
    descending, summed element-wise over people (not normalised, so it can be combined).
    """

    frames: int = 0
    objects: int = 0
    predictions: int = 0
    matches: int = 0
    misses: int = 0
    false_positives: int = 0
    id_switches: int = 0
    recall_errors: int = 0
    fragmentations: int = 0
    distance_sum: float = 0.0
    idtp: int = 0
    gt_tracks: int = 0
    mostly_tracked: int = 0
    partially_tracked: int = 0
    mostly_lost: int = 0
    consistency_counts: tuple[int, ...] = field(default_factory=tuple)

    @property
    def detections(self) -> int:
        """Matched pairs, ID switches included (MOTP's denominator)."""
        return self.matches + self.id_switches

    @property
    def mota(self) -> float:
        return 1.0 - _ratio(self.misses + self.false_positives + self.id_switches, self.objects)

    @property
    def motp(self) -> float:
        """Mean distance of the matched pairs (metres, or 1 - IoU)."""
        return _ratio(self.distance_sum, self.detections)

    @property
    def idfp(self) -> int:
        return self.predictions - self.idtp

    @property
    def idfn(self) -> int:
        return self.objects - self.idtp

    @property
    def idf1(self) -> float:
        return _ratio(2 * self.idtp, self.objects + self.predictions)

    @property
    def idp(self) -> float:
        return _ratio(self.idtp, self.predictions)

    @property
    def idr(self) -> float:
        return _ratio(self.idtp, self.objects)

    @property
    def consistency_histogram(self) -> list[float]:
        """Seed 001's sorted ID histogram, normalised to sum to 1 (empty if nothing matched)."""
        total = sum(self.consistency_counts)
        return [c / total for c in self.consistency_counts] if total else []

    @property
    def consistency(self) -> float:
        """Share of the matched time during which people kept their main hypothesis ID."""
        hist = self.consistency_histogram
        return hist[0] if hist else float("nan")

    def percent(self, count: int) -> float:
        """``count`` as a percentage of the ground-truth objects."""
        return 100.0 * _ratio(count, self.objects)

    @classmethod
    def combine(cls, parts: Iterable[ClearMot]) -> ClearMot:
        """Totals over sequences whose IDs are unrelated (as py-motmetrics's merged overall)."""
        parts = list(parts)
        kwargs: dict[str, object] = {}
        for f in fields(cls):
            if f.name != "consistency_counts":
                kwargs[f.name] = sum(getattr(p, f.name) for p in parts)
        width = max((len(p.consistency_counts) for p in parts), default=0)
        hist = np.zeros(width, dtype=np.int64)
        for p in parts:
            hist[: len(p.consistency_counts)] += np.asarray(p.consistency_counts, dtype=np.int64)
        kwargs["consistency_counts"] = tuple(int(c) for c in hist)
        return cls(**kwargs)  # type: ignore[arg-type]

    def to_dict(self) -> dict[str, object]:
        """Every count and derived metric, JSON-ready (NaN becomes None)."""
        out: dict[str, object] = {f.name: getattr(self, f.name) for f in fields(self)}
        out["consistency_counts"] = list(self.consistency_counts)
        for name in ("detections", "idfp", "idfn"):
            out[name] = getattr(self, name)
        for name in ("mota", "motp", "idf1", "idp", "idr", "consistency"):
            out[name] = _finite_or_none(getattr(self, name))
        for name in ("misses", "false_positives", "id_switches"):
            out[f"{name}_pct"] = _finite_or_none(self.percent(getattr(self, name)))
        out["consistency_histogram"] = self.consistency_histogram
        return out


class ClearMotAccumulator:
    """Feed frames with :meth:`update`, read the result with :meth:`result`.

    IDs are integers; within a frame the GT IDs must be unique, and so must the
    hypothesis IDs. GT and hypothesis IDs live in separate name spaces.
    """

    def __init__(self, threshold: float, inclusive: bool = True) -> None:
        if not np.isfinite(threshold) or threshold < 0:
            raise ValueError(f"threshold must be a finite number >= 0, got {threshold}")
        self.threshold = float(threshold)
        self.inclusive = inclusive
        self._last_hyp: dict[int, int] = {}  # GT id -> hypothesis of its latest match
        self._hyp_gts: dict[int, set[int]] = {}  # hypothesis id -> GT ids it was ever matched to
        self._tracked: dict[int, list[bool]] = {}  # GT id -> matched?, per frame it is present
        self._id_hist: dict[int, Counter[int]] = {}  # GT id -> matched frames per hypothesis
        self._pairs_gt: list[NDArray[np.int64]] = []  # valid pairs, for the global ID matching
        self._pairs_hyp: list[NDArray[np.int64]] = []
        self._frames = self._objects = self._predictions = 0
        self._matches = self._switches = self._recall = self._misses = self._fps = 0
        self._distance_sum = 0.0

    def update(self, gt_ids: ArrayLike, hyp_ids: ArrayLike, dist: ArrayLike | None) -> FrameEvents:
        """Match one frame. ``dist`` is (N, M) for N GT and M hypothesis IDs; NaN/inf = no pair."""
        gt = np.asarray(gt_ids, dtype=np.int64).reshape(-1)
        hyp = np.asarray(hyp_ids, dtype=np.int64).reshape(-1)
        n, m = gt.size, hyp.size
        if np.unique(gt).size != n or np.unique(hyp).size != m:
            raise ValueError(f"IDs must be unique within a frame (GT {gt.tolist()}, hypotheses {hyp.tolist()})")
        if n == 0 or m == 0 or dist is None:
            d = np.full((n, m), np.nan)
        else:
            d = gate_distances(np.asarray(dist, dtype=np.float64).reshape(n, m), self.threshold, self.inclusive)
        gt_done = np.zeros(n, dtype=bool)
        hyp_done = np.zeros(m, dtype=bool)
        events = FrameEvents([], [], [], [], [])

        # 1. Keep last frame's correspondences while they stay valid.
        hyp_col = {int(h): j for j, h in enumerate(hyp)}
        for i, o in enumerate(gt.tolist()):
            previous = self._last_hyp.get(o)
            j = None if previous is None else hyp_col.get(previous)
            if j is None or hyp_done[j] or not np.isfinite(d[i, j]):
                continue
            gt_done[i] = hyp_done[j] = True
            self._record(o, int(hyp[j]), float(d[i, j]), switch=False, events=events)

        # 2. Minimum-cost assignment of the rest.
        free = d.copy()
        free[gt_done, :] = np.nan
        free[:, hyp_done] = np.nan
        for i, j in zip(*solve_assignment(free)):
            o, h = int(gt[i]), int(hyp[j])
            previous = self._last_hyp.get(o)
            gt_done[i] = hyp_done[j] = True
            self._record(o, h, float(d[i, j]), switch=previous is not None and previous != h, events=events)

        # 3./4. Misses and false positives; bookkeeping for the per-object and ID measures.
        events.misses.extend(int(o) for o in gt[~gt_done])
        events.false_positives.extend(int(h) for h in hyp[~hyp_done])
        for o, done in zip(gt.tolist(), gt_done.tolist()):
            self._tracked.setdefault(o, []).append(done)
        rows, cols = np.nonzero(np.isfinite(d))
        self._pairs_gt.append(gt[rows])
        self._pairs_hyp.append(hyp[cols])
        self._frames += 1
        self._objects += n
        self._predictions += m
        self._misses += len(events.misses)
        self._fps += len(events.false_positives)
        return events

    def _record(self, o: int, h: int, distance: float, switch: bool, events: FrameEvents) -> None:
        pair = (o, h, distance)
        if switch:
            self._switches += 1
            events.switches.append(pair)
            if any(g != o for g in self._hyp_gts.get(h, ())):
                self._recall += 1
                events.recall_errors.append(pair)
        else:
            self._matches += 1
            events.matches.append(pair)
        self._last_hyp[o] = h
        self._hyp_gts.setdefault(h, set()).add(o)
        self._id_hist.setdefault(o, Counter())[h] += 1
        self._distance_sum += distance

    def result(self) -> ClearMot:
        """The counts so far (the accumulator can keep being updated)."""
        frag = mt = pt = ml = 0
        for flags in self._tracked.values():
            tracked = np.asarray(flags, dtype=bool)
            ratio = tracked.mean()
            mt += int(ratio >= MOSTLY_TRACKED)
            ml += int(ratio < MOSTLY_LOST)
            pt += int(MOSTLY_LOST <= ratio < MOSTLY_TRACKED)
            hit = np.flatnonzero(tracked)
            if hit.size:
                span = tracked[hit[0] : hit[-1] + 1]
                frag += int(np.count_nonzero(span[:-1] & ~span[1:]))
        width = max((len(c) for c in self._id_hist.values()), default=0)
        hist = np.zeros(width, dtype=np.int64)
        for counts in self._id_hist.values():
            sorted_counts = sorted(counts.values(), reverse=True)
            hist[: len(sorted_counts)] += sorted_counts
        return ClearMot(
            frames=self._frames, objects=self._objects, predictions=self._predictions,
            matches=self._matches, misses=self._misses, false_positives=self._fps,
            id_switches=self._switches, recall_errors=self._recall, fragmentations=frag,
            distance_sum=self._distance_sum, idtp=self._global_id_matches(), gt_tracks=len(self._tracked),
            mostly_tracked=int(mt), partially_tracked=int(pt), mostly_lost=int(ml),
            consistency_counts=tuple(int(c) for c in hist),
        )

    def _global_id_matches(self) -> int:
        """IDTP: most frames coverable by a one-to-one GT-to-hypothesis ID mapping (Ristani et al. 2016)."""
        if not self._pairs_gt:
            return 0
        gt = np.concatenate(self._pairs_gt)
        hyp = np.concatenate(self._pairs_hyp)
        if gt.size == 0:
            return 0
        gt_ids, gi = np.unique(gt, return_inverse=True)
        hyp_ids, hi = np.unique(hyp, return_inverse=True)
        counts = np.zeros((gt_ids.size, hyp_ids.size), dtype=np.int64)
        np.add.at(counts, (gi, hi), 1)
        rows, cols = linear_sum_assignment(counts, maximize=True)
        return int(counts[rows, cols].sum())


def evaluate_frames(
    frames: Iterable[tuple[ArrayLike, ArrayLike, ArrayLike | None]],
    threshold: float,
    inclusive: bool = True,
) -> ClearMot:
    """Run :class:`ClearMotAccumulator` over (gt_ids (N,), hyp_ids (M,), dist (N, M)) frames."""
    acc = ClearMotAccumulator(threshold, inclusive)
    for gt_ids, hyp_ids, dist in frames:
        acc.update(gt_ids, hyp_ids, dist)
    return acc.result()


def _ratio(num: float, den: float) -> float:
    return float(num) / den if den else float("nan")


def _finite_or_none(x: float) -> float | None:
    return float(x) if np.isfinite(x) else None

