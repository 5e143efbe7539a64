"""What the demo prints fits a default terminal: :data:`WIDTH` columns, longer lines wrapped;
and the text it prints at the end of a run."""

from __future__ import annotations

import textwrap
from pathlib import Path
from typing import Any

__all__ = ["WIDTH", "attention_line", "closing_text", "wrap"]

#: The width the live table and the final tables fit in (a default terminal's).
WIDTH = 80


def wrap(text: str, width: int = WIDTH) -> str:
    """``text`` with every line longer than ``width`` broken at spaces (indented after the first)."""
    return "\n".join(textwrap.fill(line, width, subsequent_indent="  ", break_on_hyphens=False) if len(line) > width
                     else line for line in text.split("\n"))


def attention_line(a: dict[str, Any]) -> str:
    """The attention node's scores (``report["attention"]``) as one line."""
    return (f"attention (person {a['person_id']}): centring error p50 {a['center_error_px_p50']} px, "
            f"p95 {a['center_error_px_p95']} px; visible {a['target_visible_fraction']} of {a['frames']} frames")


def closing_text(stages_text: str, table: str, log_dir: Path, cpu: dict[str, float | None], extra: list[str],
                 plotted: str | None) -> str:
    """What the demo prints at the end (without ``--json``): the stages over the run, Table II
    and the pose line (``table``), each process's CPU, ``extra`` lines and where the plot is;
    no line longer than :data:`WIDTH` columns."""
    parts = ["", stages_text, "", "Table II for this run (ground truth from the simulator):", "", table, "",
             "CPU per service: " + ", ".join(f"{n} {v}%" for n, v in cpu.items() if v is not None), *extra,
             f"logs: {log_dir}"]
    if plotted:
        parts.append(f"plot of the run (tracks against the ground truth): {plotted}")
    return wrap("\n".join(parts), WIDTH)
