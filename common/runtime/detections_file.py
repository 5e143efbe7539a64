"""The detection JSON-lines format shared by the offline tools.

``perception detect`` writes one line per image::

    {"image": path, "width": W, "height": H, "detections": [{"bbox_xyxy": [x1, y1, x2, y2], "score": s}, ...]}

and ``perception embed``, ``perception calibrate-embedder`` and ``perception localize`` read
it. Lines may carry extra keys (a detection's ``"person_id"``, an ``"embedding"``, ...).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any, Iterator, TextIO

from common.runtime.cli_util import CliError, check_input_file

__all__ = ["read_detection_lines"]


def read_detection_lines(path: str | Path, *, require_image: bool = False) -> Iterator[tuple[int, dict[str, Any]]]:
    """(line number, object) of every non-empty line of ``path`` (``-`` reads stdin).

    Raises :class:`CliError` naming the file and line for a missing file, a line that is
    not JSON, or a line without a ``"detections"`` list (or, with ``require_image``,
    without an ``"image"`` path).
    """
    p = Path(path)
    expected = "expected JSON lines as written by 'perception detect'"
    if str(path) != "-":
        check_input_file(p, expected)
    stream: TextIO = sys.stdin if str(path) == "-" else p.open(encoding="utf-8")
    seen = False
    with stream:
        for n, raw in _lines(stream, p, expected):
            if not raw.strip():
                continue
            seen = True
            try:
                obj = json.loads(raw)
            except json.JSONDecodeError as exc:
                raise CliError(f"{p}:{n}: not JSON: {exc}") from exc
            if not isinstance(obj, dict) or not isinstance(obj.get("detections", []), list):
                raise CliError(f'{p}:{n}: expected an object with a "detections" list')
            if require_image and not isinstance(obj.get("image"), str):
                raise CliError(f'{p}:{n}: expected {{"image": path, "detections": [...]}}')
            yield n, obj
    if not seen and str(path) != "-":
        raise CliError(f"{p} is empty ({expected})")


def _lines(stream: TextIO, p: Path, expected: str) -> Iterator[tuple[int, str]]:
    """(line number, text) of ``stream``; a CliError naming the line where it stops being UTF-8 text."""
    n = 0
    try:
        for n, raw in enumerate(stream, 1):
            yield n, raw
    except UnicodeDecodeError as exc:
        raise CliError(f"{p}:{n + 1}: not a text file ({expected})") from exc
