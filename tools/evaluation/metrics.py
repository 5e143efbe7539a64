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
   hypothesis is an ID switch; it is also a *recall error* (Pinto's thesis, §V-C) when its
   hypothesis had earlier been matched to a different object.
4. Unmatched objects are misses, unmatched hypotheses false positives, except that a
   hypothesis still unmatched but within the gate of an *ignored* person (KITTI's ignore
   regions, given as ``ignore_dist``) is dropped from the frame: neither a hit nor a false
   positive, and absent from the identity measures.

HOTA, DetA and AssA (Luiten et al., IJCV 2021) come from :class:`HotaAccumulator`, fed
per-frame *similarities* in [0, 1]; it follows TrackEval's ``metrics/hota.py`` step for step.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field, fields
from typing import Iterable

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import linear_sum_assignment

__all__ = ["HOTA_ALPHAS", "ClearMot", "ClearMotAccumulator", "FrameEvents", "Hota", "HotaAccumulator",
           "evaluate_frames", "evaluate_hota", "gate_distances", "solve_assignment"]

MOSTLY_TRACKED = 0.8
MOSTLY_LOST = 0.2

#: HOTA's localisation thresholds: 0.05, 0.10, ..., 0.95 (19 values), built as TrackEval builds them.
HOTA_ALPHAS: NDArray[np.float64] = np.arange(0.05, 0.99, 0.05)
_EPS = float(np.finfo(np.float64).eps)


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
    ignored: list[int] = field(default_factory=list)  # unmatched hypotheses dropped by an ignore region


@dataclass(frozen=True)
class ClearMot:
    """Counts of one evaluation (one sequence, or several combined).

    ``matches`` counts continued or new correspondences that are not ID switches, so
    ``objects == matches + id_switches + misses``. ``consistency_counts`` is the TU Ilmenau
    framework's histogram: per GT person the matched-frame counts of each hypothesis ID,
    sorted descending, summed element-wise over people (not normalised, so it can be
    combined).
    ``ignored`` counts the hypotheses dropped by ignore regions (not in ``predictions``).
    ``hota_counts`` holds HOTA's sums when they were computed (``None`` otherwise, and then
    ``hota``, ``deta`` and ``assa`` are NaN).
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
    ignored: int = 0
    hota_counts: Hota | None = None

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
        """TU Ilmenau's sorted ID histogram, normalised to sum to 1 (empty if nothing matched)."""
        total = sum(self.consistency_counts)
        return [c / total for c in self.consistency_counts] if total else []

    @property
    def consistency(self) -> float:
        """Share of the matched time during which people kept their main hypothesis ID."""
        hist = self.consistency_histogram
        return hist[0] if hist else float("nan")

    @property
    def hota(self) -> float:
        """HOTA averaged over the 19 alphas (NaN if not computed)."""
        return self.hota_counts.hota if self.hota_counts is not None else float("nan")

    @property
    def deta(self) -> float:
        return self.hota_counts.deta if self.hota_counts is not None else float("nan")

    @property
    def assa(self) -> float:
        return self.hota_counts.assa if self.hota_counts is not None else float("nan")

    def percent(self, count: int) -> float:
        """``count`` as a percentage of the ground-truth objects."""
        return 100.0 * _ratio(count, self.objects)

    @classmethod
    def combine(cls, parts: Iterable[ClearMot]) -> ClearMot:
        """Totals over sequences whose IDs are unrelated (as py-motmetrics's merged overall)."""
        parts = list(parts)
        kwargs: dict[str, object] = {}
        for f in fields(cls):
            if f.name not in ("consistency_counts", "hota_counts"):
                kwargs[f.name] = sum(getattr(p, f.name) for p in parts)
        hotas = [p.hota_counts for p in parts if p.hota_counts is not None]
        kwargs["hota_counts"] = Hota.combine(hotas) if hotas and len(hotas) == len(parts) else None
        width = max((len(p.consistency_counts) for p in parts), default=0)
        hist = np.zeros(width, dtype=np.int64)
        for p in parts:
            hist[: len(p.consistency_counts)] += np.asarray(p.consistency_counts, dtype=np.int64)
        kwargs["consistency_counts"] = tuple(int(c) for c in hist)
        return cls(**kwargs)  # type: ignore[arg-type]

    def to_dict(self) -> dict[str, object]:
        """Every count and derived metric, JSON-ready (NaN becomes None)."""
        out: dict[str, object] = {f.name: getattr(self, f.name) for f in fields(self) if f.name != "hota_counts"}
        out["consistency_counts"] = list(self.consistency_counts)
        for name in ("detections", "idfp", "idfn"):
            out[name] = getattr(self, name)
        for name in ("mota", "motp", "idf1", "idp", "idr", "consistency"):
            out[name] = _finite_or_none(getattr(self, name))
        for name in ("misses", "false_positives", "id_switches"):
            out[f"{name}_pct"] = _finite_or_none(self.percent(getattr(self, name)))
        out["consistency_histogram"] = self.consistency_histogram
        h = self.hota_counts
        for name in ("hota", "deta", "assa", "detre", "detpr", "assre", "asspr", "loca"):
            out[name] = _finite_or_none(getattr(h, name)) if h is not None else None
        out["hota_per_alpha"] = h.per_alpha() if h is not None else None
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
        self._frames = self._objects = self._predictions = self._ignored = 0
        self._matches = self._switches = self._recall = self._misses = self._fps = 0
        self._distance_sum = 0.0

    def update(self, gt_ids: ArrayLike, hyp_ids: ArrayLike, dist: ArrayLike | None,
               ignore_dist: ArrayLike | None = None) -> FrameEvents:
        """Match one frame. ``dist`` is (N, M) for N GT and M hypothesis IDs; NaN/inf = no pair.

        ``ignore_dist`` (M, K), optional: distances from the hypotheses to K people of this
        frame that are neither required nor penalised (KITTI's ignore regions). After the
        matching, a hypothesis still unmatched whose distance to one of them passes the gate
        is dropped from the frame (``FrameEvents.ignored``): it is no false positive, is not
        counted in ``predictions`` and takes no part in the identity measures (IDF1).
        """
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

        # 3./4. Ignore regions drop some unmatched hypotheses (taken out of the frame for the
        # ID measures too); the other unmatched hypotheses are false positives.
        valid = np.isfinite(d)
        unmatched = ~hyp_done
        dropped = self._near_ignored(ignore_dist, m, unmatched)
        if dropped is not None:
            events.ignored.extend(int(h) for h in hyp[dropped])
            unmatched &= ~dropped
            valid[:, dropped] = False
            m -= len(events.ignored)
            self._ignored += len(events.ignored)
        events.misses.extend(int(o) for o in gt[~gt_done])
        events.false_positives.extend(int(h) for h in hyp[unmatched])
        for o, done in zip(gt.tolist(), gt_done.tolist()):
            self._tracked.setdefault(o, []).append(done)
        rows, cols = np.nonzero(valid)
        self._pairs_gt.append(gt[rows])
        self._pairs_hyp.append(hyp[cols])
        self._frames += 1
        self._objects += n
        self._predictions += m
        self._misses += len(events.misses)
        self._fps += len(events.false_positives)
        return events

    def _near_ignored(self, ignore_dist: ArrayLike | None, m: int,
                      unmatched: NDArray[np.bool_]) -> NDArray[np.bool_] | None:
        """(M,) the unmatched hypotheses within the gate of an ignored person; None if there are none."""
        if ignore_dist is None or not unmatched.any():
            return None
        d = np.asarray(ignore_dist, dtype=np.float64)
        if d.size == 0:
            return None
        near = np.isfinite(gate_distances(d.reshape(m, -1), self.threshold, self.inclusive)).any(axis=1) & unmatched
        return near if near.any() else None

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
            consistency_counts=tuple(int(c) for c in hist), ignored=self._ignored,
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


@dataclass(frozen=True)
class Hota:
    """HOTA's sums over one evaluation, one entry per alpha of ``alphas`` (Luiten et al., IJCV 2021).

    ``tp``, ``fn`` and ``fp`` count detections matched with a similarity >= alpha, GT
    detections left unmatched and hypotheses left unmatched. ``ass_sum`` is the sum over
    the true positives of their association score A(c) (so AssA = ass_sum / TP), and
    ``ass_re_sum`` / ``ass_pr_sum`` likewise for AssRe and AssPr; ``loc_sum`` is the sum of
    the similarities of the true positives. Being sums, results of sequences combine by
    adding them, which is how TrackEval combines sequences (AssA weighted by TP).
    """

    alphas: tuple[float, ...]
    tp: tuple[int, ...]
    fn: tuple[int, ...]
    fp: tuple[int, ...]
    ass_sum: tuple[float, ...]
    ass_re_sum: tuple[float, ...]
    ass_pr_sum: tuple[float, ...]
    loc_sum: tuple[float, ...]

    @classmethod
    def empty(cls, alphas: ArrayLike = HOTA_ALPHAS) -> Hota:
        a = tuple(float(x) for x in np.asarray(alphas, dtype=np.float64).reshape(-1))
        zeros_i, zeros_f = (0,) * len(a), (0.0,) * len(a)
        return cls(a, zeros_i, zeros_i, zeros_i, zeros_f, zeros_f, zeros_f, zeros_f)

    @classmethod
    def combine(cls, parts: Iterable[Hota]) -> Hota:
        """Totals over sequences (their IDs unrelated), as TrackEval's ``combine_sequences``."""
        parts = list(parts)
        if not parts:
            return cls.empty()
        alphas = parts[0].alphas
        if any(p.alphas != alphas for p in parts):
            raise ValueError("cannot combine HOTA results computed over different alphas")
        kwargs: dict[str, object] = {"alphas": alphas}
        for f in fields(cls):
            if f.name != "alphas":
                total = np.sum([np.asarray(getattr(p, f.name)) for p in parts], axis=0)
                kwargs[f.name] = tuple(total.tolist())
        return cls(**kwargs)  # type: ignore[arg-type]

    @property
    def is_empty(self) -> bool:
        """No ground truth and no hypothesis at all: every figure is NaN."""
        return not any(self.tp) and not any(self.fn) and not any(self.fp)

    # Per-alpha curves (arrays of len(alphas)), with TrackEval's max(1, .) denominators.
    def _curve(self, num: tuple[float, ...], *den: tuple[int, ...]) -> NDArray[np.float64]:
        return np.asarray(num, dtype=np.float64) / np.maximum(1.0, np.sum([np.asarray(d) for d in den], axis=0))

    @property
    def det_re_curve(self) -> NDArray[np.float64]:
        return self._curve(self.tp, self.tp, self.fn)

    @property
    def det_pr_curve(self) -> NDArray[np.float64]:
        return self._curve(self.tp, self.tp, self.fp)

    @property
    def det_a_curve(self) -> NDArray[np.float64]:
        return self._curve(self.tp, self.tp, self.fn, self.fp)

    @property
    def ass_a_curve(self) -> NDArray[np.float64]:
        return self._curve(self.ass_sum, self.tp)

    @property
    def ass_re_curve(self) -> NDArray[np.float64]:
        return self._curve(self.ass_re_sum, self.tp)

    @property
    def ass_pr_curve(self) -> NDArray[np.float64]:
        return self._curve(self.ass_pr_sum, self.tp)

    @property
    def hota_curve(self) -> NDArray[np.float64]:
        return np.sqrt(self.det_a_curve * self.ass_a_curve)

    @property
    def loc_a_curve(self) -> NDArray[np.float64]:
        return np.maximum(1e-10, np.asarray(self.loc_sum)) / np.maximum(1e-10, np.asarray(self.tp, dtype=np.float64))

    def _mean(self, curve: NDArray[np.float64]) -> float:
        return float("nan") if self.is_empty else float(np.mean(curve))

    # The figures benchmarks rank by: each curve averaged over the alphas.
    @property
    def hota(self) -> float:
        return self._mean(self.hota_curve)

    @property
    def deta(self) -> float:
        return self._mean(self.det_a_curve)

    @property
    def assa(self) -> float:
        return self._mean(self.ass_a_curve)

    @property
    def detre(self) -> float:
        return self._mean(self.det_re_curve)

    @property
    def detpr(self) -> float:
        return self._mean(self.det_pr_curve)

    @property
    def assre(self) -> float:
        return self._mean(self.ass_re_curve)

    @property
    def asspr(self) -> float:
        return self._mean(self.ass_pr_curve)

    @property
    def loca(self) -> float:
        return self._mean(self.loc_a_curve)

    def per_alpha(self) -> dict[str, list[float]] | None:
        """The curves, JSON-ready (``None`` when empty)."""
        if self.is_empty:
            return None
        return {"alpha": [round(a, 2) for a in self.alphas], "hota": self.hota_curve.tolist(),
                "deta": self.det_a_curve.tolist(), "assa": self.ass_a_curve.tolist(),
                "tp": list(self.tp), "fn": list(self.fn), "fp": list(self.fp)}


class HotaAccumulator:
    """HOTA, DetA and AssA of one sequence: feed frames with :meth:`update`, then :meth:`result`.

    ``similarity`` is (N, M) in [0, 1] (IoU for boxes; a decreasing function of distance
    for points). The algorithm is TrackEval's (``trackeval/metrics/hota.py``):

    1. Global alignment: per frame, each pair's similarity is normalised as a Jaccard
       index against its row and column sums (``S / (rowsum + colsum - S)``), summed over
       frames per (GT ID, hypothesis ID), and divided by ``n_gt + n_hyp - that sum``.
    2. Per frame, one Hungarian assignment maximising ``alignment * similarity``; for each
       alpha the assigned pairs with ``similarity >= alpha`` are true positives, the rest
       of the GT and hypotheses are FN and FP.
    3. Per alpha, A(c) = TPA / (TPA + FNA + FPA) of each (GT ID, hypothesis ID) pair, with
       TPA its true positives: AssA = sum over TPs of A(c) / TP; DetA = TP / (TP + FN + FP);
       HOTA = sqrt(DetA * AssA). The reported figures are averages over the 19 alphas.

    The two passes need every frame, so the frames are kept until :meth:`result`.
    """

    def __init__(self, alphas: ArrayLike = HOTA_ALPHAS) -> None:
        self.alphas = np.asarray(alphas, dtype=np.float64).reshape(-1)
        self._frames: list[tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64]]] = []

    def update(self, gt_ids: ArrayLike, hyp_ids: ArrayLike, similarity: ArrayLike | None) -> None:
        """Add one frame: N GT IDs, M hypothesis IDs, their (N, M) similarity (None if N or M is 0)."""
        gt = np.asarray(gt_ids, dtype=np.int64).reshape(-1)
        hyp = np.asarray(hyp_ids, dtype=np.int64).reshape(-1)
        n, m = gt.size, hyp.size
        if len(set(gt.tolist())) != n or len(set(hyp.tolist())) != m:
            raise ValueError(f"IDs must be unique within a frame (GT {gt.tolist()}, hypotheses {hyp.tolist()})")
        if n == 0 or m == 0 or similarity is None:
            sim = np.zeros((n, m))
        else:
            sim = np.asarray(similarity, dtype=np.float64).reshape(n, m)
            if not ((sim >= 0.0).all() and (sim <= 1.0).all()):  # NaN fails both
                raise ValueError("similarities must be finite numbers in [0, 1]")
        self._frames.append((gt, hyp, sim))

    def result(self) -> Hota:
        """The sums of HOTA over the frames so far."""
        n_alpha = self.alphas.size
        frames = self._frames
        all_gt = np.concatenate([f[0] for f in frames]) if frames else np.empty(0, np.int64)
        all_hyp = np.concatenate([f[1] for f in frames]) if frames else np.empty(0, np.int64)
        gt_ids, hyp_ids = np.unique(all_gt), np.unique(all_hyp)
        if all_gt.size == 0 or all_hyp.size == 0:
            zeros = np.zeros(n_alpha)
            tp, fn, fp = np.zeros(n_alpha, np.int64), np.full(n_alpha, all_gt.size), np.full(n_alpha, all_hyp.size)
            return self._make(tp, fn, fp, zeros, zeros, zeros, zeros)
        n_hyp_ids = np.int64(hyp_ids.size)
        gt_count = np.bincount(np.searchsorted(gt_ids, all_gt), minlength=gt_ids.size).astype(np.float64)
        hyp_count = np.bincount(np.searchsorted(hyp_ids, all_hyp), minlength=hyp_ids.size).astype(np.float64)

        # 1. Global alignment of every (GT ID, hypothesis ID) pair that shares a frame. Pairs are
        # keyed gt_index * n_hyp_ids + hyp_index; `pair` maps each frame's N*M entries to a key.
        keys, sim_iou = [], []
        for gt, hyp, sim in frames:
            gi, hi = np.searchsorted(gt_ids, gt), np.searchsorted(hyp_ids, hyp)
            keys.append((gi[:, None] * n_hyp_ids + hi[None, :]).reshape(-1))
            denom = sim.sum(0)[None, :] + sim.sum(1)[:, None] - sim
            s = np.zeros_like(sim)
            mask = denom > 0 + _EPS
            s[mask] = sim[mask] / denom[mask]
            sim_iou.append(s.reshape(-1))
        pair_keys, pair = np.unique(np.concatenate(keys), return_inverse=True)
        pair = pair.reshape(-1)
        potential = np.bincount(pair, weights=np.concatenate(sim_iou), minlength=pair_keys.size)
        pair_gt_count = gt_count[pair_keys // n_hyp_ids]
        pair_hyp_count = hyp_count[pair_keys % n_hyp_ids]
        alignment = potential / (pair_gt_count + pair_hyp_count - potential)

        # 2. Per frame, one assignment maximising alignment * similarity; its pairs are true
        # positives at the alphas their similarity reaches (all frames thresholded at once).
        assigned_sim: list[NDArray[np.float64]] = []
        assigned_pair: list[NDArray[np.intp]] = []
        start = 0
        for _, _, sim in frames:
            n, m = sim.shape
            if n == 0 or m == 0:
                continue
            frame_pair = pair[start : start + n * m].reshape(n, m)
            start += n * m
            rows, cols = linear_sum_assignment(-(alignment[frame_pair] * sim))
            assigned_sim.append(sim[rows, cols])
            assigned_pair.append(frame_pair[rows, cols])
        a_sim = np.concatenate(assigned_sim) if assigned_sim else np.empty(0)
        a_pair = np.concatenate(assigned_pair) if assigned_pair else np.empty(0, dtype=np.intp)
        hit = a_sim[None, :] >= self.alphas[:, None] - _EPS  # (alphas, assigned pairs)
        tp = hit.sum(axis=1).astype(np.int64)
        fn = all_gt.size - tp
        fp = all_hyp.size - tp
        loc = (hit * a_sim[None, :]).sum(axis=1)

        # 3. Association: per alpha, TPA of each pair and its A(c), summed over the true positives
        # (kept sparse: only the (alpha, pair) combinations that have true positives).
        a_idx, k_idx = np.nonzero(hit)
        tpa_keys, tpa = np.unique(a_idx * np.int64(pair_keys.size) + a_pair[k_idx], return_counts=True)
        tpa_alpha, tpa_pair = tpa_keys // pair_keys.size, tpa_keys % pair_keys.size
        c = tpa.astype(np.float64)
        g_count, h_count = pair_gt_count[tpa_pair], pair_hyp_count[tpa_pair]

        def per_alpha(values: NDArray[np.float64]) -> NDArray[np.float64]:
            return np.bincount(tpa_alpha, weights=values, minlength=n_alpha)

        ass = per_alpha(c * c / np.maximum(1.0, g_count + h_count - c))
        ass_re = per_alpha(c * c / np.maximum(1.0, g_count))
        ass_pr = per_alpha(c * c / np.maximum(1.0, h_count))
        return self._make(tp, fn, fp, ass, ass_re, ass_pr, loc)

    def _make(self, tp: NDArray[np.int64], fn: NDArray[np.int64], fp: NDArray[np.int64], ass: NDArray[np.float64],
              ass_re: NDArray[np.float64], ass_pr: NDArray[np.float64], loc: NDArray[np.float64]) -> Hota:
        return Hota(alphas=tuple(self.alphas.tolist()), tp=tuple(int(x) for x in tp), fn=tuple(int(x) for x in fn),
                    fp=tuple(int(x) for x in fp), ass_sum=tuple(ass.tolist()), ass_re_sum=tuple(ass_re.tolist()),
                    ass_pr_sum=tuple(ass_pr.tolist()), loc_sum=tuple(loc.tolist()))


def evaluate_hota(frames: Iterable[tuple[ArrayLike, ArrayLike, ArrayLike | None]],
                  alphas: ArrayLike = HOTA_ALPHAS) -> Hota:
    """Run :class:`HotaAccumulator` over (gt_ids (N,), hyp_ids (M,), similarity (N, M)) frames."""
    acc = HotaAccumulator(alphas)
    for gt_ids, hyp_ids, similarity in frames:
        acc.update(gt_ids, hyp_ids, similarity)
    return acc.result()


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

