"""The embedder service on an in-memory bus, with a camera side that publishes frames and
detections and reads the embeddings back."""

from __future__ import annotations

from common.messages.keys import FRAMES, RELIABLE, Keys
from common.transport.memory import MemoryBus
from common.runtime.service import Counters
from common.messages.schemas import Detections, Embeddings, RGBDFrame
from services.embedder.config import EmbedderConfig
from services.embedder.core import ColourDescriptor
from services.embedder.service import EmbedderService

__all__ = ["KEYS", "Rig"]

KEYS = Keys(robot="testbot")


class Rig:
    def __init__(self, config: EmbedderConfig | None = None, backend: object | None = None) -> None:
        bus = MemoryBus()
        self.camera = bus.transport()
        self.counters = Counters()
        self.service = EmbedderService(bus.transport(), KEYS, config or EmbedderConfig(), self.counters,
                                       backend=backend or ColourDescriptor())  # type: ignore[arg-type]
        self.frames = self.camera.publisher(KEYS.frames("head"), RGBDFrame, FRAMES)
        self.dets = self.camera.publisher(KEYS.detections("head"), Detections, RELIABLE)
        self.out = self.camera.subscribe(KEYS.embeddings("head"), Embeddings, RELIABLE)

    def received(self) -> list[Embeddings]:
        got = []
        while (r := self.out.recv(timeout=0.5 if not got else 0.05)) is not None:
            got.append(r.msg)
        return got
