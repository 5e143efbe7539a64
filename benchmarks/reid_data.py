"""Re-ID evaluation for the embedder benchmark: labelled crops and rank-1 / mAP / AUC.

* :func:`pets_crops`: ground-truth person crops of ``pets09_dev`` (``conf = 1`` rows,
  boxes scaled by 0.625 to the 480x360 frames), every ``step``-th frame.
* :func:`sim_crops`: people rendered by the simulated apartment with their depth, each
  box the bounding box of the person's visible pixels widened as a detector's box is.
* :func:`reid_scores`: each crop queries all others; a same-person crop taken less than
  ``min_gap_s`` apart is neither a positive nor a negative (junk, as in Market-1501),
  so an easy neighbouring frame cannot make a descriptor look good. rank-1 and mAP over
  the queries that have a positive; pair AUC over the same-person pairs ``>= min_gap_s``
  apart against all different-person pairs.
* :func:`hsv_stripes_anchor`: the reference hand-made descriptor (6 horizontal stripes,
  8x4x4 HSV histograms, Bhattacharyya distance averaged over the stripes).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from common.runtime.progress import progress

__all__ = ["Crops", "ReidScores", "bhattacharyya_matrix", "euclidean_matrix", "hsv_stripes_anchor", "pets_crops",
           "reid_scores", "sim_crops"]

PETS_GT_SCALE = 0.625


@dataclass
class Crops:
    """Labelled crops: ``images`` list of (h, w, 3) uint8 RGB, ``ids`` (N,), ``times_s`` (N,),
    ``depths`` list of (h, w) float32 metres (0 = no depth) or None."""

    images: list[np.ndarray]
    ids: np.ndarray
    times_s: np.ndarray
    depths: list[np.ndarray] | None = None


@dataclass(frozen=True)
class ReidScores:
    rank1: float
    mAP: float
    auc: float
    queries: int


def pets_crops(root: Path, step: int = 5, fps: float = 10.0) -> Crops:
    """Ground-truth crops of every ``step``-th frame of ``root`` (a ``pets09_dev`` folder).

    On a terminal a bar counts the frames read."""
    gt = np.loadtxt(root / "gt.txt", delimiter=",", ndmin=2)
    gt = gt[gt[:, 6] > 0]
    images, ids, times = [], [], []
    frames = [f for f in np.unique(gt[:, 0]).astype(int).tolist() if (f - 1) % step == 0]
    for frame in progress(frames, total=len(frames), desc="pets09 crops", unit="frame"):
        path = root / "frames" / f"frame_{frame:04d}.jpg"
        bgr = cv2.imread(str(path))
        if bgr is None:
            continue
        rgb = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
        h, w = rgb.shape[:2]
        for r in gt[gt[:, 0] == frame]:
            x0, y0 = r[2] * PETS_GT_SCALE, r[3] * PETS_GT_SCALE
            x1, y1 = x0 + r[4] * PETS_GT_SCALE, y0 + r[5] * PETS_GT_SCALE
            c0, r0, c1, r1 = int(max(x0, 0)), int(max(y0, 0)), int(min(np.ceil(x1), w)), int(min(np.ceil(y1), h))
            if c1 - c0 < 4 or r1 - r0 < 8:
                continue
            images.append(rgb[r0:r1, c0:c1].copy())
            ids.append(int(r[1]))
            times.append((frame - 1) / fps)
    return Crops(images, np.asarray(ids), np.asarray(times, np.float64))


def sim_crops(scenario: str = "changing-clothes-out-of-view", seconds: float = 30.0, fps: float = 2.0,
              seed: int = 0, min_visible: float = 0.6, pad: float = 0.15) -> Crops:
    """People of a simulated scenario with their depth; one crop per visible person and frame.

    The box is the bounding box of the person's visible pixels, widened by ``pad`` of its
    width on each side and of its height at the top (a detector's box holds background).
    An identity is the person *and* their outfit, so a change of clothes is a new identity.
    On a terminal a bar counts the frames rendered.
    """
    from tools.simulator.core.render import default_camera
    from tools.simulator.core.scenarios import build_world
    from tools.simulator.core.simulation import Simulation

    sim = Simulation(build_world(scenario, seed=seed), default_camera(), fps=fps, seed=seed)
    images, depths, ids, times = [], [], [], []
    n = int(seconds * fps)
    for seq in progress(range(n), total=n, desc=f"sim {scenario}", unit="frame"):
        fr = sim.frame(seq)
        owner = fr.render.owner
        depth = fr.render.depth_mm.astype(np.float32) * np.float32(1e-3)
        for k, person in enumerate(fr.people):
            if person.visible_fraction < min_visible:
                continue
            ys, xs = np.nonzero(owner == k)
            if len(ys) < 200:
                continue
            bw, bh = xs.max() - xs.min() + 1, ys.max() - ys.min() + 1
            h, w = owner.shape
            c0, c1 = int(max(xs.min() - pad * bw, 0)), int(min(xs.max() + 1 + pad * bw, w))
            r0, r1 = int(max(ys.min() - pad * bh, 0)), int(min(ys.max() + 1, h))
            images.append(fr.render.rgb[r0:r1, c0:c1].copy())
            depths.append(depth[r0:r1, c0:c1].copy())
            ids.append(person.id * 100 + person.outfit)
            times.append(fr.t)
    return Crops(images, np.asarray(ids), np.asarray(times, np.float64), depths)


def euclidean_matrix(a: np.ndarray) -> np.ndarray:
    """(N, N) Euclidean distances of (N, D) rows."""
    a = np.asarray(a, np.float64)
    sq = np.sum(a * a, axis=1)
    return np.sqrt(np.maximum(sq[:, None] + sq[None] - 2.0 * a @ a.T, 0.0))


def bhattacharyya_matrix(hists: np.ndarray) -> np.ndarray:
    """(N, N) Bhattacharyya distance sqrt(1 - BC) of (N, S, B) per-stripe histograms, averaged over S."""
    r = np.sqrt(np.asarray(hists, np.float64))
    bc = np.einsum("isb,jsb->ijs", r, r)
    return np.sqrt(np.clip(1.0 - bc, 0.0, None)).mean(axis=2)


def hsv_stripes_anchor(crops: list[np.ndarray], stripes: int = 6, bins: tuple[int, int, int] = (8, 4, 4)) -> np.ndarray:
    """(N, stripes, prod(bins)) normalised HSV histograms of horizontal stripes of each (h, w, 3) RGB crop."""
    out = np.zeros((len(crops), stripes, int(np.prod(bins))), np.float64)
    for i, crop in enumerate(crops):
        hsv = cv2.cvtColor(cv2.resize(crop, (32, 96), interpolation=cv2.INTER_AREA), cv2.COLOR_RGB2HSV)
        for s in range(stripes):
            part = np.ascontiguousarray(hsv[s * 96 // stripes:(s + 1) * 96 // stripes])
            h = cv2.calcHist([part], [0, 1, 2], None, list(bins), [0, 180, 0, 256, 0, 256]).ravel()
            out[i, s] = h / max(h.sum(), 1e-12)
    return out


def reid_scores(dist: np.ndarray, ids: np.ndarray, times_s: np.ndarray, min_gap_s: float = 5.0) -> ReidScores:
    """rank-1, mAP and pair AUC of an (N, N) distance matrix (see the module docstring)."""
    d = np.asarray(dist, np.float64)
    ids, times_s = np.asarray(ids), np.asarray(times_s, np.float64)
    same = ids[:, None] == ids[None]
    far = np.abs(times_s[:, None] - times_s[None]) >= min_gap_s
    positive = same & far
    valid = ~same | far
    np.fill_diagonal(valid, False)
    rank1, aps = [], []
    for q in range(len(d)):
        if not positive[q].any():
            continue
        cand = np.flatnonzero(valid[q])
        order = cand[np.argsort(d[q, cand], kind="stable")]
        hits = positive[q, order]
        rank1.append(bool(hits[0]))
        ranks = np.flatnonzero(hits) + 1
        aps.append(float(np.mean(np.arange(1, len(ranks) + 1) / ranks)))
    iu = np.triu_indices(len(d), 1)
    pos = d[iu][positive[iu]]
    neg = np.sort(d[iu][~same[iu]])
    auc = float(np.mean(len(neg) - np.searchsorted(neg, pos, side="right")) / len(neg)) if len(pos) and len(neg) \
        else float("nan")
    return ReidScores(float(np.mean(rank1)) if rank1 else float("nan"), float(np.mean(aps)) if aps else float("nan"),
                      auc, len(aps))
