"""Progress of long offline work: a bar with a count and an ETA on a terminal, nothing otherwise.

``progress(items, total=N, desc="frames")`` wraps an iterable in a tqdm bar written to
stderr when stderr is a terminal, and returns it unchanged otherwise (a pipe, a log file,
CI), so output that goes to files or other programs never carries bar text.
"""

from __future__ import annotations

import sys
from typing import Iterable, Iterator, TypeVar

__all__ = ["progress"]

T = TypeVar("T")


def progress(items: Iterable[T], *, total: int | None = None, desc: str = "", unit: str = "it",
             enabled: bool | None = None) -> Iterable[T] | Iterator[T]:
    """``items``, with a progress bar on stderr when it is a terminal (``enabled`` overrides that)."""
    show = sys.stderr.isatty() if enabled is None else enabled
    if not show:
        return items
    import shutil

    from tqdm import tqdm

    # a terminal that reports no size (some pseudo-terminals) would get an empty bar
    ncols = shutil.get_terminal_size((80, 24)).columns or 80
    return tqdm(items, total=total, desc=desc, unit=unit, file=sys.stderr, ncols=ncols, leave=False)
