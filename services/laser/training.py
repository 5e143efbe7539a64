"""Train the leg classifier from labelled scans: ``perception train-legs`` and the benchmark.

A positive is a segment whose centre is a labelled leg; a negative is any segment of an empty
room. Segments of labelled scans that carry no label are left out: outside the labelled window
nothing is known of them. Every scan is used four times: as recorded, mirrored (``dev_data.mirrored``),
and both again with 1 cm of range noise (``dev_data.noisy``), so that the classifier holds on
scanners noisier than the one that recorded the dev scans.
"""

from __future__ import annotations

from dataclasses import asdict
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from services.laser.core.boost import Boosted, BoostParams, train
from services.laser.core.features import MODEL, MODEL_COLUMNS, features
from services.laser.core.legs import LegParams
from services.laser.core.scan import ScanGeometry, beams
from services.laser.core.segments import centres, segment
from services.laser.dev_data import DevScan, files_digest, load, mirrored, noisy

__all__ = ["augmented", "geometry_of", "samples", "train_model"]

#: how near a segment's centre must lie to a label to be that label (the labels are the same
#: clusters' centres, to float precision)
LABEL_MATCH_M = 0.01


#: the range noise of the noisy copies (m)
NOISE_M = 0.01


def augmented(scans: list[DevScan]) -> list[DevScan]:
    """``scans``, their mirror images, and both with :data:`NOISE_M` of noise (seeded by position)."""
    both = scans + [mirrored(d) for d in scans]
    return both + [noisy(d, NOISE_M, k) for k, d in enumerate(both)]


def geometry_of(scan: Any) -> ScanGeometry:
    return ScanGeometry(scan.angle_min, scan.angle_increment, scan.range_min, scan.range_max)


def samples(scans: Sequence[DevScan], p: LegParams = LegParams()) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(X, y, group): the features of every segment that has a known class, its class, and the
    index of the part (file and topic) it came from."""
    xs, ys, gs = [], [], []
    parts: dict[str, int] = {}
    for d in scans:
        b = beams(d.scan.ranges, geometry_of(d.scan))
        seg = segment(b, p.join_m, p.min_points)
        x = features(b, seg)
        if not len(x):
            continue
        centre = centres(b, seg)
        if d.empty:
            y = np.zeros(len(x))
            keep = np.ones(len(x), bool)
        else:
            near = np.linalg.norm(centre[:, None] - d.legs[None], axis=2).min(axis=1) if len(d.legs) else np.full(len(x), np.inf)
            y = (near < LABEL_MATCH_M).astype(np.float64)
            keep = y > 0
        xs.append(x[keep])
        ys.append(y[keep])
        gs.append(np.full(int(keep.sum()), parts.setdefault(d.part, len(parts))))
    return np.concatenate(xs), np.concatenate(ys), np.concatenate(gs)


def train_model(folder: Path, split: str = "all", boost: BoostParams = BoostParams(),
                p: LegParams = LegParams()) -> tuple[Boosted, dict[str, Any]]:
    """The classifier trained on ``split`` of the dev data in ``folder``, and what it came from."""
    x, y, _ = samples(augmented(load(folder, split)), p)
    model = train(x[:, MODEL_COLUMNS], y, boost)
    meta = {"features": list(MODEL), "split": split, "data": files_digest(folder, split),
            "augmented": {"mirrored": True, "noise_m": NOISE_M}, "positives": int(y.sum()), "negatives": int(len(y) - y.sum()), "boost": asdict(boost),
            "segments": {"join_m": p.join_m, "min_points": p.min_points}}
    return model, meta
