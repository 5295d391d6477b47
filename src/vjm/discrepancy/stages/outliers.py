"""Gross outliers: file rows the final model cannot have produced, set aside, and the diagnosis rerun.

A mistyped value or a probe that slipped puts one reading tens of sigmas off; a few such rows
make every effect fit them, inflate chi2 and name effects that are not there.  After a full
diagnosis the final model's residuals of *every* row are standardized: ``r / sigma`` with the
file's sigmas (then divided by the robust scale 1.4826 MAD of these standardized residuals where
that exceeds 1: a model wrong everywhere widens the whole distribution, it does not make outliers),
``r / (1.4826 MAD)`` with estimated sigmas.  An observation beyond :func:`threshold` (the Bonferroni
normal quantile over the n observations at :data:`FALSE_FLAG`, at least :data:`Z_MIN` robust
sigmas: a clean set flags nothing with probability >= 99 %) is an outlier, and its whole file row
is set aside.  The workflow (:func:`vjm.discrepancy.workflow.set_aside`) reruns the diagnosis on the
other rows and the residuals of all rows (those set aside included, predicted by the new model) are
judged again: rows may come back.  This repeats until the set aside is the set flagged (at most
:data:`MAX_PASSES` diagnoses); this module decides each step (:func:`first_look`, :func:`again`,
:func:`decide`).  The rows are set aside
only if the other rows then fit: where they still lack fit, the rows beyond the threshold are the
worst part of a gap the library lacks (a contact, a hysteresis), every row is kept and the plain
diagnosis reported, with a warning.

Breakdown point: the scale is a median absolute deviation (breakdown 50 %), but the fit itself is
least squares, trusted only once the outliers are set aside; each pass needs the model fitted
with the outliers still in to leave them beyond the threshold.  Up to :data:`UNTRUSTED` (10 %) of
the rows may be set aside; a set with more is reported ``untrusted_data`` (no effect named).
benchmarks/bench_diagnose_outliers.py measures how far the hidden effect is still named.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ... import effects as fx
from ...stats.fit import normal_upper
from ..predict import CALIBRATION, Predictor, apply_calibration
from .norms import robust_scale

#: probability that a clean set flags at least one observation (Bonferroni over the observations)
FALSE_FLAG = 0.01
#: the least threshold, in robust sigmas, whatever the number of observations
Z_MIN = 5.0
#: above this fraction of rows set aside, the data are not trusted
UNTRUSTED = 0.10
#: diagnoses run at most (the first, plain, one included)
MAX_PASSES = 4
#: flagged observations listed in the flags and the summary (report.json lists all)
SHOWN = 8


@dataclass(frozen=True)
class Outliers:
    """The rows set aside: positions into the data, and each flagged observation."""

    positions: tuple  # sorted positions (0-based) of the rows set aside, into the data of the first pass
    entries: list  # [{"row": file row, "component": name, "z": standardized residual}], by row
    n_rows: int  # rows of the data
    threshold: float  # |z| beyond which an observation is an outlier
    scale: float  # robust scale the residuals were divided by (in units of the stated sigmas, or whitened)
    passes: int  # diagnoses run
    settled: bool  # the set aside is the set the final model flags
    accepted: bool = True  # settled, and the other rows fit once they are set aside: gross errors
    #: the lack of fit can be judged (stated sigmas, or repeated rows): without it a row beyond the threshold
    #: cannot be told from the worst part of an effect the model lacks, so nothing is set aside
    judged: bool = True

    @property
    def rows(self) -> list:
        return sorted({e["row"] for e in self.entries})

    @property
    def fraction(self) -> float:
        return len(self.positions) / max(self.n_rows, 1)

    @property
    def untrusted(self) -> bool:
        return self.accepted and self.fraction > UNTRUSTED

    def record(self) -> dict:
        """report.json's ``outliers``."""
        return {"rows": self.rows, "n_rows": len(self.positions), "n_rows_total": self.n_rows,
                "fraction": self.fraction, "limit_fraction": UNTRUSTED, "threshold": self.threshold,
                "robust_scale": self.scale, "passes": self.passes, "settled": self.settled, "judged": self.judged,
                "observations": self.entries,
                "definition": "z = residual of the final model / (sigma x robust scale); robust scale = "
                              "1.4826 MAD of the standardized residuals (at least 1 with stated sigmas); "
                              f"outlier when |z| > threshold (Bonferroni over the observations at {FALSE_FLAG}, "
                              f"at least {Z_MIN:g}); the whole file row is set aside"}


def threshold(n: int) -> float:
    """|z| beyond which one of ``n`` standard normal observations is an outlier."""
    return max(Z_MIN, normal_upper(FALSE_FLAG / (2 * max(n, 1))))


def file_rows(data) -> np.ndarray:
    """The file row number of each row (header = row 1; in-memory data: as if written without comments)."""
    return np.asarray(data.rows) if data.rows is not None else np.arange(2, data.n + 2)


def _predictor(full, cur, names) -> Predictor | None:
    """A predictor of every row of ``full``'s data with the terms of ``cur`` (both problem Setups;
    None if one of ``names`` does not apply to the full data)."""
    if cur is full:
        return full.pred
    for nm in names:
        if nm != CALIBRATION and nm not in full.candidates and fx.get(nm).prepare(full.ctx):
            return None
    return Predictor(full.model, full.ctx, cur.pred.terms, cur.pred.fixed)


def whitened(full, cur, final):
    """(residual / sigma of every observation of the full data under ``cur``'s final fit, row position
    of each, component name of each), or None when the final model cannot predict the full data."""
    pred = _predictor(full, cur, final.names)
    if pred is None:
        return None
    return full.kind.whitened(full, pred, final)


def flag(full, cur, final, sigma_known: bool):
    """(positions of the rows holding an outlier, entries, threshold, scale), or None (see :func:`whitened`)."""
    w = whitened(full, cur, final)
    if w is None:
        return None
    r, pos, comp = w
    scale = robust_scale(r)
    if sigma_known:
        scale = max(scale, 1.0)
    z = r / scale
    thr = threshold(r.size)
    out = np.flatnonzero(np.abs(z) > thr)
    rows = file_rows(full.data)
    entries = [{"row": int(rows[pos[i]]), "component": comp[i], "z": float(z[i])}
               for i in sorted(out, key=lambda i: (pos[i], i))]
    return tuple(sorted({int(pos[i]) for i in out})), entries, thr, float(scale)


def first_look(full, final, sigma_known: bool, judged: bool = True):
    """The rows the first, plain, diagnosis (problem Setup ``full``, its final FitResult ``final``) flags:
    None when none is beyond the threshold (the plain diagnosis stands); an :class:`Outliers` when they
    are reported but kept (``judged`` False: the lack of fit cannot be judged, so the other rows' fit
    cannot say what they are); else the tuple of :func:`flag` to rerun the diagnosis without."""
    got = flag(full, full, final, sigma_known)
    if got is None or not got[0]:
        return None
    if not judged:
        rows = set(file_rows(full.data)[list(got[0])].tolist())
        return Outliers(got[0], [e for e in got[1] if e["row"] in rows], full.data.n, got[2], got[3], 1,
                        False, False, False)
    return got


def again(got, aside: tuple, seen: set, passes: int) -> bool:
    """Whether to diagnose again without the rows ``got`` flags: they are not the rows set aside, not a set
    tried before (a cycle), and fewer than :data:`MAX_PASSES` diagnoses ran."""
    return got is not None and got[0] != aside and got[0] not in seen and passes < MAX_PASSES


def kept_rows(full, aside: tuple):
    """The rows of ``full``'s data without the positions ``aside``."""
    keep = np.ones(full.data.n, bool)
    keep[list(aside)] = False
    return full.kind.subset(full.data, keep)


def decide(full, got, aside: tuple, passes: int, verdict: str) -> Outliers:
    """The rows set aside after the reruns: ``got`` what the last pass (``verdict`` its verdict) flags on
    every row of ``full``'s data, ``aside`` the rows it was run without.  Rows that are gross errors leave
    the others fitting once set aside (:attr:`Outliers.accepted`); a gap the library lacks does not (the
    rows beyond the threshold are its worst part, and setting them aside uncovers the next ones)."""
    if got is None:
        return Outliers(aside, [], full.data.n, threshold(0), float("nan"), passes, False, False)
    settled = got[0] == aside
    rows = set(file_rows(full.data)[list(aside)].tolist())
    return Outliers(aside, [e for e in got[1] if e["row"] in rows], full.data.n, got[2], got[3], passes, settled,
                    settled and verdict != "unexplained")


def flags(o: Outliers) -> list:
    """The warnings of the rows set aside (or of the rows beyond the threshold that were kept)."""
    if not o.judged:
        return [f"{len(o.positions)} of {o.n_rows} rows hold residuals beyond {o.threshold:.2f} robust sigmas; "
                "without stated sigmas or repeated rows the lack of fit cannot be judged, so they cannot be told "
                "from the worst part of an effect the model lacks: every row is kept (state sigma_t, sigma_r to "
                "have gross errors set aside)"]
    if not o.accepted:
        return [f"{len(o.positions)} of {o.n_rows} rows hold residuals beyond {o.threshold:.2f} robust sigmas, but "
                f"setting them aside {'does not make the other rows fit' if o.settled else 'uncovers more'} "
                f"({o.passes} diagnoses): they are part of the gap, not gross errors; every row is kept"]
    shown = ", ".join(f"{e['row']} ({e['component']}, z = {e['z']:+.1f})" for e in o.entries[:SHOWN])
    more = f" and {len(o.entries) - SHOWN} more (report.json: outliers)" if len(o.entries) > SHOWN else ""
    out = [f"{len(o.positions)} of {o.n_rows} rows ({100 * o.fraction:.1f} %) are gross outliers "
           f"(|standardized residual| > {o.threshold:.2f} robust sigmas) and were set aside; file rows "
           f"{shown}{more}; check them (a mistyped value, a probe that slipped, a row logged with another load)"]
    if o.untrusted:
        out.append(f"more than {100 * UNTRUSTED:.0f} % of the rows are outliers: the data cannot be trusted, "
                   "no effect is named")
    return out


def untrusted_model(s, baseline):
    """The model with the calibration only (what model_updated.yaml holds when the data are not trusted)."""
    return apply_calibration(s.model, s.pred.full_theta(CALIBRATION, baseline.term_theta(s.prob, CALIBRATION)))
