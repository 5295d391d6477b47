"""The diagnosis report as a typed value that serialises to report.json.

:class:`Report` holds one field per top-level key of report.json, in the
file's order; :meth:`Report.to_dict` gives the dictionary that is written.
It also reads like that dictionary (``rep["verdict"]``, ``rep.get(...)``,
``dict(rep)``).
"""
from __future__ import annotations

import dataclasses
import os
from collections.abc import Mapping
from dataclasses import dataclass

from ...stats.selection import OCCAM_WINDOW
from ..predict import CALIBRATION
from .calibrate import Calibration
from .candidates import Candidates
from .confounding import Confounding
from .goodness import Goodness
from .kinds import Located
from .observability import Observability
from .problem import Setup
from .select import Selected
from .verdict import Verdict

CHI2_DEFINITION = ("reduced chi-square: sum of squared normalized residuals / (n - fitted parameters); "
                   "'before' = nominal parameters recalibrated, no effect")


@dataclass(frozen=True)
class Report(Mapping):
    """What report.json holds (units: the data's; see ``rms_units``)."""

    model: str
    data: str
    data_kind: str  # "deflection" or "stiffness"
    n_observations: int
    n_postures: int
    named_effects: list
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
    calibration: dict
    calibration_held: dict
    final_params: dict
    localization: dict
    localization_after: dict
    candidates: dict
    verdict: str
    lack_of_fit: dict
    confounded: list
    alternatives: list
    alternatives_window: float
    confounding: list
    unobservable: dict
    dropped: dict
    flags: list
    n_tested: int
    suggest: dict | None = None  # present in report.json only when measurements were suggested
    summary: str = ""
    outliers: dict | None = None  # rows set aside as gross outliers (stages.outliers); None (null) when none were
    #: the noise: stated sigmas checked against the final residuals (stages/noise.py), or the estimated ones
    noise: dict = dataclasses.field(default_factory=dict)

    def to_dict(self) -> dict:
        """The report.json dictionary (keys in the file's order)."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)
                if not (f.name == "suggest" and self.suggest is None)}

    def __getitem__(self, key):
        return self.to_dict()[key]

    def __iter__(self):
        return iter(self.to_dict())

    def __len__(self) -> int:
        return len(self.to_dict())


def _candidate_entries(table: Candidates, conf: Confounding) -> dict:
    """The candidate entries with the calibration change that imitates each (where one does)."""
    return {nm: {**e, "mimicked_by_calibration": conf.mimicked[nm]} if nm in conf.mimicked else e
            for nm, e in table.entries.items()}


def build_report(s: Setup, cal: Calibration, obs: Observability, chosen: Selected, fit: Goodness, loc: Located,
                 table: Candidates, conf: Confounding, v: Verdict, *, model_name: str, alpha: float,
                 folds: int) -> Report:
    """The report of the stages (without ``suggest`` and ``summary``)."""
    sel, final, prob, w = chosen.sel, chosen.sel.final, s.prob, s.weights
    final_vals = final.values(prob)
    alternatives = [{"named_effects": list(x.selected), "delta_bic": float(x.final.bic - final.bic),
                     "chi2_red": float(x.final.chi2 / fit.s2 / max(x.final.dof, 1))} for x in chosen.explanations[1:]]
    return Report(
        model=model_name, data=os.path.basename(str(s.data.source)), data_kind=s.kind.name,
        n_observations=int(prob.n), n_postures=int(len(s.U)), named_effects=list(sel.selected),
        rms_before=loc.rms_before, rms_after=loc.rms_after, rms_nominal=loc.rms_nominal, rms_units=loc.units,
        chi2_before=fit.chi2_before, chi2_after=fit.chi2_after, chi2_nominal=fit.chi2_nominal,
        chi2_definition=CHI2_DEFINITION, sigma_source=w.source, sigma_known=bool(w.sigma_known),
        test="likelihood-ratio chi2 test" if w.sigma_known else (
            "likelihood-ratio test, variances of translations and rotations profiled" if prob.n_components > 1
            else "F test"),
        alpha=alpha, cv_baseline=sel.cv_baseline, cv_folds=folds,
        calibration=final_vals[CALIBRATION], calibration_held=cal.held, final_params=final_vals,
        localization=loc.before, localization_after=loc.after, candidates=_candidate_entries(table, conf),
        verdict=v.verdict, lack_of_fit=fit.lack_of_fit, confounded=conf.groups, alternatives=alternatives,
        alternatives_window=OCCAM_WINDOW, confounding=conf.details, unobservable=obs.unobservable,
        dropped=table.dropped, flags=v.flags, n_tested=len(obs.tested))
