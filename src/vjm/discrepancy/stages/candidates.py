"""Candidates: the table of candidates (round-1 fits, the named ones' final values, why others were
skipped, dropped or never fitted, and what the data can see of each parameter)."""
from __future__ import annotations

from dataclasses import dataclass

from ... import effects as fx
from .observability import Observability
from .problem import Setup
from .select import Selected


@dataclass(frozen=True)
class Candidates:
    entries: dict  # name -> the report's candidate entry (before the confounding notes)
    dropped: dict  # name -> why a selected effect was dropped again


def _fitted(prob, nm, d, named) -> dict:
    return {"description": fx.get(nm).description, "kind": fx.get(nm).kind,
            "delta_bic": d["delta_bic"], "p_value": d["p_value"], "cv_error": d["cv_error"],
            "params": d["fit"].values(prob)[nm], "named": nm in named, "observable": True,
            "converged": bool(d["converged"]), "at_bound": list(d["clipped"]), "threshold": d["threshold"]}


def candidates(s: Setup, obs: Observability, chosen: Selected) -> Candidates:
    """One entry per candidate of the library (applicable or not)."""
    prob, sel = s.prob, chosen.sel
    first = chosen.first_round
    rep = {nm: _fitted(prob, nm, first[nm], sel.selected) for nm in s.candidates if nm in first}
    final_vals = sel.final.values(prob)
    for nm in sel.selected:
        i = sel.round_of(nm)
        d = sel.rounds[i][nm]
        rep[nm].update({"selected_at_round": i + 1, "round_delta_bic": d["delta_bic"], "round_p_value": d["p_value"],
                        "final_params": final_vals[nm]})
    dropped = {}
    for nm, (dchi2, dbic, p) in sel.dropped.items():
        rep[nm]["dropped"] = {"delta_chi2": dchi2, "delta_bic": dbic, "p_value": p}
        dropped[nm] = (f"{nm} was selected, then dropped: with {', '.join(sel.selected) or 'the calibration'} in "
                       f"the model it is no longer needed (removing it raises chi-square by {dchi2:.1f}, p = {p:.2g}, "
                       f"BIC change {dbic:+.1f})")
    for nm, why in {**s.skipped, **obs.unobservable}.items():
        rep[nm] = {"description": fx.get(nm).description, "skipped": why, "delta_bic": None,
                   "p_value": None, "cv_error": None, "params": {}, "named": False,
                   "observable": nm not in obs.unobservable if nm in obs.sens else None}
    for nm, ts in obs.sens.items():
        specs = obs.full_terms[nm].params
        rep[nm]["sensitivity"] = {p.name: float(v) for p, v in zip(specs, ts.norms)}
        if ts.fixed and ts.observable:
            rep[nm]["fixed"] = {specs[i].name: float(specs[i].start) for i in ts.fixed}
    return Candidates(rep, dropped)
