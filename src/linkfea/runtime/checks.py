"""Checks of numeric arguments: type, finiteness and range, with one message format.

Every numeric option of ``linkfea`` and ``vjm`` (the CLI flag and the Python
argument behind it) is checked here, against a :class:`Bounds` that states its
valid range once.  The error names the Python argument (``alpha must be in
(0, 1), got 2``); a CLI shows the flag instead (``--alpha must be ...``) with
:func:`cli_message`, from the ``argument`` and ``rule`` the error carries.

>>> ALPHA = Bounds(0, 1, lo_open=True, hi_open=True)
>>> number(0.05, "alpha", ALPHA)
0.05
>>> number(float("nan"), "alpha", ALPHA)
Traceback (most recent call last):
...
linkfea.runtime.checks.ArgumentError: alpha must be a finite number in (0, 1), got nan
>>> integer(3, "grid", Bounds(2))
3
"""
from __future__ import annotations

import math
import numbers
import operator
from dataclasses import dataclass
from typing import Mapping

from .errors import LinkFeaError


class ArgumentError(LinkFeaError):
    """A numeric argument of the wrong type or outside its range.

    ``argument`` is the name the message starts with; ``rule`` the rest
    (``"must be > 0, got -1"``), so that a CLI can put its flag in front.
    """

    def __init__(self, argument: str, rule: str):
        super().__init__(f"{argument} {rule}")
        self.argument = argument
        self.rule = rule


def _fmt(v: float) -> str:
    return f"{v:g}"


@dataclass(frozen=True)
class Bounds:
    """The valid range of a number: ``lo``/``hi`` (None: unbounded), open or closed ends, an integer or not."""

    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    hi_open: bool = False
    unit: str = ""

    def __str__(self) -> str:
        u = f" {self.unit}" if self.unit else ""
        if self.lo is not None and self.hi is not None:
            return (f"in {'(' if self.lo_open else '['}{_fmt(self.lo)}, {_fmt(self.hi)}"
                    f"{')' if self.hi_open else ']'}{u}")
        if self.lo is not None:
            return f"{'>' if self.lo_open else '>='} {_fmt(self.lo)}{u}"
        if self.hi is not None:
            return f"{'<' if self.hi_open else '<='} {_fmt(self.hi)}{u}"
        return f"any finite value{u}"

    def contains(self, v: float) -> bool:
        """Whether ``v`` is in the range; NaN never is (every comparison with it is false, so the
        ends below would let it through)."""
        if v != v:
            return False
        if self.lo is not None and (v <= self.lo if self.lo_open else v < self.lo):
            return False
        if self.hi is not None and (v >= self.hi if self.hi_open else v > self.hi):
            return False
        return True


#: common ranges
POSITIVE = Bounds(0, lo_open=True)
NON_NEGATIVE = Bounds(0)


def number(value, name: str, bounds: Bounds = Bounds(), error: type[ArgumentError] = ArgumentError) -> float:
    """``value`` as a float, checked: a real number (not a bool or a string), finite, within ``bounds``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise error(name, f"must be a number {bounds}, got {value!r}")
    v = float(value)
    if not math.isfinite(v):
        raise error(name, f"must be a finite number {bounds}, got {v!r}")
    if not bounds.contains(v):
        raise error(name, f"must be {bounds}, got {_fmt(v)}")
    return v


def optional_number(value, name: str, bounds: Bounds = Bounds(),
                    error: type[ArgumentError] = ArgumentError) -> float | None:
    """:func:`number`, with None passed through (the default)."""
    return None if value is None else number(value, name, bounds, error)


def integer(value, name: str, bounds: Bounds = Bounds(), error: type[ArgumentError] = ArgumentError) -> int:
    """``value`` as an int, checked: an integer type (int, numpy integer; not a bool or a float), within ``bounds``."""
    if isinstance(value, bool):
        raise error(name, f"must be a whole number {bounds}, got {value!r}")
    try:
        v = operator.index(value)
    except TypeError:
        raise error(name, f"must be a whole number {bounds}, got {value!r}") from None
    if not bounds.contains(v):
        raise error(name, f"must be a whole number {bounds}, got {v}")
    return v


def optional_integer(value, name: str, bounds: Bounds = Bounds(),
                     error: type[ArgumentError] = ArgumentError) -> int | None:
    """:func:`integer`, with None passed through (the default)."""
    return None if value is None else integer(value, name, bounds, error)


def flag(argument: str) -> str:
    """The CLI flag of a Python argument: ``mesh_size`` -> ``--mesh-size``."""
    return "--" + argument.replace("_", "-")


def cli_message(exc: BaseException, flags: Mapping[str, str] | None = None) -> str:
    """The message of ``exc`` for the command line: an :class:`ArgumentError` names the flag, not the argument.

    ``flags`` maps the arguments whose flag is not :func:`flag` of their name (``epsilon`` -> ``--envelope``).
    """
    arg = getattr(exc, "argument", None)
    rule = getattr(exc, "rule", None)
    text = str(exc)
    if isinstance(arg, str) and isinstance(rule, str) and text == f"{arg} {rule}":
        text = f"{(flags or {}).get(arg, flag(arg))} {rule}"
    return " ".join(text.split())


def closest(name: str, known) -> str | None:
    """The known name nearest to ``name`` (a typo, another case), or None when none is near."""
    import difflib

    known = list(known)
    low = {k.lower(): k for k in known}
    if name.lower() in low:
        return low[name.lower()]
    m = difflib.get_close_matches(name.lower(), list(low), n=1, cutoff=0.6)
    return low[m[0]] if m else None


def did_you_mean(name: str, known) -> str:
    """`` (did you mean 'sigma_t'?)`` for a misspelt name, else an empty string."""
    c = closest(name, known)
    return f" (did you mean {c!r}?)" if c else ""
