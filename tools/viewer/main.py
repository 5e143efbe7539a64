"""``perception view``: the operator's live page (and, with --foxglove-port, a Foxglove server)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any, Mapping

from common.runtime.cli_util import CliError
from common.messages.keys import Keys
from common.runtime.node import add_node_arguments, run_node
from common.runtime.service import Counters
from common.transport.base import Transport
from tools.viewer.config import ViewerConfig
from tools.viewer.node import ViewerNode
from tools.viewer.web import LatestState, WebServer

DESCRIPTION = """\
Serve a live page for the robot's operator on this machine: a top-down map of the
confirmed tracks with their IDs, short trails and the robot; the camera image with the
detections' boxes labelled with track IDs; each stage's rate and latency; and each
node's health from its liveliness token and status. Open http://127.0.0.1:PORT/ in any
browser; the page needs no internet (every asset ships in the package). Any number of
browsers may watch; each gets the newest state, and a slow one skips states instead of
queueing them.

--foxglove-port PORT also serves Foxglove's WebSocket protocol (foxglove-sdk, the 'view'
extra): in the Foxglove app, open a "Foxglove WebSocket" connection to ws://127.0.0.1:PORT.
It shows /camera/image (JPEG), /camera/annotations (boxes with track IDs), /people (a
3-D scene in the map frame: body, ID, velocity arrow, covariance ellipse), /tf, /map (the
robot's map, a Grid: --static-map's file, or what perception ros2 passes on from /map), and
the tracks, detections, localized detections and statuses as JSON.

examples:
  perception view                       # the page on http://127.0.0.1:8080/
  perception view --port 9000 --robot mbot --connect tcp/192.168.1.20:7447
  perception view --foxglove-port 8765 --no-page"""

#: flag -> (setting, type, metavar, help)
_FLAGS: dict[str, tuple[str, type, str | None, str]] = {
    "--camera": ("camera", str, None, "camera name in the keys"),
    "--port": ("port", int, "PORT", "the page's HTTP port"),
    "--host": ("host", str, "ADDR", "address to serve on (127.0.0.1: this machine only)"),
    "--foxglove-port": ("foxglove_port", int, "PORT", "also serve Foxglove's WebSocket protocol on PORT"),
    "--map-frame": ("map_frame", str, None, "frame of the map and the tracks"),
    "--base-frame": ("base_frame", str, None, "the robot's body frame"),
    "--trail": ("trail_s", float, "S", "length of the tracks' trails"),
    "--static-map": ("static_map", Path, "MAP.yaml", "the robot's map (a ROS map YAML file) drawn under the tracks "
                                                     "(default: the one perception ros2 passes on from /map)"),
}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    g = parser.add_argument_group("viewer")
    for flag, (dest, kind, metavar, help_text) in _FLAGS.items():
        g.add_argument(flag, dest=dest, type=kind, default=None, metavar=metavar, help=help_text)
    g.add_argument("--no-page", action="store_true", help="serve no page (only Foxglove)")
    add_node_arguments(parser, "viewer", ViewerConfig)


def _prepare(config: ViewerConfig) -> Mapping[str, Any]:
    """Bind the servers before connecting, so a busy port fails at once (exit status 2)."""
    servers: dict[str, Any] = {}
    if config.port is not None:
        servers["web"] = WebServer(config.host, config.port, LatestState())
    if config.foxglove_port is not None:
        from tools.foxglove.bridge import FoxgloveUnavailable, start_live_server

        try:
            servers["foxglove"] = start_live_server(config.host, config.foxglove_port, config.jpeg_quality)
        except FoxgloveUnavailable as exc:
            raise ValueError(str(exc)) from exc
    return servers


def _build(transport: Transport, keys: Keys, config: ViewerConfig, counters: Counters, *,
           web: WebServer | None = None, foxglove: Any = None) -> ViewerNode:
    node = ViewerNode(transport, keys, config, counters, state=web.state if web is not None else None,
                      sinks=(foxglove,) if foxglove is not None else ())
    if web is not None:
        web.start()
        node.on_close(web.close)
        print(f"perception view: the page is on {web.url}", flush=True)
    if foxglove is not None:
        print(f"perception view: Foxglove WebSocket on ws://{config.host}:{foxglove.port}", flush=True)
    return node


def main(args: argparse.Namespace) -> int:
    overrides = {dest: getattr(args, dest, None) for dest, *_ in _FLAGS.values()}

    def adjust(config: ViewerConfig) -> ViewerConfig:
        if not args.no_page:
            return config
        if config.foxglove_port is None:
            raise CliError("--no-page leaves nothing to serve: give --foxglove-port too")
        return config.model_copy(update={"port": None})

    return run_node(args, "viewer", ViewerConfig, overrides, _build, prepare=_prepare, adjust=adjust)
