"""Next measurements (on request): the (posture, load) rows that best separate what this data could not
(:mod:`vjm.discrepancy.suggest`)."""
from __future__ import annotations

from dataclasses import dataclass

from ..suggest import Findings, Suggestion, suggest
from .candidates import Candidates
from .confounding import Confounding
from .goodness import Goodness
from .observability import Observability
from .problem import Setup
from .select import Selected


@dataclass(frozen=True)
class Suggested:
    """The suggested rows, and how they were asked for."""

    suggestion: Suggestion
    n: int
    forces_only: bool

    @property
    def rows(self):
        return self.suggestion.rows

    def record(self) -> dict:
        """report.json's ``suggest``."""
        sg = self.suggestion
        return {"n": self.n, "file": "next_measurements.csv", "criterion": sg.criterion, "targets": sg.targets,
                "criterion_before": sg.before, "criterion_after": sg.after, "forces_only": self.forces_only,
                "rows_to_separate": sg.rows_to_separate}


def next_measurements(s: Setup, obs: Observability, chosen: Selected, fit: Goodness, table: Candidates,
                      conf: Confounding, untrusted: bool, n: int, forces_only: bool) -> Suggested:
    """``n`` (posture, load) rows that best separate what this data could not (``untrusted``: the rows set
    aside as gross outliers make the data untrusted, so nothing counts as named or confounded).
    Stiffness observations have no loads to design (VjmError)."""
    scales = s.kind.design_scales(s.data, s.weights, fit.scales)
    prob, final = s.prob, chosen.sel.final
    first = chosen.first_round
    vals = {nm: first[nm]["fit"].term_theta(prob, nm) for nm in s.candidates if nm in first}
    for nm in final.names:
        vals[nm] = final.term_theta(prob, nm)
    found = Findings(named=() if untrusted else tuple(chosen.sel.selected),
                     confounded=() if untrusted else tuple(tuple(g) for g in conf.groups),
                     p_values={nm: e.get("p_value") for nm, e in table.entries.items()},
                     unobservable=tuple(obs.unobservable))
    return Suggested(suggest(s.model, s.pred, scales, vals, found, int(n), forces_only), int(n), bool(forces_only))
