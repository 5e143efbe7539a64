"""Every track's gallery in one contiguous array: :class:`GalleryBank`, the robust profile's
galleries. A gallery is Pinto's track gallery with the TU Ilmenau framework's bound: at most
``capacity`` descriptors, a full one dropping the stored descriptor nearest to the new one (as
``Gallery(prune="nearest")``, descriptor for descriptor). One batched matrix product measures every
compared (detection, track) pair against the track's whole gallery. Pure numpy.
"""

from __future__ import annotations

import bisect
from pathlib import Path

import numpy as np

__all__ = ["GalleryBank", "last_level_cache_bytes"]

#: up to this many compared pairs, :meth:`GalleryBank.pair_sq_distances` takes the galleries one by one
_FEW_PAIRS = 2


def last_level_cache_bytes(root: Path = Path("/sys/devices/system/cpu/cpu0/cache")) -> int | None:
    """The largest CPU cache's size in bytes as Linux reports it (``index*/size``, e.g. ``32768K``);
    None where it cannot be read (another system, a container that hides it)."""
    sizes = []
    for entry in root.glob("index*/size"):
        try:
            text = entry.read_text().strip().upper()
            scale = {"K": 1 << 10, "M": 1 << 20, "G": 1 << 30}.get(text[-1:], 1)
            sizes.append(int(text.rstrip("KMG")) * scale)
        except (OSError, ValueError):
            continue
    return max(sizes) if sizes else None


#: above this many bytes of galleries (half the last-level cache, which the galleries share with
#: everything else: they no longer stay in it from one frame to the next; 16 MiB where it is not
#: known) the product streams them through ``einsum``, which reads memory at about twice the rate
#: of the stacked ``matmul`` there (measured on a 32 MiB L3: 100 galleries of 500 128-D
#: descriptors, 24 MiB, in 0.79 ms against 1.55 ms; 60, 15 MiB, 0.39 against 0.26 ms, where
#: ``matmul`` is faster: in the cache, ``einsum`` is the slower). Read from Linux at the first
#: product, not when the module is imported.
_STREAM_BYTES: int | None = None


def _stream_bytes() -> int:
    global _STREAM_BYTES
    if _STREAM_BYTES is None:
        _STREAM_BYTES = (last_level_cache_bytes() or 32 << 20) // 2
    return _STREAM_BYTES


class GalleryBank:
    """Galleries of at most ``capacity`` descriptors each, in slots of one array: ``data`` (S, D,
    capacity) float32, a column per descriptor (the layout a vector-by-matrix product reads
    fastest), ``sq`` (S, capacity) their squared norms (``inf`` where a slot holds none, so a
    distance to it is ``inf``), ``age`` the order they came in, ``n`` (S,) how many each holds. A
    track holds a slot from its first descriptor on; a freed slot is reused. Copies share the arrays
    until either side changes them (copy-on-write): a tracker snapshot costs almost nothing."""

    def __init__(self, capacity: int) -> None:
        if capacity <= 0:
            raise ValueError(f"capacity must be positive, got {capacity}")
        self.capacity = capacity
        self.dim = 0
        self.data = np.zeros((0, 0, capacity), np.float32)
        self.sq = np.zeros((0, capacity), np.float32)
        self.age = np.zeros((0, capacity), np.int64)
        self.n = np.zeros(0, np.int64)
        self.counter = np.zeros(0, np.int64)
        self.free: list[int] = []  # ascending
        self._shared = False

    # ---------------------------------------------------------------- slots
    def check_dim(self, dim: int) -> None:
        """ValueError if descriptors of dimension ``dim`` cannot go into these galleries."""
        if self.dim and dim != self.dim:
            raise ValueError(f"descriptors of dimension {dim}, the galleries hold dimension {self.dim}")

    def allocate(self, dim: int) -> int:
        """A free slot for a gallery of ``dim``-D descriptors."""
        self.check_dim(dim)
        self._own()
        if not self.dim:
            self.dim = dim
            self.data = np.zeros((len(self.n), dim, self.capacity), np.float32)
        if not self.free:
            self._grow(max(4, 2 * len(self.n)))
        return self.free.pop(0)

    def release(self, slot: int) -> None:
        """Empty ``slot`` and make it free."""
        self._own()
        self.n[slot] = 0
        self.counter[slot] = 0
        self.sq[slot] = np.inf
        bisect.insort(self.free, slot)

    def _grow(self, size: int) -> None:
        extra = size - len(self.n)
        self.data = np.concatenate([self.data, np.zeros((extra, self.dim, self.capacity), np.float32)])
        self.sq = np.concatenate([self.sq, np.full((extra, self.capacity), np.inf, np.float32)])
        self.age = np.concatenate([self.age, np.zeros((extra, self.capacity), np.int64)])
        self.n = np.concatenate([self.n, np.zeros(extra, np.int64)])
        self.counter = np.concatenate([self.counter, np.zeros(extra, np.int64)])
        self.free.extend(range(size - extra, size))

    def _own(self) -> None:
        if self._shared:
            self.data, self.sq, self.age = self.data.copy(), self.sq.copy(), self.age.copy()
            self.n, self.counter, self.free = self.n.copy(), self.counter.copy(), list(self.free)
            self._shared = False

    def copy(self) -> GalleryBank:
        """A copy sharing the arrays until either side changes them."""
        other = GalleryBank.__new__(GalleryBank)
        other.__dict__.update(self.__dict__)
        self._shared = other._shared = True
        return other

    # -------------------------------------------------------------- queries
    def size(self, slot: int) -> int:
        return int(self.n[slot]) if slot >= 0 else 0

    def sizes(self, slots: list[int]) -> np.ndarray:
        """How many descriptors each of ``slots`` holds (0 for -1: no gallery)."""
        if not len(self.n):
            return np.zeros(len(slots), np.int64)
        s = np.asarray(slots, np.int64)
        return np.where(s >= 0, self.n[s], 0)

    def descriptors(self, slot: int) -> np.ndarray:
        """The descriptors of ``slot``, oldest first: (n, D) float32 (a copy)."""
        n = self.size(slot)
        order = np.argsort(self.age[slot, :n], kind="stable")
        return self.data[slot, :, :n].T[order].copy()

    def pair_sq_distances(self, slots: np.ndarray, x: np.ndarray) -> np.ndarray:
        """Squared Euclidean distances (P, capacity) from each descriptor ``x[p]`` (P, D) to
        every stored descriptor of gallery ``slots[p]``, in storage order (``inf`` beyond a
        gallery's descriptors): what :meth:`add_many` takes to pick the one to drop.

        A slot compared with one descriptor (the usual case) goes into one batched matrix
        product over the whole bank; a slot compared with several, into its own product."""
        x = np.asarray(x, np.float32)
        if not len(slots):
            return np.empty((0, self.capacity), np.float32)
        x_sq = np.einsum("ij,ij->i", x, x)
        listed = slots.tolist()
        if len(set(listed)) == len(listed):  # each slot once (the usual case): no masks
            out = self._distinct_products(slots, listed, x, len(listed) > _FEW_PAIRS)
        else:
            out = self._shared_products(slots, x)
        out += x_sq[:, None]
        return np.maximum(out, 0.0, out=out)

    def _distinct_products(self, slots: np.ndarray, listed: list[int], x: np.ndarray, batched: bool) -> np.ndarray:
        """``sq - 2 x . g`` (P, capacity) for distinct ``slots``: one ``batched`` product over
        the bank, else a product per slot (``inf`` past a gallery's descriptors, as ``sq`` is:
        for a few pairs this costs less than setting up the batched one)."""
        if not batched:
            out = np.empty((len(listed), self.capacity), np.float32)
            for k, slot in enumerate(listed):
                n = int(self.n[slot])
                out[k, n:] = np.inf
                out[k, :n] = self.sq[slot, :n] - 2.0 * (x[k] @ self.data[slot, :, :n])
            return out
        hi = max(listed) + 1  # slots are taken lowest first: the bank's used part
        in_order = hi == len(listed) and listed == list(range(hi))
        if in_order:
            xs = x[:, None, :]
        else:
            xs = np.zeros((hi, 1, self.dim), np.float32)
            xs[slots, 0] = x
        bank = self.data[:hi]
        if bank.nbytes > _stream_bytes():
            prod = np.einsum("sd,sdc->sc", xs[:, 0], bank)  # (hi, capacity), the galleries streamed once
        else:
            prod = np.matmul(xs, bank)[:, 0]  # (hi, capacity): one product per slot
        out = prod if in_order else prod[slots]
        out *= -2.0  # sq - 2 x . g, without temporaries
        out += self.sq[:hi] if in_order else self.sq[slots]
        return out

    def _shared_products(self, slots: np.ndarray, x: np.ndarray) -> np.ndarray:
        """As :meth:`_distinct_products` where some slot is compared with several descriptors."""
        out = np.empty((len(slots), self.capacity), np.float32)
        count = np.bincount(slots, minlength=len(self.n))
        single = count[slots] == 1
        if len(slots) <= _FEW_PAIRS:
            single[:] = False
        if single.any():
            out[single] = self._distinct_products(slots[single], slots[single].tolist(), x[single], True)
        for slot in np.flatnonzero(count > 1 if single.any() else count).tolist():
            rows, n = np.flatnonzero(slots == slot), int(self.n[slot])
            out[rows] = np.inf
            out[rows, :n] = self.sq[slot, :n] - 2.0 * (x[rows] @ self.data[slot, :, :n])
        return out

    # ------------------------------------------------------------- mutation
    def add(self, slot: int, x: np.ndarray) -> None:
        """Insert one descriptor ``x`` (D,) into ``slot``, dropping the nearest stored one when full."""
        x = np.asarray(x, np.float32).reshape(self.dim)
        xx = float(x @ x)
        if not np.isfinite(xx):
            raise ValueError("descriptor has non-finite values")
        self._own()
        n = int(self.n[slot])
        if n < self.capacity:
            self._write(np.array([slot]), np.array([n]), x[None], np.array([xx], np.float32), np.array([n + 1]))
            return
        d2 = self.sq[slot] + np.float32(xx) - 2.0 * (x @ self.data[slot])
        np.maximum(d2, 0.0, out=d2)
        self._write(np.array([slot]), np.array([int(np.argmin(d2))]), x[None], np.array([xx], np.float32),
                    np.array([n]))

    def add_many(self, slots: np.ndarray, x: np.ndarray, d2: np.ndarray | None) -> None:
        """Insert ``x[k]`` (K, D) into gallery ``slots[k]`` (distinct slots); a full one drops
        the stored descriptor nearest to it, by ``d2[k]`` (:meth:`pair_sq_distances`) when given."""
        if not len(slots):
            return
        x = np.asarray(x, np.float32)
        xx = np.matmul(x[:, None, :], x[:, :, None])[:, 0, 0]  # each x . x as one dot product
        if not np.all(np.isfinite(xx)):
            raise ValueError("descriptor has non-finite values")
        self._own()
        n = self.n[slots]
        full = n >= self.capacity
        cols = n.copy()
        if full.any():
            every = bool(full.all())
            if d2 is None:
                d2 = self.pair_sq_distances(slots if every else slots[full], x if every else x[full])
            elif not every:
                d2 = d2[full]
            cols[full] = np.argmin(d2, axis=1)
        self._write(slots, cols, x, xx, np.where(full, n, n + 1))

    def _write(self, slots: np.ndarray, cols: np.ndarray, x: np.ndarray, xx: np.ndarray, n: np.ndarray) -> None:
        counter = self.counter[slots]
        self.data[slots, :, cols] = x
        self.sq[slots, cols] = xx
        self.age[slots, cols] = counter
        self.counter[slots] = counter + 1
        self.n[slots] = n
