"""``perception tracker``: run the tracker node."""

from __future__ import annotations

import argparse

from common.node import run_node
from services.tracker import flags
from services.tracker.config import TrackerConfig
from services.tracker.service import TrackerService

DESCRIPTION = """\
Track people in 3-D with the thesis's Re-ID tracker (seed 000): Kalman filters,
appearance association gated by position (Algorithm 1), an ID memory that gives a
returning person their old ID (Algorithm 2). Subscribes to the localizer's
LocalizedDetections and the embedder's Embeddings, publishes the Confirmed tracks
after every frame, and answers `?id=K` queries on the track query key.

Settings come from defaults (the paper's values) <- --service-config FILE (section
'tracker' if present) <- PERCEPTION_TRACKER__FIELD environment variables <- flags.
The ID memory is kept in --memory (default under ~/.local/state) so a restarted
tracker keeps identities; --no-memory turns that off."""

add_arguments = flags.add_arguments


def main(args: argparse.Namespace) -> int:
    return run_node(args, "tracker", TrackerConfig, flags.overrides(args), TrackerService, adjust=flags.adjust(args))
