"""The diagnosis report as a typed value that serialises to report.json, assembled once.

:class:`Report` holds one field per top-level key of report.json, in the
file's order; :meth:`Report.to_dict` gives the dictionary that is written.
It also reads like that dictionary (``rep["verdict"]``, ``rep.get(...)``,
``dict(rep)``: fresh copies).  :func:`assemble` builds it from the stages'
values at the end of the workflow; its members are frozen (read-only
mappings, tuples, read-only arrays), so nothing can change it afterwards.
"""
from __future__ import annotations

import dataclasses
import os
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any, cast

import numpy as np

from ...stats.selection import OCCAM_WINDOW
from ..predict import CALIBRATION
from ..summary import summary
from .calibrate import Baseline
from .candidates import Candidates
from .confounding import Confounding
from .design import Suggested
from .goodness import Goodness
from .kinds import Located
from .load_levels import LevelTest
from .noise import NoiseCheck, estimated
from .observability import Observability
from .outliers import Outliers
from .outliers import flags as outlier_flags
from .problem import Setup
from .select import Selected
from .verdict import Verdict

CHI2_DEFINITION = ("reduced chi-square: sum of squared normalized residuals / (n - fitted parameters); "
                   "'before' = nominal parameters recalibrated, no effect")


class FrozenReport(Mapping):
    """A report as a typed, frozen value (a frozen dataclass subclasses this): one field per top-level key
    of report.json, in the file's order; :meth:`to_dict` gives the dictionary that is written, and it reads
    like that dictionary (``rep["verdict"]``, ``rep.get(...)``, ``dict(rep)``: fresh copies).  The fields
    named in ``OPTIONAL`` are left out of the file when None."""

    OPTIONAL: tuple = ()

    def __post_init__(self):
        for f in dataclasses.fields(cast(Any, self)):  # frozen all the way down: the report is assembled once
            object.__setattr__(self, f.name, frozen(getattr(self, f.name)))

    def _keys(self) -> list:
        """report.json's keys, in the file's order."""
        return [f.name for f in dataclasses.fields(cast(Any, self)) if not (f.name in self.OPTIONAL and getattr(self, f.name) is None)]

    def to_dict(self) -> dict:
        """The report.json dictionary (keys in the file's order): a fresh, mutable copy."""
        return {k: thawed(getattr(self, k)) for k in self._keys()}

    def __getitem__(self, key):
        if key not in self._keys():
            raise KeyError(key)
        return thawed(getattr(self, key))  # a copy, as to_dict's

    def __iter__(self):
        return iter(self._keys())

    def __len__(self) -> int:
        return len(self._keys())


@dataclass(frozen=True)
class Report(FrozenReport):
    """What report.json holds of the stages' diagnosis (units: the data's; see ``rms_units``); mappings and sequences frozen
    (read-only mappings, tuples), numbers and strings as they are."""

    model: str
    data: str
    data_kind: str  # "deflection" or "stiffness"
    n_observations: int
    n_postures: int
    named_effects: tuple
    rms_before: float
    rms_after: float
    rms_nominal: float
    rms_units: str
    chi2_before: float
    chi2_after: float
    chi2_nominal: float
    chi2_definition: str
    sigma_source: str
    sigma_known: bool
    test: str
    alpha: float
    cv_baseline: float
    cv_folds: int
    calibration: Mapping
    calibration_held: Mapping
    final_params: Mapping
    localization: Mapping
    localization_after: Mapping
    candidates: Mapping
    verdict: str
    lack_of_fit: Mapping
    confounded: tuple
    alternatives: tuple
    alternatives_window: float
    confounding: tuple
    unobservable: Mapping
    dropped: Mapping
    flags: tuple
    n_tested: int
    suggest: Mapping | None = None  # present in report.json only when measurements were suggested
    summary: str = ""
    outliers: Mapping | None = None  # rows set aside as gross outliers (stages.outliers); None (null) when none were
    #: the noise: stated sigmas checked against the final residuals (stages/noise.py), or the estimated ones
    noise: Mapping = dataclasses.field(default_factory=dict)

    OPTIONAL = ("suggest",)


def frozen(x):
    """``x`` with every dictionary made a read-only mapping, every list a tuple, every array read-only."""
    if isinstance(x, Mapping):
        return MappingProxyType({k: frozen(v) for k, v in x.items()})
    if isinstance(x, (list, tuple)):
        return tuple(frozen(v) for v in x)
    if isinstance(x, np.ndarray):
        x = x.copy()
        x.setflags(write=False)
    return x


def thawed(x):
    """The mutable copy of a :func:`frozen` value (mappings as dicts, tuples as lists)."""
    if isinstance(x, Mapping):
        return {k: thawed(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [thawed(v) for v in x]
    if isinstance(x, np.ndarray):
        return x.copy()
    return x


def candidate_entries(table: Candidates, conf: Confounding) -> dict:
    """The candidate entries with the calibration change that imitates each (where one does)."""
    return {nm: {**e, "mimicked_by_calibration": conf.mimicked[nm]} if nm in conf.mimicked else e
            for nm, e in table.entries.items()}


@dataclass(frozen=True)
class Pass:
    """The values of the stages of one run on one set of rows, in run order."""

    s: Setup
    baseline: Baseline
    obs: Observability
    chosen: Selected
    fit: Goodness
    noise: NoiseCheck | None  # the stated sigmas checked (None: not stated, or not deflection data)
    levels: LevelTest | None  # the load-level test (None: the data have no load levels)
    loc: Located
    table: Candidates
    conf: Confounding
    verdict: Verdict

    @property
    def final(self):
        return self.chosen.sel.final

    @property
    def scale(self) -> tuple | None:
        """The factors the stated sigmas were widened by (None: not stated)."""
        return self.noise.scale if self.noise is not None else None


def assemble(p: Pass, found: Outliers | None, suggested: Suggested | None, *, model_name: str, alpha: float,
             folds: int) -> Report:
    """The report of the run ``p`` (the one reported), the rows set aside as gross outliers (``found``, or
    None) and the suggested measurements (or None), built once: its summary is written from the same values.
    Rows set aside in more than :data:`~.outliers.UNTRUSTED` of the data: verdict ``untrusted_data``, no
    effect named, the calibration-only fit's parameters."""
    s, chosen, fit, conf, v = p.s, p.chosen, p.fit, p.conf, p.verdict
    sel, final, prob, w = chosen.sel, chosen.sel.final, s.prob, s.weights
    final_vals = final.values(prob)
    alternatives = [{"named_effects": list(x.selected), "delta_bic": float(x.final.bic - final.bic),
                     "chi2_red": float(x.final.chi2 / fit.s2 / max(x.final.dof, 1))} for x in chosen.explanations[1:]]
    untrusted = found is not None and found.untrusted
    f = dict(
        model=model_name, data=os.path.basename(str(s.data.source)), data_kind=s.kind.name,
        n_observations=int(prob.n), n_postures=int(len(s.U)), named_effects=[] if untrusted else list(sel.selected),
        rms_before=p.loc.rms_before, rms_after=p.loc.rms_after, rms_nominal=p.loc.rms_nominal, rms_units=p.loc.units,
        chi2_before=fit.chi2_before, chi2_after=fit.chi2_after, chi2_nominal=fit.chi2_nominal,
        chi2_definition=CHI2_DEFINITION, sigma_source=w.source, sigma_known=bool(w.sigma_known),
        test="likelihood-ratio chi2 test" if w.sigma_known else (
            "likelihood-ratio test, variances of translations and rotations profiled" if prob.n_components > 1
            else "F test"),
        alpha=alpha, cv_baseline=sel.cv_baseline, cv_folds=folds,
        calibration=final_vals[CALIBRATION], calibration_held=p.baseline.held,
        final_params=sel.baseline.values(prob) if untrusted else final_vals,
        localization=p.loc.before, localization_after=p.loc.after, candidates=candidate_entries(p.table, conf),
        verdict="untrusted_data" if untrusted else v.verdict,
        # the load-level test completes the lack of fit
        lack_of_fit=fit.lack_of_fit if p.levels is None else {**fit.lack_of_fit, "load_levels": p.levels.record()},
        confounded=[] if untrusted else conf.groups, alternatives=[] if untrusted else alternatives,
        alternatives_window=OCCAM_WINDOW, confounding=conf.details, unobservable=p.obs.unobservable,
        dropped=p.table.dropped,
        flags=(outlier_flags(found) if found is not None else []) + v.flags + (p.noise.flags if p.noise else []),
        n_tested=len(p.obs.tested), suggest=suggested.record() if suggested is not None else None,
        outliers=found.record() if found is not None and found.accepted else None,
        noise=p.noise.record() if p.noise is not None else estimated(s, fit.scales))
    return Report(**f, summary=summary(f))
