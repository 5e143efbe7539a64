"""The labelled dev scans of ``data/laser_legs`` (Leigh et al.'s leg_tracker training bags), as
the leg detector's trainer and benchmark read them: every scan with its labelled legs and
whether it is an empty room. The protocol is the data's README's."""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path
import numpy as np

from common.messages.schemas import LaserScan
from services.laser.files import read_scans

__all__ = ["DevScan", "SPLITS", "WINDOW_DEG", "WINDOW_RANGE_M", "files_digest", "in_window", "load", "mirrored", "noisy"]

#: The labelled window: every cluster inside it was labelled, nothing outside it was.
WINDOW_DEG = 15.0
WINDOW_RANGE_M = 5.0

#: (file, topic, empty room) of every part of the dev data, by the split the benchmark uses.
SPLITS: dict[str, tuple[tuple[str, str, bool], ...]] = {
    "train": (("positive_1_extracted.bag", "/training_scan", False),
              ("positive_2_extracted.bag", "/training_scan", False),
              ("negative_2_dev.bag", "/left_scan", True)),
    "test": (("positive_3_extracted.bag", "/training_scan", False),
             ("negative_2_dev.bag", "/rear_scan", True)),
}


@dataclass(frozen=True)
class DevScan:
    """A scan, its labelled legs (L, 2) in the scanner's frame, and whether it is an empty room
    (every cluster a non-leg); ``part`` names the file and topic."""

    scan: LaserScan
    legs: np.ndarray
    empty: bool
    part: str


def mirrored(d: DevScan) -> DevScan:
    """``d`` seen in a mirror (y -> -y): the beams in reverse order, the labels flipped. A leg
    looks the same either way; training on both keeps the classifier from learning which side
    of this robot's scanner the people walked on."""
    s = d.scan
    scan = s.model_copy(update={"ranges": s.ranges[::-1].copy(), "angle_min": -s.angle_max, "angle_max": -s.angle_min,
                                "intensities": None if s.intensities is None else s.intensities[::-1].copy()})
    return DevScan(scan, d.legs * np.array([1.0, -1.0]), d.empty, d.part + ":mirrored")


def _normal(n: int, seed: int) -> np.ndarray:
    """``n`` standard normal draws from PCG64's raw stream by Box-Muller: the same on every numpy
    (numpy keeps its bit generators' streams, not its distributions', from version to version)."""
    raw = np.random.PCG64(seed).random_raw(2 * n).reshape(2, n)
    u1, u2 = ((raw >> np.uint64(11)).astype(np.float64) + 0.5) / 2.0 ** 53
    return np.sqrt(-2.0 * np.log(u1)) * np.cos(2.0 * np.pi * u2)


def noisy(d: DevScan, sigma_m: float, seed: int) -> DevScan:
    """``d`` with Gaussian noise of ``sigma_m`` on every valid range: a scanner noisier than the
    one that recorded the dev scans, so that the classifier does not learn this one's smoothness."""
    s = d.scan
    r = s.ranges.astype(np.float64)
    ok = np.isfinite(r) & (r > s.range_min) & (r < s.range_max)
    r = np.where(ok, r + sigma_m * _normal(len(r), seed), r).astype(np.float32)
    return DevScan(s.model_copy(update={"ranges": r}), d.legs, d.empty, d.part + ":noisy")


def in_window(xy: np.ndarray) -> np.ndarray:
    """Which of the points ``xy`` (N, 2) lie inside the labelled window."""
    xy = np.asarray(xy, np.float64).reshape(-1, 2)
    return (np.abs(np.degrees(np.arctan2(xy[:, 1], xy[:, 0]))) <= WINDOW_DEG) & (np.hypot(xy[:, 0], xy[:, 1]) <= WINDOW_RANGE_M)


def _labels(path: Path) -> list[np.ndarray]:
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    out = []
    with AnyReader([path], default_typestore=get_typestore(Stores.ROS1_NOETIC)) as reader:
        conns = [c for c in reader.connections if c.topic == "/leg_cluster_positions"]
        for conn, _, raw in reader.messages(connections=conns):
            msg = reader.deserialize(raw, conn.msgtype)
            out.append(np.array([[p.position.x, p.position.y] for p in msg.poses], np.float64).reshape(-1, 2))
    return out


def load(folder: Path, split: str) -> list[DevScan]:
    """Every scan of ``split`` (``train``, ``test`` or ``all``), labels paired by order (the
    label PoseArrays carry a zero stamp: the n-th belongs to the n-th scan)."""
    parts = SPLITS["train"] + SPLITS["test"] if split == "all" else SPLITS[split]
    out: list[DevScan] = []
    for name, topic, empty in parts:
        path = Path(folder) / name
        scans = [s for _, s in read_scans(path, topic)]
        labels = [np.zeros((0, 2))] * len(scans) if empty else _labels(path)
        if len(labels) != len(scans):
            raise ValueError(f"{path}: {len(scans)} scans but {len(labels)} label sets")
        out += [DevScan(s, lab, empty, f"{name}:{topic}") for s, lab in zip(scans, labels)]
    return out


def files_digest(folder: Path, split: str) -> dict[str, str]:
    """sha256 of every file ``split`` reads: what a model trained on it came from."""
    parts = SPLITS["train"] + SPLITS["test"] if split == "all" else SPLITS[split]
    return {name: hashlib.sha256((Path(folder) / name).read_bytes()).hexdigest()
            for name in dict.fromkeys(p[0] for p in parts)}
