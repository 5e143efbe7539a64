"""Bounded appearance galleries (Pinto's track gallery, with the TU Ilmenau framework's bound).

A :class:`Gallery` holds at most ``capacity`` descriptors (500 by default, as TU Ilmenau's sample
sets). A full one prunes the older of the two most similar among the stored ones and the new one:
redundant samples go first, the newest appearance is always kept. The closest pair costs O(n * D)
per insertion by keeping every stored descriptor's nearest neighbour, from when the gallery fills
up (before, an insertion is a plain copy). :meth:`Gallery.copy` is copy-on-write: a tracker's
snapshot costs almost nothing.
"""

from __future__ import annotations

import numpy as np

__all__ = ["Gallery", "pairwise_sq_distances"]


def pairwise_sq_distances(a: np.ndarray, b: np.ndarray, b_sq: np.ndarray | None = None) -> np.ndarray:
    """Squared Euclidean distances (N, M) between rows of ``a`` (N, D) and ``b`` (M, D):
    ``|a|^2 + |b|^2 - 2 a.b`` (one matrix product), clipped at 0."""
    a_sq = np.einsum("ij,ij->i", a, a)
    if b_sq is None:
        b_sq = np.einsum("ij,ij->i", b, b)
    d2 = a_sq[:, None] + b_sq[None, :] - 2.0 * (b @ a.T).T  # (M, D) @ (D, N): BLAS's fast layout
    return np.maximum(d2, 0.0, out=d2)


class Gallery:
    """At most ``capacity`` descriptors of dimension ``dim`` (float32)."""

    def __init__(self, dim: int, capacity: int = 500, prune: str = "closest_pair") -> None:
        if dim <= 0 or capacity <= 0:
            raise ValueError(f"dim and capacity must be positive, got {dim}, {capacity}")
        if prune not in ("closest_pair", "nearest"):
            raise ValueError(f"prune must be 'closest_pair' or 'nearest', got {prune!r}")
        self.dim = dim
        self.capacity = capacity
        #: which descriptor a full gallery drops for a new one: the older of the closest
        #: pair among the stored and the new one (Pinto and TU Ilmenau), or the stored one nearest
        #: to the new one (no neighbour bookkeeping: one matrix-vector product per insertion)
        self.prune = prune
        self.n = 0
        self._counter = 0
        size = min(capacity, 16)
        self._data = np.empty((size, dim), np.float32)
        self._sq = np.empty(size, np.float32)
        self._age = np.empty(size, np.int64)
        self._nn_d = np.empty(size, np.float32)
        self._nn_j = np.empty(size, np.int64)
        self._shared = False

    # ------------------------------------------------------------------ queries
    def __len__(self) -> int:
        return self.n

    @property
    def descriptors(self) -> np.ndarray:
        """The stored descriptors, oldest first: (n, dim) float32 (a copy)."""
        order = np.argsort(self._age[: self.n], kind="stable")
        return self._data[: self.n][order].copy()

    def sq_distances(self, x: np.ndarray) -> np.ndarray:
        """Squared Euclidean distances (N, n) from each row of ``x`` (N, dim) to every stored
        descriptor, in storage order (what :meth:`add` takes as ``d2``)."""
        x = np.asarray(x, dtype=np.float32)
        d2 = (self._sq[: self.n, None] - 2.0 * (self._data[: self.n] @ x.T)).T + np.einsum("ij,ij->i", x, x)[:, None]
        return np.maximum(d2, 0.0, out=d2)

    def min_distances(self, x: np.ndarray) -> np.ndarray:
        """Smallest Euclidean distance (N,) from each row of ``x`` (N, dim) to the gallery (``inf``
        when it is empty)."""
        x = np.asarray(x, dtype=np.float32)
        if self.n == 0:
            return np.full(len(x), np.inf)
        # min over the gallery of |g|^2 - 2 x.g, then add |x|^2: one product, one reduction
        part = (self._sq[: self.n, None] - 2.0 * (self._data[: self.n] @ x.T)).min(axis=0)
        d2 = part.astype(np.float64) + np.einsum("ij,ij->i", x, x)
        return np.sqrt(np.maximum(d2, 0.0))

    # ---------------------------------------------------------------- mutation
    def _own(self) -> None:
        """Copy the arrays if they are shared with a snapshot (copy-on-write)."""
        if self._shared:
            self._data, self._sq, self._age = self._data.copy(), self._sq.copy(), self._age.copy()
            self._nn_d, self._nn_j = self._nn_d.copy(), self._nn_j.copy()
            self._shared = False

    def _grow(self) -> None:
        size = min(self.capacity, 2 * len(self._data))
        extra = size - len(self._data)
        self._data = np.concatenate([self._data, np.empty((extra, self.dim), np.float32)])
        self._sq = np.concatenate([self._sq, np.empty(extra, np.float32)])
        self._age = np.concatenate([self._age, np.empty(extra, np.int64)])
        self._nn_d = np.concatenate([self._nn_d, np.empty(extra, np.float32)])
        self._nn_j = np.concatenate([self._nn_j, np.empty(extra, np.int64)])
        self._shared = False

    def add(self, x: np.ndarray, d2: np.ndarray | None = None) -> None:
        """Insert one descriptor ``x`` (dim,), pruning one when full; ``d2``: its squared distances to
        the stored ones (:meth:`sq_distances`) if known, saving an insertion's one product."""
        x = np.asarray(x, dtype=np.float32).reshape(self.dim)
        xx = float(x @ x)
        if not np.isfinite(xx):
            raise ValueError("descriptor has non-finite values")
        self._own()
        n = self.n
        if n < self.capacity:
            # not full: nothing to prune, so no neighbour bookkeeping until it fills up
            if n == len(self._data):
                self._grow()
            self._write(n, x, xx)
            self.n = n + 1
            if self.n == self.capacity and self.prune == "closest_pair":
                self._build_neighbours()
            return
        # full: squared distances from x to every stored descriptor (one matrix-vector product)
        if d2 is None or len(d2) != n:
            d2 = self._sq[:n] + np.float32(xx) - 2.0 * (self._data[:n] @ x)
            np.maximum(d2, 0.0, out=d2)
        if self.prune == "nearest":
            self._write(int(np.argmin(d2)), x, xx)
            return
        d2 = np.array(d2, np.float32)
        slot = self._prune_slot(d2)
        d2[slot] = np.inf
        self._write(slot, x, xx)
        self._refresh_neighbours(slot, d2)

    def _write(self, slot: int, x: np.ndarray, xx: float) -> None:
        self._data[slot] = x
        self._sq[slot] = xx
        self._age[slot] = self._counter
        self._counter += 1

    def _build_neighbours(self) -> None:
        """Nearest neighbour of every stored descriptor, from the full distance matrix."""
        n = self.n
        if n == 1:
            self._nn_d[0], self._nn_j[0] = np.inf, -1
            return
        d2 = pairwise_sq_distances(self._data[:n], self._data[:n], self._sq[:n])
        np.fill_diagonal(d2, np.inf)
        self._nn_j[:n] = d2.argmin(axis=1)
        self._nn_d[:n] = d2[np.arange(n), self._nn_j[:n]]

    def extend(self, xs: np.ndarray) -> None:
        """Insert every row of ``xs`` (M, dim), oldest first."""
        for x in np.asarray(xs, dtype=np.float32).reshape(-1, self.dim):
            self.add(x)

    def _prune_slot(self, d2_new: np.ndarray) -> int:
        """The slot to free in a full gallery: the older member of the closest pair."""
        i = int(np.argmin(self._nn_d[: self.n]))
        j_new = int(np.argmin(d2_new))
        if d2_new[j_new] <= self._nn_d[i]:
            return j_new  # the new descriptor and j_new are the closest pair; j_new is older
        j = int(self._nn_j[i])
        return i if self._age[i] < self._age[j] else j

    def _refresh_neighbours(self, slot: int, d2: np.ndarray) -> None:
        """Update nearest neighbours after ``slot`` of a full gallery got a new descriptor;
        ``d2`` (n,) holds the squared distances from it to every slot (``inf`` at ``slot``)."""
        n = self.n
        if n == 1:
            self._nn_d[0], self._nn_j[0] = np.inf, -1
            return
        # rows whose nearest neighbour was the pruned descriptor need a full recompute
        stale = np.flatnonzero(self._nn_j[:n] == slot)
        stale = stale[stale != slot]
        if len(stale):
            # (n, k) squared distances from every slot to the stale rows; one product
            rows = (self._sq[:n, None] + self._sq[stale][None, :] - 2.0 * (self._data[:n] @ self._data[stale].T)).T
            np.maximum(rows, 0.0, out=rows)
            rows[np.arange(len(stale)), stale] = np.inf
            self._nn_j[stale] = rows.argmin(axis=1)
            self._nn_d[stale] = rows[np.arange(len(stale)), self._nn_j[stale]]
        closer = d2 < self._nn_d[:n]
        closer[slot] = False
        self._nn_d[:n][closer] = d2[closer]
        self._nn_j[:n][closer] = slot
        j = int(np.argmin(d2))
        self._nn_d[slot], self._nn_j[slot] = d2[j], j

    def copy(self) -> Gallery:
        """A copy that shares storage until either side is modified."""
        other = Gallery.__new__(Gallery)  # (prune and every other attribute come along)
        other.__dict__.update(self.__dict__)
        self._shared = other._shared = True
        return other

    @classmethod
    def from_descriptors(cls, xs: np.ndarray, capacity: int = 500, prune: str = "closest_pair") -> Gallery:
        """A gallery filled with the rows of ``xs`` (M, D), oldest first."""
        xs = np.asarray(xs, dtype=np.float32)
        g = cls(xs.shape[1], capacity, prune)
        g.extend(xs)
        return g
