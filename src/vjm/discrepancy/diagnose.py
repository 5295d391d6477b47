"""The discrepancy workflow's public names, in the place they have always been imported from.

:func:`diagnose` (the workflow, :mod:`vjm.discrepancy.workflow`) returns a
:class:`Diagnosis` (:mod:`vjm.discrepancy.diagnosis`); :func:`write_diagnosis`
writes it to a directory atomically; :func:`run` is the body of ``vjm diagnose``
(:mod:`vjm.discrepancy.cli`); :func:`summary` the one-paragraph summary
(:mod:`vjm.discrepancy.summary`).  The stages live in :mod:`vjm.discrepancy.stages`.
"""
from __future__ import annotations

from .cli import run
from .diagnosis import Diagnosis, write_diagnosis
from .stages.confounding import confounding
from .stages.rivals import rival_check as _rival_check  # noqa: F401  (importable from here, as before)
from .stages.thresholds import (
    COLLINEAR,
    DEFAULT_ALPHA,
    HIDDEN_SHARE,
    MIMIC,
    NEAR_COLLINEAR,
    PAIR_SCREEN,
    PLAUSIBLE,
)
from .summary import summary
from .workflow import diagnose

__all__ = ["COLLINEAR", "DEFAULT_ALPHA", "HIDDEN_SHARE", "MIMIC", "NEAR_COLLINEAR", "PAIR_SCREEN", "PLAUSIBLE",
           "Diagnosis", "diagnose", "run", "summary", "write_diagnosis"]


def _confounding(prob, sel, sens, cal_cols, cand_rep, alpha, rivals=None) -> dict:
    """:func:`~vjm.discrepancy.stages.confounding.confounding` as a dictionary ``{"groups", "details"}``;
    notes the calibration's imitations in ``cand_rep`` (``mimicked_by_calibration``)."""
    conf = confounding(prob, sel, sens, cal_cols, cand_rep, alpha, rivals)
    for n, m in conf.mimicked.items():
        if n in cand_rep:
            cand_rep[n]["mimicked_by_calibration"] = m
    return {"groups": conf.groups, "details": conf.details}
