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
