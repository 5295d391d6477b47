"""Progress callbacks: one name, ``progress``, across linkfea and vjm.

Every public function that can report how a long run is going takes ``progress``: a callable
called with one short line of text at each stage (``progress=print``, ``progress=lines.append``).
"""
from __future__ import annotations

from typing import Callable, Optional

Progress = Callable[[str], None]
"""A progress callback: called with one line of text (no trailing newline)."""


def quiet(msg: str) -> None:
    """The callback that says nothing (the default where none is given)."""


def or_quiet(progress: Optional[Progress]) -> Progress:
    """``progress``, or :func:`quiet` for None."""
    return progress if progress is not None else quiet


class StderrLines:
    """The default progress of the Python calls: one line per stage on stderr, ``linkfea [12.3 s] meshing``
    (seconds since the call began), flushed at once, so that a long run is visibly alive in a terminal and
    in a notebook's output alike."""

    def __init__(self, prefix: str = "linkfea"):
        import time

        self.prefix, self.t0 = prefix, time.perf_counter()

    def __call__(self, msg: str) -> None:
        import sys
        import time

        print(f"{self.prefix} [{time.perf_counter() - self.t0:.1f} s] {msg}", file=sys.stderr, flush=True)


def or_default(progress) -> Progress:
    """``progress`` itself; None: :class:`StderrLines` (visible by default); False: :func:`quiet`."""
    if progress is None:
        return StderrLines()
    if progress is False:
        return quiet
    return progress
