"""``perception tracker``: run the tracker node."""

from __future__ import annotations

import argparse

from common.runtime.node import run_node
from services.tracker import flags
from services.tracker.config import TrackerConfig
from services.tracker.service import TrackerService

DESCRIPTION = """\
Track people in 3-D: Kalman filters, association by position, appearance and detector
confidence, an ID memory that gives a returning person their old ID (the thesis's
Algorithm 2). Profile 'robust' (default) adds the log-odds of position, appearance,
detector confidence and a per-track appearance classifier, and publishes confirmed and
briefly coasting tracks; 'thesis' is Pinto's thesis exactly (Algorithm 1, Confirmed
tracks only). Subscribes to the localizer's LocalizedDetections and the
embedder's Embeddings, publishes Tracks at --output-rate (10 Hz by default, predicted
to the publish time; 0: after every frame), and answers `?id=K` queries on the track
query key.

Settings come from defaults (the paper's values) <- --preset NAME (deploy/presets/NAME.yaml)
<- --service-config FILE (section 'tracker' if present) <- PERCEPTION_TRACKER__FIELD
environment variables <- flags.
The ID memory is kept in --memory (default under ~/.local/state) so a restarted
tracker keeps identities; --no-memory turns that off."""

add_arguments = flags.add_arguments


def main(args: argparse.Namespace) -> int:
    return run_node(args, "tracker", TrackerConfig, flags.overrides(args), TrackerService, adjust=flags.adjust(args),
                    base=flags.preset(args))
