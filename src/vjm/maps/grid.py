"""The one home of a model's workspace grid, and of the work a grid asks for.

:class:`Workspace` is the box a model's maps, sweeps and simulated experiments cover
(``geometry.workspace`` if the model gives one, else the architecture's box);
:meth:`Workspace.grid` lays a regular grid over it (optionally one axis fixed, ``z=0``).
:func:`plan` estimates the memory and time of a run over many points before it starts:
it refuses what cannot fit in memory (naming the estimate and the limit) and, for a run
longer than :data:`LONG_SECONDS`, says how long it will take and reports progress.

>>> import vjm
>>> m = vjm.load_model("puu")
>>> g = m.grid(5, slice="z=0")
>>> g.shape, g.points.shape
((5, 5, 1), (25, 3))
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable, Optional

import numpy as np

from linkfea.runtime.memory import available_memory, human_duration
from linkfea.runtime.progress import Progress

from ..errors import ArgumentError, VjmError

#: a run estimated to take longer than this (s) says so first and reports its progress
LONG_SECONDS = 60.0
#: fraction of the available memory a run may plan to use
MEMORY_FRACTION = 0.8
#: points evaluated per step of a long run (progress is reported between steps)
CHUNK = 65536
#: seconds between two progress lines of a long run
PROGRESS_EVERY = 10.0

#: bytes a map holds per grid point: the point (24), K (288), k_tran, k_rot, the mask, the
#: grid's own construction (meshgrid + stack, 72) and a margin for the PNG and .npz writers
MAP_BYTES = 480
#: bytes per point of a machine sweep: the points and one full stiffness map (K, C, ranks ...)
SWEEP_BYTES = 800
#: bytes per simulated measurement row: posture, load, deflection, sigmas, its compliance (288)
#: and the temporaries of the prediction
SIMULATE_BYTES = 900
#: conservative seconds per point of a stiffness evaluation when no probe has run yet
SECONDS_PER_POINT = 2e-5



def parse_slice(text: str) -> tuple[int, float]:
    """``"z=0"`` -> ``(2, 0.0)``: the fixed axis index and its value in mm."""
    try:
        name, val = str(text).split("=")
        k, v = "xyz".index(name.strip()), float(val)
    except ValueError:
        k, v = -1, float("nan")
    if k < 0 or not np.isfinite(v):
        raise ArgumentError("slice", f"expects axis=value (x, y or z = a finite number of mm), e.g. z=0, "
                                     f"got {text!r}")
    return k, v


@dataclass(frozen=True)
class Grid:
    """A regular grid: ``axes`` (three 1-D arrays, mm) and the ``(axis, value)`` of a slice, or None."""

    axes: tuple
    fixed: Optional[tuple] = None

    @property
    def shape(self) -> tuple[int, int, int]:
        return tuple(len(a) for a in self.axes)  # type: ignore[return-value]

    @property
    def size(self) -> int:
        return int(np.prod(self.shape, dtype=np.int64))

    @property
    def points(self) -> np.ndarray:
        """The grid points (size, 3), in the order of ``np.meshgrid(*axes, indexing="ij")``
        (VjmError, before any allocation, if they cannot fit in memory)."""
        plan(f"a {'x'.join(map(str, self.shape))} grid", self.size, 72)
        return np.stack(np.meshgrid(*self.axes, indexing="ij"), axis=-1).reshape(-1, 3)


@dataclass(frozen=True)
class Workspace:
    """A box ``lo``..``hi`` (each (3,), mm)."""

    lo: np.ndarray
    hi: np.ndarray

    @classmethod
    def of(cls, model) -> "Workspace":
        """The model's box: ``geometry.workspace`` (``[lo, hi]`` a cube, or ``[[x, y, z], [x, y, z]]``)
        if the model gives one, else its architecture's (a described machine's own)."""
        ws = model.geometry.get("workspace")
        if ws is None:
            lo, hi = model.arch.workspace
        else:
            try:
                lo, hi = ws
            except (TypeError, ValueError):
                raise VjmError(f"geometry.workspace must be [lo, hi] (mm), got {ws!r}") from None
        lo, hi = (np.broadcast_to(np.asarray(v, dtype=float), (3,)).copy() for v in (lo, hi))
        if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)) and np.all(hi > lo)):
            raise VjmError(f"the workspace box needs finite corners with lo < hi, got {lo.tolist()}, {hi.tolist()}")
        return cls(lo, hi)

    def grid(self, n: int, slice: Optional[str] = None) -> Grid:
        """An n-point-per-axis grid over the box (n = 1: the ``lo`` corner); ``slice`` (``"z=0"``) fixes one axis."""
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
            raise VjmError(f"a workspace grid needs a whole number >= 1 of points per axis, got {n!r}")
        fixed = parse_slice(slice) if slice else None
        axes = [np.linspace(self.lo[k], self.hi[k], int(n)) for k in range(3)]
        if fixed is not None:
            axes[fixed[0]] = np.array([fixed[1]])
        return Grid(tuple(axes), fixed)

    def random(self, n: int, rng) -> np.ndarray:
        """n uniform random points (n, 3) in the box."""
        return self.lo + (self.hi - self.lo) * rng.random((n, 3))


def _gb(b: float) -> str:
    return f"{b / 1e9:.3g} GB"


@dataclass(frozen=True)
class Plan:
    """What a run over ``n`` items (points, rows) will ask for: ``memory`` bytes and ``seconds``."""

    what: str
    n: int
    memory: float
    seconds: float

    @property
    def long(self) -> bool:
        return self.seconds > LONG_SECONDS

    def describe(self) -> str:
        return f"{self.what}: {self.n:,} points, about {_gb(self.memory)} of memory and {human_duration(self.seconds)}"


def plan(what: str, n: float, bytes_per_item: float, seconds_per_item: float = SECONDS_PER_POINT,
         limit: Optional[float] = None, unit: str = "points",
         hint: str = "use fewer points (a coarser grid or a slice)") -> Plan:
    """The memory and time of a run over ``n`` items (``unit``), or VjmError if it cannot fit in memory.

    ``limit`` defaults to :data:`MEMORY_FRACTION` of the memory available now; the error names
    the estimate, the limit and what to do (``hint``).
    """
    memory = float(n) * bytes_per_item
    lim = MEMORY_FRACTION * available_memory() if limit is None else float(limit)
    if memory > lim:  # before int(n): a count may be astronomically large (or inf)
        raise VjmError(f"{what} would need about {_gb(memory)} of memory for {float(n):.3g} {unit}, more than "
                       f"the {_gb(lim)} this machine can give it; {hint}")
    p = Plan(what, int(n), memory, float(n) * seconds_per_item)
    return p


def grid_plan(n: int, slice: Optional[str], what: str, bytes_per_point: float = MAP_BYTES,
              hint: str = "use a coarser grid or a slice") -> Plan:
    """:func:`plan` for an n-per-axis grid (one axis fixed by ``slice``), checked before it is built."""
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 2:
        raise VjmError(f"a workspace grid needs a whole number >= 2 of points per axis, got {n!r}")
    size = int(n) ** (2 if slice else 3)
    return plan(f"{what} ({n} per axis{', ' + slice if slice else ''})", size, bytes_per_point, hint=hint)


def in_chunks(n: int, step: Callable[[slice], None], progress: Optional[Progress] = None,
              what: str = "points", chunk: Optional[int] = None) -> None:
    """Run ``step(slice(a, b))`` over ``0..n`` in chunks; once the first chunk shows the whole run will
    take longer than :data:`LONG_SECONDS`, say so through ``progress`` and report each later chunk."""
    chunk = CHUNK if chunk is None else chunk
    t0 = last = time.perf_counter()
    loud = False
    for a in range(0, n, chunk):
        b = min(n, a + chunk)
        step(slice(a, b))
        if progress is None or b == n:
            continue
        spent = time.perf_counter() - t0
        left = spent * (n - b) / b
        if not loud and spent + left > LONG_SECONDS:
            loud = True
            progress(f"{n:,} {what}: this will take about {human_duration(spent + left)}")
        if loud and t0 + spent - last >= PROGRESS_EVERY * (last > t0):
            last = t0 + spent
            progress(f"{100 * b / n:.0f}% ({b:,} of {n:,} {what}), about {human_duration(left)} left")
    if loud and progress is not None:
        progress(f"100% ({n:,} {what}) in {human_duration(time.perf_counter() - t0)}")
