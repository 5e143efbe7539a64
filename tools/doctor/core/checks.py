"""Every check, in checklist order, and the verdict: text, JSON-ready dicts and exit code.

``run_checks(observation)`` is the whole diagnosis; it is pure, so a test can hand it
hand-made facts. The exit code is 0 when every check passes, 1 on a warning, 2 on a
failure, so that a robot's start-up script can gate on it.
"""

from __future__ import annotations

from typing import Any

from tools.doctor.core.camera import camera_checks
from tools.doctor.core.chain import chain_checks, clock_checks
from tools.doctor.core.config import config_checks
from tools.doctor.core.facts import SYMBOLS, Check, Observation
from tools.doctor.core.geometry import geometry_checks
from tools.doctor.core.laser import laser_checks
from tools.doctor.core.ros2 import ros2_checks
from tools.doctor.core.streams import node_checks, stream_checks
from tools.doctor.core.transforms import transform_checks

__all__ = ["SECTIONS", "exit_code", "render", "run_checks", "to_dicts"]

SECTIONS = ("Streams", "ROS 2", "Camera", "Laser", "Transforms", "Clocks", "Chain", "Config")
_CODES = {"ok": 0, "warn": 1, "fail": 2}


def run_checks(obs: Observation) -> list[Check]:
    """The checklist for ``obs``, section by section."""
    return [*stream_checks(obs), *node_checks(obs), *ros2_checks(obs), *camera_checks(obs), *laser_checks(obs),
            *transform_checks(obs),
            *geometry_checks(obs),
            *clock_checks(obs), *chain_checks(obs), *config_checks(obs)]


def exit_code(checks: list[Check]) -> int:
    """0 if all pass, 1 if the worst is a warning, 2 if any fails."""
    return max((_CODES[c.status] for c in checks), default=0)


def to_dicts(checks: list[Check]) -> list[dict[str, Any]]:
    return [{"section": c.section, "name": c.name, "status": c.status, "figure": c.figure, "fix": c.fix}
            for c in checks]


def render(checks: list[Check], title: str) -> str:
    """The checklist as text: a title, then per section one line per check and its fix."""
    width = max((len(c.name) for c in checks), default=0)
    lines = [title]
    for section in SECTIONS:
        these = [c for c in checks if c.section == section]
        if not these:
            continue
        lines += ["", section]
        for c in these:
            lines.append(f"  {SYMBOLS[c.status]} {c.name:<{width}}  {c.figure}")
            if c.fix:
                lines.append(f"    {'':<{width}}  fix: {c.fix}")
    fails = sum(c.status == "fail" for c in checks)
    warns = sum(c.status == "warn" for c in checks)
    verdict = ("all checks pass" if not fails and not warns else
               f"{fails} failed, {warns} warning{'s' if warns != 1 else ''}, {len(checks) - fails - warns} passed")
    lines += ["", verdict]
    return "\n".join(lines)
