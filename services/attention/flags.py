"""The flags of ``perception attention`` and the settings they override."""

from __future__ import annotations

import argparse
from typing import Any

from common.runtime.node import add_node_arguments
from services.attention.config import AttentionConfig

__all__ = ["add_arguments", "overrides"]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    g = parser.add_argument_group("attention")
    g.add_argument("--target", default=None, metavar="ID|nearest|lock|none",
                   help="whom to look at from the start")
    g.add_argument("--camera", default=None, help="the camera on the head, for its camera info")
    g.add_argument("--gain", type=float, default=None, metavar="PER_S", help="control gain")
    g.add_argument("--hold", dest="hold_s", type=float, default=None, metavar="S",
                   help="a lost target: hold still this long, then return to rest")
    add_node_arguments(parser, "attention", AttentionConfig)


def overrides(args: argparse.Namespace) -> dict[str, Any]:
    return {"target": args.target, "camera": args.camera, "gain": args.gain, "hold_s": args.hold_s}
