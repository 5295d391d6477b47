"""The ``--param NAME=SPEC`` grammar of a sweep: a list ``10,15,20`` or a range ``lo:hi[:step]``."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..runtime.errors import LinkFeaError
from .budget import range_count


@dataclass(frozen=True)
class ParamSpec:
    """One ``--param NAME=SPEC``: a list ``10,15,20`` (numbers or words) or a range ``lo:hi[:step]``.

    A range with a step gives ``lo, lo+step, ...`` up to ``hi`` inclusive.  In
    a Latin hypercube, a range is sampled uniformly in ``[lo, hi]`` (snapped to
    the step if one is given) and a list by its items.
    """

    name: str
    values: tuple = ()
    lo: float | None = None
    hi: float | None = None
    step: float | None = None

    @property
    def is_range(self) -> bool:
        return self.lo is not None

    def grid_values(self) -> tuple:
        if not self.is_range:
            return self.values
        return tuple(_tidy(self.lo + k * self.step) for k in range(self.grid_count()))

    def grid_count(self) -> int:
        """Number of grid values, counted without listing them."""
        if not self.is_range:
            return len(self.values)
        if self.step is None:
            raise LinkFeaError(f"--param {self.name}: a grid needs a step, lo:hi:step (or use --sample)")
        return range_count(self.lo, self.hi, self.step)

    def sample(self, u: np.ndarray) -> list:
        """Values at the unit-interval coordinates ``u`` of a Latin hypercube."""
        if not self.is_range:
            idx = np.minimum((u * len(self.values)).astype(int), len(self.values) - 1)
            return [self.values[i] for i in idx]
        x = self.lo + u * (self.hi - self.lo)
        if self.step is not None:
            x = np.minimum(self.lo + np.round((x - self.lo) / self.step) * self.step, self.hi)
        return [_tidy(v, 6) for v in x]


def _tidy(v: float, digits: int = 12) -> float:
    """Round to ``digits`` significant digits: 10 + 3*0.1 is 10.3, and keys do not depend on round-off."""
    return 0.0 if v == 0 else float(f"{v:.{digits}g}")


def _number(text: str):
    try:
        v = float(text)
    except ValueError:
        return None
    return v if math.isfinite(v) else None


def parse_param_spec(item: str) -> ParamSpec:
    """``"width=10,15,20"`` or ``"length=100:300:50"`` -> :class:`ParamSpec`.

    >>> parse_param_spec("length=10:20:5").grid_values()
    (10.0, 15.0, 20.0)
    >>> parse_param_spec("section=rect,tube").grid_values()
    ('rect', 'tube')
    """
    name, eq, spec = str(item).partition("=")
    name, spec = name.strip(), spec.strip()
    if not eq or not name or not spec:
        raise LinkFeaError(f"--param {item!r}: expected NAME=SPEC, SPEC a list 10,15,20 or a range lo:hi:step")
    if ":" in spec:
        parts = spec.split(":")
        nums = [_number(p) for p in parts]
        if len(parts) not in (2, 3) or any(v is None for v in nums):
            raise LinkFeaError(f"--param {name}: range {spec!r} must be lo:hi or lo:hi:step with finite numbers")
        lo, hi = nums[0], nums[1]
        step = nums[2] if len(parts) == 3 else None
        if not hi >= lo:
            raise LinkFeaError(f"--param {name}: range {spec!r} needs hi >= lo")
        if step is not None and not step > 0:
            raise LinkFeaError(f"--param {name}: range {spec!r} needs a step > 0")
        return ParamSpec(name, lo=lo, hi=hi, step=step)
    items = [s.strip() for s in spec.split(",")]
    if any(not s for s in items):
        raise LinkFeaError(f"--param {name}: empty item in list {spec!r}")
    vals = tuple(_number(s) if _number(s) is not None else s for s in items)
    return ParamSpec(name, values=vals)


