"""Progress callbacks: one name, ``progress``, across linkfea and vjm.

Every public function that can report how a long run is going takes ``progress``: a callable
called with one short line of text at each stage (``progress=print``, ``progress=lines.append``).
Older releases called the same thing ``log`` (``vjm.diagnose``); :func:`renamed_progress` keeps
such a name working, with a :class:`DeprecationWarning`.
"""
from __future__ import annotations

import functools
import warnings
from typing import Callable, Optional, TypeVar

Progress = Callable[[str], None]
"""A progress callback: called with one line of text (no trailing newline)."""

F = TypeVar("F", bound=Callable)


def quiet(msg: str) -> None:
    """The callback that says nothing (the default where none is given)."""


def or_quiet(progress: Optional[Progress]) -> Progress:
    """``progress``, or :func:`quiet` for None."""
    return progress if progress is not None else quiet


def renamed_progress(*old: str) -> Callable[[F], F]:
    """Decorator: the keyword names ``old`` are deprecated names of the function's ``progress``.

    A call with one of them warns (:class:`DeprecationWarning`) and passes its value as
    ``progress``; giving both is a TypeError.  ``deprecated_progress_names`` on the function lists them.
    """

    def deco(f: F) -> F:
        @functools.wraps(f)
        def wrapper(*args, **kwargs):
            for name in old:
                if name in kwargs:
                    if kwargs.get("progress") is not None:
                        raise TypeError(f"{f.__name__}() got progress and its deprecated name {name}: give one")
                    warnings.warn(f"{f.__name__}({name}=...) is deprecated: use progress=...",
                                  DeprecationWarning, stacklevel=2)
                    kwargs["progress"] = kwargs.pop(name)
            return f(*args, **kwargs)

        wrapper.deprecated_progress_names = old  # type: ignore[attr-defined]
        return wrapper  # type: ignore[return-value]

    return deco
