"""Gradient-boosted decision trees for a yes/no question, in numpy: trained here, read from JSON.

Trees of a fixed depth, grown level by level on binned features with Newton steps of the
logistic loss (as XGBoost and LightGBM grow theirs), then a Platt scaling fitted on
out-of-fold margins so that the output is a calibrated probability. Training is deterministic:
the same data gives the same model to the bit (quantile bins, sequential sums, no sampling).
Prediction walks every tree at once, one gather per level.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import expit

__all__ = ["BoostParams", "Boosted", "train"]


@dataclass(frozen=True)
class BoostParams:
    rounds: int = 400
    depth: int = 3
    rate: float = 0.05
    bins: int = 64
    l2: float = 1.0
    min_hessian: float = 1.0
    #: positives' weight, against 1 for a negative (0: balance the classes' total weights)
    positive_weight: float = 0.0
    folds: int = 4


@dataclass(frozen=True)
class Boosted:
    """``feature``/``threshold`` (T, 2^depth - 1): each inner node goes right when
    ``x[feature] > threshold``; ``leaf`` (T, 2^depth); ``margin = base + sum of leaves``;
    ``P = sigmoid(platt[0] * margin + platt[1])``."""

    feature: np.ndarray
    threshold: np.ndarray
    leaf: np.ndarray
    base: float
    platt: tuple[float, float] = (1.0, 0.0)

    @property
    def depth(self) -> int:
        return int(np.log2(self.leaf.shape[1]))

    def margin(self, x: np.ndarray) -> np.ndarray:
        n, t = len(x), len(self.leaf)
        if n == 0:
            return np.zeros(0)
        trees = np.arange(t)[None, :]
        rows = np.arange(n)[:, None]
        node = np.zeros((n, t), np.int64)
        for _ in range(self.depth):
            go_right = x[rows, self.feature[trees, node]] > self.threshold[trees, node]
            node = 2 * node + 1 + go_right
        return self.base + self.leaf[trees, node - (self.leaf.shape[1] - 1)].sum(axis=1)

    def log_odds(self, x: np.ndarray) -> np.ndarray:
        """The calibrated log-odds (no ties where the probability rounds to 1)."""
        a, b = self.platt
        return a * self.margin(x) + b

    def probability(self, x: np.ndarray) -> np.ndarray:
        return expit(self.log_odds(x))

    def to_json(self) -> dict[str, object]:
        return {"depth": self.depth, "base": self.base, "platt": list(self.platt),
                "feature": self.feature.tolist(), "threshold": self.threshold.tolist(), "leaf": self.leaf.tolist()}

    @classmethod
    def from_json(cls, d: dict[str, object]) -> Boosted:
        feature = np.asarray(d["feature"], np.int64)
        threshold = np.asarray(d["threshold"], np.float64)
        leaf = np.asarray(d["leaf"], np.float64)
        depth = int(d["depth"])  # type: ignore[call-overload]
        if feature.ndim != 2 or feature.shape != threshold.shape or feature.shape[1] != 2 ** depth - 1 \
                or leaf.shape != (feature.shape[0], 2 ** depth):
            raise ValueError(f"inconsistent tree arrays: feature {feature.shape}, threshold {threshold.shape}, "
                             f"leaf {leaf.shape} for depth {depth}")
        platt = tuple(float(v) for v in d.get("platt", (1.0, 0.0)))  # type: ignore[attr-defined]
        return cls(feature, threshold, leaf, float(d["base"]), (platt[0], platt[1]))  # type: ignore[arg-type]


def _edges(x: np.ndarray, bins: int) -> list[np.ndarray]:
    """Per feature, the split candidates: the distinct quantiles of its values."""
    q = np.linspace(0, 1, bins + 1)[1:-1]
    return [np.unique(np.quantile(col, q, method="lower")) for col in x.T]


def _histograms(codes_t: np.ndarray, slot: np.ndarray, rows: np.ndarray | None, g: np.ndarray, h: np.ndarray,
                width: int, nb: int) -> tuple[np.ndarray, np.ndarray]:
    """(F, width, nb) sums of ``g`` and ``h`` by node slot and bin, over ``rows`` (None: all)."""
    if rows is not None:
        codes_t, slot, g, h = codes_t[:, rows], slot[rows], g[rows], h[rows]
    base = slot * nb
    hg = np.stack([np.bincount(base + c, g, width * nb) for c in codes_t])
    hh = np.stack([np.bincount(base + c, h, width * nb) for c in codes_t])
    return hg.reshape(len(codes_t), width, nb), hh.reshape(len(codes_t), width, nb)


def _grow(codes_t: np.ndarray, edges: list[np.ndarray], g: np.ndarray, h: np.ndarray,
          p: BoostParams) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One tree: (feature, threshold, leaf values) for the gradients ``g`` and hessians ``h``
    (``codes_t`` (F, N): each feature's bin codes). Below the root only the left children's
    histograms are summed; the right ones are their parent's less them (LightGBM's trick)."""
    f, n = codes_t.shape
    inner = 2 ** p.depth - 1
    feature, threshold = np.zeros(inner, np.int64), np.full(inner, np.inf)
    split = np.full(inner, 1 << 30, np.int64)  # each node's bin: right when the code is above
    node = np.zeros(n, np.int64)
    nb = p.bins
    hg = hh = np.zeros(0)
    for level in range(p.depth):
        first, width = 2 ** level - 1, 2 ** level
        local = node - first
        if level == 0:
            hg, hh = _histograms(codes_t, local, None, g, h, 1, nb)
        else:
            lg, lh = _histograms(codes_t, local // 2, np.flatnonzero(local % 2 == 0), g, h, width // 2, nb)
            pg, ph = hg, hh
            hg, hh = np.empty((f, width, nb)), np.empty((f, width, nb))
            hg[:, 0::2], hg[:, 1::2] = lg, pg - lg
            hh[:, 0::2], hh[:, 1::2] = lh, ph - lh
        cg, ch = hg.cumsum(axis=2), hh.cumsum(axis=2)
        tg, th = cg[:, :, -1:], ch[:, :, -1:]
        rg, rh = tg - cg, th - ch
        gain = cg ** 2 / (ch + p.l2) + rg ** 2 / (rh + p.l2) - tg ** 2 / (th + p.l2)
        gain[(ch < p.min_hessian) | (rh < p.min_hessian)] = -np.inf
        for k in range(width):
            j, b = np.unravel_index(np.argmax(gain[:, k, :]), (f, nb))
            if gain[j, k, b] > 1e-12 and b < len(edges[j]):
                feature[first + k], threshold[first + k], split[first + k] = j, edges[j][b], b
        node = 2 * node + 1 + (codes_t[feature[node], np.arange(n)] > split[node])
    leaves = node - inner
    lg = np.bincount(leaves, g, inner + 1)
    lh = np.bincount(leaves, h, inner + 1)
    return feature, threshold, -p.rate * lg / (lh + p.l2)


def _codes(x: np.ndarray, edges: list[np.ndarray]) -> np.ndarray:
    """(F, N): each feature's bin codes (code c: edges[c - 1] < x <= edges[c])."""
    return np.stack([np.searchsorted(e, col, side="left") for e, col in zip(edges, x.T)]).astype(np.int64)


def _boost(x: np.ndarray, y: np.ndarray, w: np.ndarray, p: BoostParams) -> Boosted:
    edges = _edges(x, p.bins)
    codes = _codes(x, edges)
    prior = float(np.sum(w * y) / np.sum(w))
    base = float(np.log(prior / (1 - prior)))
    margin = np.full(len(y), base)
    trees = []
    for _ in range(p.rounds):
        prob = expit(margin)
        feature, threshold, leaf = _grow(codes, edges, w * (prob - y), w * prob * (1 - prob), p)
        trees.append((feature, threshold, leaf))
        model = Boosted(feature[None], threshold[None], leaf[None], 0.0)
        margin = margin + model.margin(x)
    feats, thrs, leaves = (np.stack(a) for a in zip(*trees))
    return Boosted(feats, thrs, leaves, base)


def _platt(m: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """Platt's scaling: the a, b of P = sigmoid(a m + b) that fit ``y`` best (Newton steps), on
    Platt's smoothed targets, which keep a and b finite when the margins separate the classes."""
    pos = y.sum()
    y = np.where(y > 0, (pos + 1) / (pos + 2), 1 / (len(y) - pos + 2))
    a, b = 1.0, 0.0
    for _ in range(50):
        prob = expit(a * m + b)
        r, s = prob - y, np.maximum(prob * (1 - prob), 1e-12)
        grad = np.array([np.dot(r, m), r.sum()])
        hess = np.array([[np.dot(s, m * m), np.dot(s, m)], [np.dot(s, m), s.sum()]]) + 1e-9 * np.eye(2)
        step = np.linalg.solve(hess, grad)
        a, b = a - step[0], b - step[1]
        if np.abs(step).max() < 1e-10:
            break
    return float(a), float(b)


def _folds(y: np.ndarray, k: int) -> np.ndarray:
    """Each row's fold: contiguous blocks of each class (neighbouring scans look alike, so
    interleaved folds would calibrate on near copies of the training rows)."""
    fold = np.zeros(len(y), np.int64)
    for c in (0.0, 1.0):
        rows = np.flatnonzero(y == c)
        fold[rows] = np.arange(len(rows)) * k // max(len(rows), 1)
    return fold


def train(x: np.ndarray, y: np.ndarray, p: BoostParams = BoostParams()) -> Boosted:
    """Boosted trees for ``x`` (N, F) -> ``y`` (N,) in {0, 1}, calibrated on out-of-fold
    margins."""
    x, y = np.asarray(x, np.float64), np.asarray(y, np.float64)
    pos = y.sum()
    if pos == 0 or pos == len(y):
        raise ValueError("training needs both positives and negatives")
    wp = p.positive_weight or (len(y) - pos) / pos
    w = np.where(y > 0, wp, 1.0)
    fold = _folds(y, p.folds)
    oof = np.zeros(len(y))
    for k in range(p.folds):
        test = fold == k
        oof[test] = _boost(x[~test], y[~test], w[~test], p).margin(x[test])
    model = _boost(x, y, w, p)
    return Boosted(model.feature, model.threshold, model.leaf, model.base, _platt(oof, y))
