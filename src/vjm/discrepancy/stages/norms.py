"""Scalar summaries of residuals: RMS, a robust scale, RMS per posture."""
from __future__ import annotations

import numpy as np


def rms(x) -> float:
    """Root mean square of the finite entries of ``x`` (NaN when there are none)."""
    x = np.asarray(x, float)
    x = x[np.isfinite(x)]
    return float(np.sqrt(np.mean(x * x))) if x.size else float("nan")


def robust_scale(r) -> float:
    """1.4826 x the median absolute deviation of the finite entries (the RMS if that is 0; 1 if none)."""
    r = r[np.isfinite(r)]
    if r.size == 0:
        return 1.0
    s = 1.4826 * np.median(np.abs(r - np.median(r)))
    return float(s if s > 0 else max(np.sqrt(np.mean(r * r)), 1e-300))


def per_pose(rn, mask, idx, m) -> np.ndarray:
    """(m,) RMS of the normalized residuals ``rn`` (n, k) of each of ``m`` postures (measured components only)."""
    r2 = np.where(mask, np.nan_to_num(rn) ** 2, 0.0).sum(axis=1)
    c = mask.sum(axis=1)
    num = np.bincount(idx, r2, minlength=m)
    den = np.bincount(idx, c, minlength=m)
    return np.sqrt(num / np.maximum(den, 1))
