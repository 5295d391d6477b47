"""The memory at hand and how big and long things are, in words: one home for linkfea and vjm."""
from __future__ import annotations

import os


def available_memory() -> int:
    """Bytes of memory available to a new allocation now (Linux ``MemAvailable``), else the physical
    memory, else 8 GiB."""
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):
        return 8 << 30


def human_bytes(n: float) -> str:
    """``1.5e10`` -> ``'15 GB'`` (decimal units, as Dask's memory limits)."""
    for unit, f in (("PB", 1e15), ("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= f:
            return f"{n / f:.3g} {unit}"
    return f"{n:.0f} B"


def human_duration(s: float) -> str:
    """``90`` -> ``'1.5 min'``, ``4e8`` -> ``'13 years'``."""
    for unit, f in (("years", 3.156e7), ("days", 86400.0), ("h", 3600.0), ("min", 60.0)):
        if s >= f:
            return f"{s / f:.2g} {unit}"
    return f"{s:.0f} s"
