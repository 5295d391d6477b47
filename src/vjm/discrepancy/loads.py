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


def by_level(levels: Levels, W, rnorm, mask, tnorm=None) -> list[dict]:
    """Per level: magnitude (N), RMS of the normalized residuals, rows, and (given the model's own
    normalized deflections ``tnorm``) ``along_model``: the least-squares factor of the residual along
    the model's deflection, i.e. how much more compliant than the model the data are at that level
    (0.02: 2 % softer), and its standard deviation under noise alone ``along_model_se``.  Every
    linear effect gives the same factor at every level."""
    rn = np.where(mask, np.nan_to_num(rnorm), 0.0)
    r2 = (rn ** 2).sum(axis=1)
    cnt = mask.sum(axis=1)
    tn = None if tnorm is None else np.where(mask, np.nan_to_num(tnorm), 0.0)
    out = []
    for j, mag in enumerate(levels.magnitude):
        sel = levels.index == j
        n = int(cnt[sel].sum())
        row = {"magnitude_N": float(mag), "rms_normalized": float(np.sqrt(r2[sel].sum() / n)) if n else float("nan"),
               "n": int(sel.sum())}
        if tn is not None:
            tt = float(np.sum(tn[sel] ** 2))
            row["along_model"] = float(np.sum(rn[sel] * tn[sel]) / tt) if tt > 0 else float("nan")
            row["along_model_se"] = float(1.0 / np.sqrt(tt)) if tt > 0 else float("nan")  # noise alone
        out.append(row)
    return out


def growth_words(rows: list[dict]) -> str:
    """One clause: the residual per level, and how the data's compliance against the model's changes
    from the lowest to the highest level (where known)."""
    levels = ", ".join(f"{r['rms_normalized']:.2f} at {r['magnitude_N']:.4g} N" for r in rows)
    out = f"normalized residual by load level {levels}"
    if all("along_model" in r and np.isfinite(r["along_model"]) for r in rows):
        lo, hi = rows[0]["along_model"], rows[-1]["along_model"]
        se = 2.0 * float(np.hypot(rows[0]["along_model_se"], rows[-1]["along_model_se"]))  # ~95 % of noise
        along = ", ".join(f"{100 * r['along_model']:+.2f} %" for r in rows)
        how = ("the data grow softer with the load than the model" if hi - lo > se else
               "the data grow stiffer with the load than the model" if lo - hi > se else
               "the same at every level within the noise, as a linear effect gives")
        out += f"; compliance beyond the model's along its deflection {along}: {how}"
    return out
