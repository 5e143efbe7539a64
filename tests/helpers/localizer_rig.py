"""The localizer service on an in-memory bus, plus a client transport playing robot, camera and detector."""

from __future__ import annotations

from common.messages.keys import RELIABLE, Keys
from common.messages.schemas import Detections, LocalizedDetections, RGBDFrame, TransformBatch
from common.runtime.service import Counters
from common.transport.base import Transport
from common.transport.memory import MemoryBus
from services.localizer.config import LocalizerConfig
from services.localizer.service import LocalizerService
from tests.fixtures import localizer_scene as scene
from tests.fixtures.localizer_scene import S

__all__ = ["KEYS", "Rig"]

KEYS = Keys()


class Rig:
    """A localizer on a memory bus, plus a client transport playing robot, camera and detector."""

    def __init__(self, bus: MemoryBus, **config: object) -> None:
        """``config``: the localizer's settings; ``body_half_depth_m`` 0 unless given, for the
        synthetic scenes' people are flat cut-outs at their centre's depth."""
        self.counters = Counters()
        settings = {"body_half_depth_m": 0.0, **config}
        self.service = LocalizerService(bus.transport(), KEYS, LocalizerConfig(**settings), self.counters)
        self.client: Transport = bus.transport()
        self.frames = self.client.publisher(KEYS.frames("head"), RGBDFrame, RELIABLE)
        self.dets = self.client.publisher(KEYS.detections("head"), Detections, RELIABLE)
        self.tf = self.client.publisher(KEYS.tf(), TransformBatch, RELIABLE)
        self.tf_static = self.client.publisher(KEYS.tf_static(), TransformBatch, RELIABLE)
        self.out = self.client.subscribe(KEYS.localized("head"), LocalizedDetections, RELIABLE)

    def robot(self, stamp_ns: int) -> None:
        """The robot's transforms: the static mount, and two poses around ``stamp_ns``."""
        self.tf_static.put(scene.tf_static())
        self.tf.put(scene.tf(stamp_ns - S // 10))
        self.tf.put(scene.tf(stamp_ns + S // 10))
