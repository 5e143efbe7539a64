"""The tracker service on an in-memory bus with a hand-driven clock, and a localizer/embedder
side that publishes people at given stamps; the frames' timing and the people's looks."""

from __future__ import annotations

import typing
from pathlib import Path

import numpy as np

from common.messages.keys import RELIABLE, Keys
from common.transport.memory import MemoryBus
from common.messages.schemas import Embeddings, Header, LocalizedDetection, LocalizedDetections, ModelCard, Tracks
from services.tracker.config import TrackerConfig
from services.tracker.service import TrackerService

__all__ = ["DIM", "KEYS", "PERIOD_NS", "S", "T0", "Clock", "Person", "Rig", "config", "ids_by_x", "look"]

KEYS = Keys(robot="r1")
T0 = 1_700_000_000_000_000_000
S = 1_000_000_000
PERIOD_NS = S // 10  # 10 Hz
DIM = 16
RNG = np.random.default_rng(23)
LOOKS = RNG.normal(size=(3, DIM))
LOOKS /= np.linalg.norm(LOOKS, axis=1, keepdims=True)
GOOD_COV = np.eye(3) * 0.01

#: (who, (x, y, z)): a person (their look) at a position.
Person = tuple[int, tuple[float, float, float]]


class Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


class Rig:
    """A tracker on a MemoryBus, and a 'localizer/embedder' that publishes frames at given stamps."""

    def __init__(self, config: TrackerConfig, bus: MemoryBus | None = None) -> None:
        self.bus = bus if bus is not None else MemoryBus()
        self.clock = Clock()
        self.service = TrackerService(self.bus.transport(), KEYS, config, clock=self.clock)
        peer = self.bus.transport()
        self.loc_pub = peer.publisher(KEYS.localized("head"), LocalizedDetections, RELIABLE)
        self.emb_pub = peer.publisher(KEYS.embeddings("head"), Embeddings, RELIABLE)
        self.tracks_sub = peer.subscribe(KEYS.tracks(), Tracks, RELIABLE)

    def send(self, stamp_ns: int, seq: int, people: list[Person], cov: np.ndarray = GOOD_COV,
             card: ModelCard | None = None, embeddings: bool = True) -> None:
        header = Header(stamp_ns=stamp_ns, frame_id="map", seq=seq, source="head")
        dets = [LocalizedDetection(index=i, bbox_xyxy=(0, 0, 10, 10), score=0.9, position=np.array(p, float),
                                   cov=cov, depth_m=2.0) for i, (_, p) in enumerate(people)]
        self.loc_pub.put(LocalizedDetections(header=header, detections=dets))
        if embeddings:
            card = card or ModelCard(name="colour", dim=DIM, normalized=True)
            vec = np.stack([look(w, card.dim) for w, _ in people]) if people else np.zeros((0, card.dim))
            self.emb_pub.put(Embeddings(header=header, model=card, indices=np.arange(len(people), dtype=np.int32),
                                        vectors=vec.astype(np.float32)))

    def step(self, stamp_ns: int, seq: int, people: list[Person], **kw: typing.Any) -> list[Tracks]:
        """Send one frame, advance the clock by a frame period and poll; what was published."""
        self.send(stamp_ns, seq, people, **kw)
        self.clock.now += PERIOD_NS / S
        return self.service.poll(self.clock())

    def walk(self, start_ns: int, n: int, people: list[Person], seq0: int = 0) -> list[Tracks]:
        out: list[Tracks] = []
        for k in range(n):
            out += self.step(start_ns + k * PERIOD_NS, seq0 + k, people)
        return out

    @property
    def extra(self) -> dict[str, float]:
        return self.service.counters.extra


def look(who: int, dim: int = DIM) -> np.ndarray:
    """Person ``who``'s descriptor, a little noisy ((dim,) float32, unit length)."""
    base = LOOKS[who] if dim == DIM else np.resize(LOOKS[who], dim)
    v = base + RNG.normal(scale=0.01, size=dim)
    return (v / np.linalg.norm(v)).astype(np.float32)


def config(tmp_path: Path, profile: str = "robust", **kw: typing.Any) -> TrackerConfig:
    kw.setdefault("output_rate_hz", 0.0)  # once per frame: these tests follow each frame's output
    return TrackerConfig(profile=profile, memory_path=tmp_path / "memory.npz", **kw)


def ids_by_x(msg: Tracks) -> dict[int, int]:
    """{rounded x: track ID} of the reported tracks."""
    return {round(float(t.position[0])): t.id for t in msg.tracks}
