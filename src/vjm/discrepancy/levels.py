"""Load levels: the distinct magnitudes at which a data set applies its loads.

A design has *load levels* when its rows apply a few distinct load magnitudes
(e.g. ``vjm simulate --loads axes:50,100``: every direction at 50 N and at
100 N), as opposed to magnitudes spread continuously.  The magnitude of a
wrench is ``sqrt(|F|^2 + (|M| / ARM)^2)`` (N; a moment counts as the force
that makes it on a 100 mm arm), rounded to 4 significant digits.

Only with two or more levels can a compliance that changes with the load (a
hardening or softening spring, a preloaded clearance) be told apart from a
constant one: every linear effect of the library scales with the load, so the
same posture and direction must show the same compliance at every level.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: moment arm that turns a moment into a force magnitude, mm
ARM = 100.0
#: more distinct magnitudes than this: the loads are spread, not applied at levels
MAX_LEVELS = 8
#: each level needs at least this many rows
MIN_ROWS = 3


@dataclass(frozen=True)
class Levels:
    """The load levels of a data set: ``index`` (n,) level of each row, ``magnitude`` (k,) N, ascending."""

    index: np.ndarray
    magnitude: np.ndarray

    @property
    def count(self) -> int:
        return int(self.magnitude.size)


def load_magnitude(W) -> np.ndarray:
    """(n,) magnitude of each wrench (N): ``sqrt(|F|^2 + (|M| / ARM)^2)``."""
    W = np.atleast_2d(np.asarray(W, dtype=float))
    return np.sqrt(np.sum(W[:, :3] ** 2, axis=1) + np.sum((W[:, 3:] / ARM) ** 2, axis=1))


def _round(v, digits: int = 4) -> np.ndarray:
    """``v`` rounded to ``digits`` significant digits (0 stays 0)."""
    v = np.asarray(v, dtype=float)
    e = np.floor(np.log10(np.where(v > 0, v, 1.0)))
    return np.where(v > 0, np.round(v / 10.0 ** e, digits - 1) * 10.0 ** e, 0.0)


def load_levels(W) -> Levels | None:
    """The load levels of wrenches ``W`` (n, 6), or None when the rows do not apply 2 to MAX_LEVELS
    distinct non-zero magnitudes with at least MIN_ROWS rows each."""
    m = _round(load_magnitude(W))
    mags, index, counts = np.unique(m, return_inverse=True, return_counts=True)
    if not (2 <= mags.size <= MAX_LEVELS) or np.any(mags <= 0) or np.any(counts < MIN_ROWS):
        return None
    return Levels(index.ravel(), mags)


def parse_levels(text: str, what: str) -> list[float]:
    """``"50,100"`` -> [50.0, 100.0]: one or more finite positive numbers, comma-separated
    (ValueError naming ``what`` otherwise)."""
    out = []
    for item in text.split(","):
        try:
            v = float(item)
        except ValueError:
            raise ValueError(f"{what}: {item.strip()!r} is not a number") from None
        if not np.isfinite(v) or v <= 0:
            raise ValueError(f"{what}: {item.strip()!r} must be a finite number > 0")
        out.append(v)
    if len(set(out)) != len(out):
        raise ValueError(f"{what}: the magnitudes {text} repeat a value")
    return out


def by_level(levels: Levels, W, rnorm, mask) -> list[dict]:
    """Per level: magnitude (N), RMS of the normalized residuals, rows, and the RMS of the residual
    per unit load (normalized residual / magnitude x the largest magnitude): flat across levels when the
    gap scales with the load, as every linear effect's does."""
    r2 = np.where(mask, np.nan_to_num(rnorm) ** 2, 0.0).sum(axis=1)
    cnt = mask.sum(axis=1)
    out = []
    for j, mag in enumerate(levels.magnitude):
        sel = levels.index == j
        n = int(cnt[sel].sum())
        rms = float(np.sqrt(r2[sel].sum() / n)) if n else float("nan")
        out.append({"magnitude_N": float(mag), "rms_normalized": rms, "n": int(sel.sum())})
    return out


def growth_words(rows: list[dict]) -> str:
    """One clause: how the residual grows from the lowest to the highest level, against the load."""
    lo, hi = rows[0], rows[-1]
    load = hi["magnitude_N"] / lo["magnitude_N"]
    r0, r1 = lo["rms_normalized"], hi["rms_normalized"]
    levels = ", ".join(f"{r['rms_normalized']:.2f} at {r['magnitude_N']:.4g} N" for r in rows)
    if not (np.isfinite(r0) and np.isfinite(r1)) or r0 <= 0:
        return f"residual by load level: {levels}"
    g = r1 / r0
    how = ("faster than the load" if g > 1.3 * load else "about as the load" if g > 0.77 * load else
           "slower than the load" if g > 1.3 else "flat" if g > 0.77 else "shrinks")
    return f"residual by load level {levels}: x{g:.2f} for x{load:.3g} load ({how})"
