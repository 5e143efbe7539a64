"""The laser leg detector against two anchors, with the protocol of ``data/laser_legs/README.md``.

    python benchmarks/legs.py [--data DIR] [--json FILE] [--repeat N]

Every detector is trained on the ``train`` split of the dev scans (bags 1 and 2, ``/left_scan``)
and judged on the ``test`` split (bag 3, ``/rear_scan``), deciding from the scan alone over all
270 degrees:

- ``hand-rules``: jump-distance segments (a jump over 0.1 m starts a new one) 0.05-0.35 m wide
  with at least 3 points; its score is how near its width is to 0.15 m (a leg's), so that it
  ranks at all.
- ``forest``: Leigh et al.'s leg_tracker as they built it: their clusters, their 16 features
  computed per cluster in Python (as ``cluster_features.cpp`` does, less the radius it sets to
  0) and a random forest of 100 trees of depth 20 (scikit-learn, seed 0).
- ``boosted``: this project's detector (``services/laser/core``): the same clusters, the
  features computed for all segments at once plus six of its own, 400 boosted trees of depth
  3, calibrated, trained on every scan, its mirror image and both with 1 cm of range noise; trained with ``services.laser.training`` exactly as ``perception train-legs``
  trains the shipped model, but on the train split only.

Each is judged twice: on the test scans as recorded, and with their background filled ("filled":
every beam that returned nothing reads a wall 6 m out). Most labelled legs of these recordings
have no return beside them (an open hall beyond the range) while the empty rooms have walls
everywhere, so a detector that reads a segment's surroundings (Leigh et al.'s occlusion flags,
the jumps to the neighbouring beams) learns the recording and misses a person standing in front
of a wall; the filled view shows it. This project's detector does not read them.

Reported per detector, in the "window" view (an empty scan's detections count inside the
labelled window) and the "all" view (every detection on an empty scan counts): average
precision over all labels, recall at the best F1, recall at 0.1 false legs per empty scan;
and the time a scan takes (the median over the test scans of the best of ``--repeat`` runs,
one core), with each detector's time over the boosted detector's. Needs scikit-learn for the
forest (``pip install scikit-learn``); without it that row is skipped, saying so.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path
from typing import Any, Callable, Sequence

if __name__ == "__main__":
    for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(_var, "1")

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402
from scipy.optimize import linear_sum_assignment  # noqa: E402

from services.laser import dev_data, training  # noqa: E402
from services.laser.core.legs import LegParams, detect  # noqa: E402
from services.laser.core.scan import beams  # noqa: E402
from services.laser.core.segments import segment  # noqa: E402

MATCH_M = 0.15
FALSE_PER_EMPTY = 0.1

#: A detector: a scan -> (xy (D, 2), score (D,)).
Detector = Callable[[Any], tuple[np.ndarray, np.ndarray]]


def judge(scans: Sequence[dev_data.DevScan], found: Sequence[tuple[np.ndarray, np.ndarray]]) -> dict[str, dict[str, float]]:
    """The protocol's figures, in both views."""
    out = {}
    n_labels = sum(len(d.legs) for d in scans)
    n_empty = sum(d.empty for d in scans)
    for view in ("window", "all"):
        scores, hits = [], []
        empty_scores = []
        for d, (xy, score) in zip(scans, found):
            xy = np.asarray(xy).reshape(-1, 2)
            inside = dev_data.in_window(xy)
            if d.empty:
                counted = inside if view == "window" else np.ones(len(xy), bool)
                empty_scores += list(score[counted])
                scores += list(score[counted])
                hits += [False] * int(counted.sum())
                continue
            tp = np.zeros(len(xy), bool)
            if len(xy) and len(d.legs):
                cost = np.linalg.norm(xy[:, None] - d.legs[None], axis=2)
                r, c = linear_sum_assignment(cost)
                tp[r[cost[r, c] <= MATCH_M]] = True
            counted = tp | inside
            scores += list(score[counted])
            hits += list(tp[counted])
        out[view] = _curve(np.asarray(scores), np.asarray(hits, bool), n_labels, np.asarray(empty_scores), n_empty)
    return out


def _curve(scores: np.ndarray, hits: np.ndarray, n_labels: int, empty_scores: np.ndarray,
           n_empty: int) -> dict[str, float]:
    """Precision and recall at every distinct score (tied detections pass or fail together, as
    scikit-learn's average_precision_score treats them)."""
    order = np.argsort(-scores, kind="stable")
    s, h = scores[order], hits[order]
    last = np.r_[np.flatnonzero(s[1:] != s[:-1]), len(s) - 1] if len(s) else np.zeros(0, np.int64)
    tp = np.cumsum(h)[last]
    fp = np.cumsum(~h)[last]
    recall = tp / max(n_labels, 1)
    precision = tp / np.maximum(tp + fp, 1)
    # average precision: the step sum over the distinct thresholds, over all labels
    ap = float(np.sum(np.diff(np.r_[0.0, recall]) * precision))
    f1 = 2 * precision * recall / np.maximum(precision + recall, 1e-12)
    best = int(np.argmax(f1)) if len(f1) else 0
    allowed = int(np.floor(FALSE_PER_EMPTY * n_empty))
    ranked = np.sort(empty_scores)[::-1]
    # the threshold at which the empty scans give at most `allowed` false legs
    thr = ranked[allowed] if allowed < len(ranked) else -np.inf
    rec_at = float(hits[scores > thr].sum() / n_labels) if n_labels else 0.0
    return {"ap": round(ap, 3), "recall_best_f1": round(float(recall[best]) if len(recall) else 0.0, 3),
            "recall_at_0.1_fp": round(rec_at, 3)}


# ------------------------------------------------------------------------------ anchors


def hand_rules(scan: Any) -> tuple[np.ndarray, np.ndarray]:
    b = beams(scan.ranges, training.geometry_of(scan))
    idx = np.flatnonzero(b.valid)
    if len(idx) < 3:
        return np.zeros((0, 2)), np.zeros(0)
    gap = np.hypot(np.diff(b.x[idx]), np.diff(b.y[idx])) > 0.1
    cuts = np.split(idx, np.flatnonzero(gap) + 1)
    xy, score = [], []
    for c in cuts:
        if len(c) < 3:
            continue
        width = float(np.hypot(b.x[c[0]] - b.x[c[-1]], b.y[c[0]] - b.y[c[-1]]))
        if 0.05 <= width <= 0.35:
            xy.append((b.x[c].mean(), b.y[c].mean()))
            score.append(1.0 - abs(width - 0.15) / 0.2)
    return np.asarray(xy).reshape(-1, 2), np.asarray(score)


def leigh_features(points: np.ndarray, ranges: np.ndarray, first_prev: tuple[float, float, float] | None,
                   last_next: tuple[float, float, float] | None) -> list[float]:
    """One cluster's features as Leigh et al.'s ``calcClusterFeatures`` computes them, point by
    point (``points`` (n, 2) in beam order; a neighbour is (x, y, range) or None when invalid)."""
    n = len(points)
    mean = points.mean(axis=0)
    med = np.array([np.median(points[:, 0]), np.median(points[:, 1])])
    distance = float(np.hypot(*med))
    std = float(np.sqrt(((points - mean) ** 2).sum() / (n - 1)))
    med_dev = float(np.mean(np.hypot(*(points - med).T)))
    occ_l = occ_r = 1.0
    if first_prev is not None and (ranges[0] < first_prev[2] or first_prev[2] < 0.01):
        occ_l = 0.0
    if last_next is not None and (ranges[-1] < last_next[2] or last_next[2] < 0.01):
        occ_r = 0.0
    width = float(np.hypot(*(points[0] - points[-1])))
    centred = points - mean
    sv = np.linalg.svd(centred, compute_uv=False)
    linearity = float(sv[-1] ** 2) if len(sv) > 1 else 0.0
    a = np.column_stack([-2 * points, np.ones(n)])
    sol = np.linalg.lstsq(a, -(points ** 2).sum(axis=1), rcond=None)[0]
    rc = float(np.sqrt(max(sol[0] ** 2 + sol[1] ** 2 - sol[2], 0.0)))
    circularity = float(((rc - np.hypot(*(points - sol[:2]).T)) ** 2).sum())
    length = sq = curv = ang = 0.0
    last_seg = 0.0
    for k in range(n - 2):
        right, mid, left = points[k], points[k + 1], points[k + 2]
        ml, mr, lr = left - mid, right - mid, left - right
        l_ml, l_mr, l_lr = np.hypot(*ml), np.hypot(*mr), np.hypot(*lr)
        length += l_mr
        sq += l_mr ** 2
        last_seg = l_ml
        th = np.arctan2(ml[0] * mr[1] - ml[1] * mr[0], ml @ mr)
        th = th + 2 * np.pi if th < 0 else th
        ang += th / n
        s = 0.5 * (l_ml + l_mr + l_lr)
        area = np.sqrt(max(s * (s - l_ml) * (s - l_mr) * (s - l_lr), 0.0))
        c = 4 * area / max(l_ml * l_mr * l_lr * n, 1e-12)
        curv += c if th > 0 else -c
    length += last_seg
    sq += last_seg ** 2
    regularity = float(np.sqrt(max(sq - length ** 2 / n, 0.0) / (n - 1)))
    s_iav = s_iav2 = 0.0
    for k in range(1, n - 1):
        ml, mr = points[0] - points[k], points[-1] - points[k]
        th = np.arctan2(ml[0] * mr[1] - ml[1] * mr[0], ml @ mr)
        th = th + 2 * np.pi if th < 0 else th
        s_iav += th
        s_iav2 += th * th
    iav = s_iav / n
    std_iav = float(np.sqrt(max(s_iav2 - s_iav ** 2 / n, 0.0) / (n - 1)))
    return [n, std, med_dev, width, linearity, circularity, length, regularity, curv, ang, iav, std_iav,
            distance, distance / n, occ_r, occ_l]


def forest_clusters(scan: Any) -> tuple[np.ndarray, np.ndarray]:
    """(features (C, 16), centres (C, 2)) of a scan's clusters, one cluster at a time."""
    b = beams(scan.ranges, training.geometry_of(scan))
    seg = segment(b)
    rows, centres = [], []
    for s in range(len(seg)):
        idx = seg.beams_of(s)
        pts = np.column_stack([b.x[idx], b.y[idx]])
        nb = []
        for j in (idx[0] - 1, idx[-1] + 1):
            nb.append((b.x[j], b.y[j], b.ranges[j]) if 0 <= j < len(b) and b.valid[j] else None)
        rows.append(leigh_features(pts, b.ranges[idx], nb[0], nb[1]))
        centres.append(pts.mean(axis=0))
    return np.asarray(rows).reshape(-1, 16), np.asarray(centres).reshape(-1, 2)


def forest_detector(train_scans: Sequence[dev_data.DevScan]) -> Detector | None:
    try:
        from sklearn.ensemble import RandomForestClassifier
    except ImportError:
        print("forest: skipped (scikit-learn is not installed: pip install scikit-learn)")
        return None
    xs, ys = [], []
    for d in train_scans:
        x, c = forest_clusters(d.scan)
        if not len(x):
            continue
        if d.empty:
            xs.append(x)
            ys.append(np.zeros(len(x)))
        elif len(d.legs):
            near = np.linalg.norm(c[:, None] - d.legs[None], axis=2).min(axis=1) < training.LABEL_MATCH_M
            xs.append(x[near])
            ys.append(np.ones(int(near.sum())))
    forest = RandomForestClassifier(n_estimators=100, max_depth=20, random_state=0, n_jobs=1)
    forest.fit(np.concatenate(xs), np.concatenate(ys))

    def run(scan: Any) -> tuple[np.ndarray, np.ndarray]:
        x, c = forest_clusters(scan)
        return (c, forest.predict_proba(x)[:, 1]) if len(x) else (c, np.zeros(0))

    return run


def boosted_detector(folder: Path) -> Detector:
    model, _ = training.train_model(folder, "train")
    p = LegParams(min_probability=0.0)

    def run(scan: Any) -> tuple[np.ndarray, np.ndarray]:
        legs = detect(scan.ranges, training.geometry_of(scan), model, p)
        return legs.xy, legs.log_odds

    return run


def filled(scans: Sequence[dev_data.DevScan]) -> list[dev_data.DevScan]:
    """``scans`` with every beam that returned nothing reading a wall 6 m out."""
    out = []
    for d in scans:
        s = d.scan
        r = s.ranges.copy()
        r[~(np.isfinite(r) & (r > s.range_min) & (r < s.range_max))] = 6.0
        out.append(dev_data.DevScan(s.model_copy(update={"ranges": r}), d.legs, d.empty, d.part))
    return out


def timed(det: Detector, scans: Sequence[dev_data.DevScan], repeat: int) -> tuple[list[tuple[np.ndarray, np.ndarray]], float]:
    found, times = [], []
    for d in scans:
        best = np.inf
        for _ in range(repeat):
            t0 = time.perf_counter()
            out = det(d.scan)
            best = min(best, time.perf_counter() - t0)
        found.append(out)
        times.append(best)
    return found, float(np.median(times) * 1e3)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, default=Path(os.environ.get("PERCEPTION_SHARED_DATA", ROOT.parent / "shared" / "data")))
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)
    folder = args.data / "laser_legs"
    if not folder.is_dir():
        print(f"no dev scans at {folder}: give --data (the folder holding laser_legs/)", file=sys.stderr)
        return 2
    train_scans, test_scans = dev_data.load(folder, "train"), dev_data.load(folder, "test")
    wall_scans = filled(test_scans)
    detectors: dict[str, Detector | None] = {"hand-rules": hand_rules, "forest": forest_detector(train_scans),
                                             "boosted": boosted_detector(folder)}
    rows: dict[str, dict[str, Any]] = {}
    for name, det in detectors.items():
        if det is None:
            continue
        found, ms = timed(det, test_scans, args.repeat)
        rows[name] = {**judge(test_scans, found), "ms_per_scan": round(ms, 3)}
        in_room = judge(wall_scans, [det(d.scan) for d in wall_scans])
        rows[name].update({"filled " + view: v for view, v in in_room.items()})
    base = rows["boosted"]["ms_per_scan"]
    print(f"{'detector':<11} {'view':<13} {'AP':>6} {'R@F1':>6} {'R@0.1':>6}  ms/scan  x boosted")
    for name, r in rows.items():
        r["time_over_boosted"] = round(r["ms_per_scan"] / base, 2)
        for view in ("window", "all", "filled window", "filled all"):
            v = r[view]
            tail = f"  {r['ms_per_scan']:7.3f}  {r['time_over_boosted']:5.2f}" if view == "window" else ""
            print(f"{name:<11} {view:<13} {v['ap']:6.3f} {v['recall_best_f1']:6.3f} {v['recall_at_0.1_fp']:6.3f}{tail}")
    if args.json:
        args.json.write_text(json.dumps(rows, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
