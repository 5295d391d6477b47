"""Stage 9 (on request): the measurements to make next (:mod:`vjm.discrepancy.suggest`)."""
from __future__ import annotations

import dataclasses

from ..suggest import Suggestion, suggest
from .goodness import Goodness
from .problem import Setup
from .record import Report
from .select import Selected


def next_measurements(s: Setup, chosen: Selected, fit: Goodness, rep: Report, n: int,
                      forces_only: bool) -> tuple[Suggestion, Report]:
    """``n`` (posture, load) rows that best separate what this data could not; the report with its
    ``suggest`` entry.  Stiffness observations have no loads to design (VjmError)."""
    scales = s.kind.design_scales(s.data, s.weights, fit.scales)
    prob, final = s.prob, chosen.sel.final
    first = chosen.first_round
    vals = {nm: first[nm]["fit"].term_theta(prob, nm) for nm in s.candidates if nm in first}
    for nm in final.names:
        vals[nm] = final.term_theta(prob, nm)
    sg = suggest(s.model, s.pred, scales, vals, rep.to_dict(), int(n), forces_only)
    entry = {"n": int(n), "file": "next_measurements.csv", "criterion": sg.criterion, "targets": sg.targets,
             "criterion_before": sg.before, "criterion_after": sg.after, "forces_only": bool(forces_only),
             "rows_to_separate": sg.rows_to_separate}
    return sg, dataclasses.replace(rep, suggest=entry)
