"""How big a sweep is and how long it takes: design count, memory of its bookkeeping, expected
time before the start, and the progress bar during the run.

The designs are counted arithmetically from the ``--param`` specs (or ``--sample N``), so a
grid of 10^8 designs is refused in milliseconds, never materialised.  Each design costs the
client memory whatever its mesh: its :class:`~linkfea.sweep.Design` and key (about 4.3 kB,
measured with tracemalloc on a 20,000-design grid), its table row (3.0 kB) and its Dask task
(the future, the scheduler's task state and the pickled task, which carries the source bytes:
about 8 kB plus the source's size, an estimate).  A sweep whose bookkeeping exceeds half the
memory available now (the other half is for the workers' FEA) is refused, naming both figures.

The time is the number of designs times the seconds per design, divided among the workers:
the median of the designs already computed in this output folder, or, for a new sweep,
:data:`NOMINAL_SECONDS` (a bundled link at its default mesh, the CAD included).  Above
:data:`ANNOUNCE_SECONDS` the run says how long it expects to take before it starts.
"""
from __future__ import annotations

import math
import os
import statistics
from dataclasses import dataclass
from typing import Callable

from ..runtime.errors import LinkFeaError
from ..runtime.memory import available_memory, human_bytes, human_duration

BYTES_PER_DESIGN = 16_000
"""Client and scheduler memory per design besides the source bytes (see the module docstring)."""

MEMORY_SHARE = 0.5
"""Share of the available memory a sweep's bookkeeping may take."""

NOMINAL_SECONDS = 10.0
"""Seconds per design before any has run: ``linkfea compute bar`` at its default mesh takes 13 s
on this 2-core machine under load, 9 s of it the CAD import a worker pays once."""

UNCOUNTABLE = 10 ** 18
"""Design counts from here on are not worth spelling out (a product of such counts stays exact)."""

ANNOUNCE_SECONDS = 60.0
"""A run expected to take longer than this says so before it starts."""


@dataclass(frozen=True)
class SweepSize:
    """The size of a sweep: designs, the memory they need here, and the limit."""

    n_designs: int
    memory: float
    memory_limit: float

    def check(self) -> None:
        """Refuse a sweep whose bookkeeping cannot fit in memory, with one line naming the figures."""
        if self.n_designs >= UNCOUNTABLE:
            fit = self.memory_limit / self.memory * self.n_designs
            raise LinkFeaError(f"more than {UNCOUNTABLE:.0e} designs are too "
                               f"many: the limit is the memory for about {fit:,.0f} designs (half the memory "
                               "available now); use fewer values, a coarser step or --sample N")
        if self.memory > self.memory_limit:
            raise LinkFeaError(
                f"{self.n_designs:,} designs are too many: the sweep needs about {human_bytes(self.memory)} of "
                f"memory for them (limit {human_bytes(self.memory_limit)}, half the memory available now) and "
                f"would take about {human_duration(self.n_designs * NOMINAL_SECONDS / (os.cpu_count() or 1))} at "
                f"~{NOMINAL_SECONDS:g} s per design; use fewer values, a coarser step or --sample N")


def sweep_size(n_designs: int, source_bytes: int, limit: float | None = None) -> SweepSize:
    """The :class:`SweepSize` of ``n_designs`` (``limit`` default: a share of :func:`available_memory`)."""
    lim = MEMORY_SHARE * available_memory() if limit is None else float(limit)
    return SweepSize(int(n_designs), float(n_designs) * (BYTES_PER_DESIGN + source_bytes), lim)


def range_count(lo: float, hi: float, step: float) -> int:
    """Values ``lo, lo+step, ... <= hi`` (with a 1e-9 step tolerance), counted without listing them.

    A ratio too large for a float (``1:2:1e-320``) or above 10**18 counts as :data:`UNCOUNTABLE`.
    """
    q = (hi - lo) / step
    if not math.isfinite(q) or q > UNCOUNTABLE:
        return UNCOUNTABLE
    return int(math.floor(q + 1e-9)) + 1


def expected_seconds(n: int, workers: int, per_design: float | None) -> float:
    """Wall time of ``n`` designs on ``workers``: whole rounds of ``per_design`` seconds."""
    w = max(int(workers), 1)
    return math.ceil(n / w) * (NOMINAL_SECONDS if per_design is None else per_design)


def median_seconds(docs, at_most: int = 50) -> float | None:
    """Median ``sweep.seconds`` of (at most ``at_most``) stored design documents; None skipped, None if none."""
    t: list[float] = []
    for d in docs:
        if d is not None and isinstance(d["sweep"].get("seconds"), (int, float)):
            t.append(float(d["sweep"]["seconds"]))
            if len(t) >= at_most:
                break
    return float(statistics.median(t)) if t else None


def announcement(n: int, workers: int, per_design: float | None) -> str | None:
    """The line said before a long run, or None for a short one."""
    t = expected_seconds(n, workers, per_design)
    if t <= ANNOUNCE_SECONDS:
        return None
    how = "measured on this sweep's designs" if per_design is not None else "a first guess"
    each = NOMINAL_SECONDS if per_design is None else per_design
    return (f"{n:,} designs to compute on {workers} worker{'s' if workers != 1 else ''}, about {each:.3g} s each "
            f"({how}): about {human_duration(t)}; Ctrl-C stops, a rerun resumes")


class DesignProgress:
    """A rich progress bar on stderr: designs done, failed, elapsed and remaining time."""

    def __init__(self, total: int):
        from rich.console import Console
        from rich.progress import (
            BarColumn,
            MofNCompleteColumn,
            Progress,
            TextColumn,
            TimeElapsedColumn,
            TimeRemainingColumn,
        )

        self.nfail = 0
        self.p = Progress(TextColumn("designs"), BarColumn(), MofNCompleteColumn(), TextColumn("{task.fields[f]}"),
                          TimeElapsedColumn(), TimeRemainingColumn(), console=Console(stderr=True))
        self.t = self.p.add_task("sweep", total=total, f="")
        self.p.start()

    def advance(self, ok: bool = True):
        self.nfail += not ok
        self.p.update(self.t, advance=1, f=f"{self.nfail} failed" if self.nfail else "")

    def stop(self):
        self.p.stop()


class LineProgress:
    """The progress of a sweep as lines to a callback: one per finished design (done, failed, of total)."""

    def __init__(self, total: int, progress: Callable[[str], None]):
        self.total, self.progress, self.done, self.nfail = total, progress, 0, 0

    def advance(self, ok: bool = True):
        self.done += 1
        self.nfail += not ok
        self.progress(f"designs {self.done}/{self.total}" + (f", {self.nfail} failed" if self.nfail else ""))

    def stop(self):
        pass


def check_memory_limit(text) -> None:
    """``--memory-limit``: ``auto``, ``0`` (no limit) or a size such as ``4GB``, else one line naming it."""
    if str(text) == "auto":
        return
    from dask.utils import parse_bytes

    try:
        n = parse_bytes(text)
    except (ValueError, TypeError):
        raise LinkFeaError(f"--memory-limit: cannot read {text!r}; use auto, 0 (no limit) or a size such as 4GB") \
            from None
    if n < 0:
        raise LinkFeaError(f"--memory-limit must be auto, 0 (no limit) or a positive size such as 4GB, got {text!r}")
