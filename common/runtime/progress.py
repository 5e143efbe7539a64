"""Progress of long offline work: a bar with a count and an ETA on a terminal, nothing otherwise.

``progress(items, total=N, desc="frames")`` wraps an iterable in a tqdm bar written to
stderr when stderr is a terminal, and returns it unchanged otherwise (a pipe, a log file,
CI), so output that goes to files or other programs never carries bar text.

``progress_bar(total=N, desc=...)`` is the same bar advanced by hand (``bar.update()``), for
work that is not one loop: nested loops, callbacks. While it is shown, lines printed to a
terminal's stdout are written above it rather than through it.
"""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Iterable, Iterator
from typing import Any, Protocol, TextIO, TypeVar

__all__ = ["Bar", "progress", "progress_bar"]

T = TypeVar("T")


class Bar(Protocol):
    """What :func:`progress_bar` yields: ``update(n)`` advances the count by ``n``."""

    def update(self, n: int = 1) -> Any: ...


class _Hidden:
    """The bar off a terminal: counts nothing, shows nothing."""

    def update(self, n: int = 1) -> None:
        del n


def _shown(enabled: bool | None) -> bool:
    return sys.stderr.isatty() if enabled is None else enabled


def _tqdm(items: Iterable[Any] | None, total: int | None, desc: str, unit: str) -> Any:
    import shutil

    from tqdm import tqdm

    # a terminal that reports no size (some pseudo-terminals) would get an empty bar
    ncols = shutil.get_terminal_size((80, 24)).columns or 80
    return tqdm(items, total=total, desc=desc, unit=unit, file=sys.stderr, ncols=ncols, leave=False)


def progress(items: Iterable[T], *, total: int | None = None, desc: str = "", unit: str = "it",
             enabled: bool | None = None) -> Iterable[T] | Iterator[T]:
    """``items``, with a progress bar on stderr when it is a terminal (``enabled`` overrides that)."""
    if not _shown(enabled):
        return items
    return _tqdm(items, total, desc, unit)  # type: ignore[no-any-return]


class _LinesAboveBar:
    """A terminal's stdout while a bar is shown: each whole line clears the bar, goes out, and the bar is redrawn.

    A partial line waits for its end (or the bar's end), so the bar never lands in the middle of it.
    """

    def __init__(self, stream: TextIO, bar: Any) -> None:
        self._stream = stream
        self._bar = bar
        self._pending = ""

    def write(self, text: str) -> int:
        lines, newline, rest = (self._pending + text).rpartition("\n")
        if newline:
            self._bar.clear()
            self._stream.write(lines + newline)
            self._stream.flush()
            self._bar.refresh()
            self._pending = rest
        else:
            self._pending += text
        return len(text)

    def flush(self) -> None:
        self._stream.flush()

    def finish(self) -> None:
        """Write what is left of an unfinished line (the bar is gone by then)."""
        if self._pending:
            self._stream.write(self._pending)
            self._stream.flush()
            self._pending = ""

    def __getattr__(self, name: str) -> Any:  # isatty, fileno, encoding, ... of the terminal
        return getattr(self._stream, name)


@contextlib.contextmanager
def progress_bar(total: int | None, *, desc: str = "", unit: str = "it", enabled: bool | None = None) -> Iterator[Bar]:
    """A bar of ``total`` steps advanced by ``bar.update(n)``, on stderr when it is a terminal.

    Off a terminal (``enabled`` overrides that) the bar does nothing and stdout is not
    touched. On one, stdout, if it is a terminal too, is wrapped for the bar's lifetime so
    printed lines appear above the bar; the bytes written to stdout are the same.
    """
    if not _shown(enabled):
        yield _Hidden()
        return
    bar = _tqdm(None, total, desc, unit)
    out = sys.stdout
    above = _LinesAboveBar(out, bar) if out is not None and out.isatty() else None
    if above is not None:
        sys.stdout = above  # type: ignore[assignment]
    try:
        yield bar  # type: ignore[misc]
    finally:
        if above is not None:
            sys.stdout = out
        bar.close()
        if above is not None:
            above.finish()
