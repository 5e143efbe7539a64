"""``perception attention``: run the attention node."""

from __future__ import annotations

import argparse

from common.runtime.node import run_node
from services.attention import flags
from services.attention.config import AttentionConfig
from services.attention.service import AttentionService

DESCRIPTION = """\
Keep a chosen person in view with the robot's pan/tilt head (Ban et al.'s visual servoing):
the control law inverts the image Jacobian of the person's point for the pan and tilt
joints, with a configurable gain, velocity limits and dead zone; when the person is lost
the head holds still for a while, then returns to its rest pose. Subscribes to the
tracker's Tracks, the head camera's frames (for the camera info) and the transforms,
publishes HeadCommand (pan/tilt rates) on the head/command key, and takes whom to look at
from --target or at run time from the attention query (perception look ID|nearest|lock|none).

Settings come from defaults <- --service-config FILE (section 'attention' if present) <-
PERCEPTION_ATTENTION__FIELD environment variables <- flags."""

add_arguments = flags.add_arguments


def main(args: argparse.Namespace) -> int:
    return run_node(args, "attention", AttentionConfig, flags.overrides(args), AttentionService)
