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


#: where the cgroup file systems are mounted, and the file naming this process's cgroups
CGROUP_ROOT = "/sys/fs/cgroup"
CGROUP_OF_PROCESS = "/proc/self/cgroup"


def _read_number(path: str) -> Optional[float]:
    try:
        with open(path, encoding="ascii") as fh:
            text = fh.read().strip()
        return None if text in ("", "max") else float(text)
    except (OSError, ValueError):
        return None


def _cgroup_room() -> Optional[float]:
    """Bytes this process's memory cgroup (v2 ``memory.max``, v1 ``memory.limit_in_bytes``) still allows:
    its limit less its usage, the smallest over the places the cgroup may be seen (its own path, the
    container's root); None without a limit."""
    try:
        with open(CGROUP_OF_PROCESS, encoding="utf-8") as fh:
            lines = [ln.strip().split(":", 2) for ln in fh if ln.count(":") >= 2]
    except OSError:
        lines = []
    places = []
    for _, ctrl, rel in lines:
        rel = rel.lstrip("/")
        if ctrl == "":
            places += [(f"{CGROUP_ROOT}/{rel}".rstrip("/"), "memory.max", "memory.current")]
        elif "memory" in ctrl.split(","):
            places += [(f"{CGROUP_ROOT}/memory/{rel}".rstrip("/"), "memory.limit_in_bytes", "memory.usage_in_bytes")]
    places += [(CGROUP_ROOT, "memory.max", "memory.current"),
               (f"{CGROUP_ROOT}/memory", "memory.limit_in_bytes", "memory.usage_in_bytes")]
    room = None
    for d, limit_file, usage_file in places:
        lim = _read_number(f"{d}/{limit_file}")
        if lim is None or lim >= 2 ** 62:  # v1's "no limit" is a huge number
            continue
        left = lim - (_read_number(f"{d}/{usage_file}") or 0.0)
        room = left if room is None else min(room, left)
    return room


def memory_limit() -> float:
    """Bytes a new allocation of this process can get: the machine's available memory, bounded by the
    process's address-space limit (``RLIMIT_AS``, less what it maps already) and by its cgroup's memory
    limit (:func:`_cgroup_room`): a run in a container or under ``ulimit -v`` must be refused by the
    estimate, not end in a MemoryError."""
    lim = float(available_memory())
    try:
        import resource

        soft = resource.getrlimit(resource.RLIMIT_AS)[0]
        if soft != resource.RLIM_INFINITY:
            vm = 0.0
            with open("/proc/self/status", encoding="ascii") as fh:
                vm = next((float(ln.split()[1]) * 1024 for ln in fh if ln.startswith("VmSize:")), 0.0)
            lim = min(lim, soft - vm)
    except (ImportError, OSError, ValueError):
        pass
    room = _cgroup_room()
    return max(0.0, lim if room is None else min(lim, room))


def plan(what: str, n: float, bytes_per_item: float, seconds_per_item: float = SECONDS_PER_POINT,
         limit: Optional[float] = None, unit: str = "points",
         hint: str = "use fewer points (a coarser grid or a slice)", progress: Optional[Progress] = None) -> Plan:
    """The memory and time of a run over ``n`` items (``unit``), or VjmError if it cannot fit in memory.

    ``limit`` defaults to :data:`MEMORY_FRACTION` of the memory this process can get now
    (:func:`memory_limit`); the error names the estimate, the limit and what to do (``hint``).
    ``progress``: told the estimate before the work if the run is long (:attr:`Plan.long`).
    """
    memory = float(n) * bytes_per_item
    lim = MEMORY_FRACTION * memory_limit() if limit is None else float(limit)
    if memory > lim:  # before int(n): a count may be astronomically large (or inf)
        raise VjmError(f"{what} would need about {_gb(memory)} of memory for {float(n):.3g} {unit}, more than "
                       f"the {_gb(lim)} this machine can give it; {hint}")
    p = Plan(what, int(n), memory, float(n) * seconds_per_item)
    if progress is not None and p.long:
        progress(f"{p.describe()}; this will take a while")
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
