"""Rows that no model of the library explains, set aside rather than fitted: a marker swapped between
hands, a reflector lost to another one, a mistyped row.

A gross error pulls a least-squares fit everywhere and makes the F tests name effects that are not there.
:func:`calibrate_robust` fits (:func:`vjm.calibration.engine.calibrate`), sets aside the rows whose position
error exceeds ``ratio`` times the median error of the rows kept, and fits again on the others from the
start (registration included), until the set aside no longer changes.  With Gaussian noise the error
norm is Maxwell-distributed: its median is 1.54 sigma and 4.5 medians (6.9 sigma) are passed by one row
in 1e10, so clean data lose no row; a real set whose errors are model errors (the UR10's, max/median
about 3.5) loses none either.  The rows set aside are listed in the calibration (``set_aside``).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from .engine import calibrate, position_errors
from .result import Calibration


def outlying(errors: np.ndarray, kept: np.ndarray, ratio: float) -> np.ndarray:
    """Rows (a mask) whose error exceeds ``ratio`` times the median error of the ``kept`` rows."""
    return errors > ratio * float(np.median(errors[kept]))


def calibrate_robust(model, data, frame: str | tuple | None = None, ratio: float = 4.5, rounds: int = 4,
                     fit=None, **kw) -> Calibration:
    """:func:`~vjm.calibration.engine.calibrate` with outlying rows set aside (see the module docstring);
    ``fit(model, data, frame, **kw)`` another calibration (a parallel machine's,
    :func:`vjm.calibration.parallel_fit.calibrate_platform`)."""
    calibrate_ = fit or calibrate
    kept = np.ones(data.n, dtype=bool)
    cal = calibrate_(model, data, frame, **kw)
    for _ in range(rounds):
        e = position_errors(cal, data)
        new = ~outlying(e, kept, ratio)
        if np.array_equal(new, kept):
            break
        kept = new
        cal = calibrate_(model, data.subset(kept), frame, **kw)
    return replace(cal, set_aside=tuple(int(i) for i in np.flatnonzero(~kept)))
