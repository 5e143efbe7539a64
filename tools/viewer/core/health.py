"""A node's health from what the viewer has seen of it: its liveliness token and its status."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

__all__ = ["NodeSeen", "health"]

#: A status older than this (s) makes a live node "stale": statuses come at 1 Hz.
STALE_AFTER_S = 3.0


@dataclass
class NodeSeen:
    """What is known of one node instance (``status_at`` on the viewer's clock, s)."""

    name: str
    instance: str
    alive: bool = False
    status_at: float | None = None
    state: str = "running"
    error: str = ""
    #: The last status's counters and host, as the page shows them.
    counters: dict[str, Any] = field(default_factory=dict)


def health(node: NodeSeen, now: float) -> str:
    """``failed`` (stopped on an error), ``down`` (no liveliness token), ``stale`` (alive but
    no recent status) or ``ok``."""
    if node.state == "failed":
        return "failed"
    if not node.alive:
        return "down"
    if node.status_at is None or now - node.status_at > STALE_AFTER_S:
        return "stale"
    return "ok"
