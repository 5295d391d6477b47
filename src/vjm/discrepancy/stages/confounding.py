"""Confounding: groups of candidates this data cannot tell apart, one function per rule.

* :func:`collinear_groups`: two observable candidates whose signatures, with
  the calibration's projected out, have a canonical correlation >= COLLINEAR
  form a group whatever the data's outcome (the design cannot separate them);
* :func:`near_rivals`: a named effect A and a candidate B whose fit, with the
  other named effects in place, is not worse by a (1 - alpha) chi-square(1)
  margin and whose partial correlation with A is >= NEAR_COLLINEAR: "A or B";
* :func:`hidden_inside`: a candidate B not named whose signature lies in the
  span of the named effects' (multiple correlation >= COLLINEAR) and that
  could carry at least HIDDEN_SHARE of what they explain along it within the
  margin and within its own parameter range (:func:`observe.hiding_share`):
  grouped with the named effect(s) that imitate it, even where the swap test
  separated them (B cannot replace A, but may be present besides it);
* :func:`calibration_mimicry`: a candidate whose signature the calibration
  reproduces (correlation >= MIMIC) is noted with the calibration change that
  imitates it, and grouped with "calibration" when it was not named and the
  calibration is flagged (at a bound or implausibly far from nominal): the
  calibration may have absorbed it.

A pair that the selection did separate (:func:`separated_pairs`: a named
effect whose rival fitted worse by more than the chi-square(1) margin in its
round, or could not fit) is not grouped by the first rule, however collinear
the linearised signatures; a rival with several parameters that could not
fit at all is not grouped by the third either (a one-parameter rival on its
bound only ran out of range).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...stats.fit import chi2_margin, clipped
from ...stats.selection import Selection
from .. import observe
from ..predict import CALIBRATION
from .thresholds import COLLINEAR, HIDDEN_SHARE, MIMIC, PLAUSIBLE


@dataclass(frozen=True)
class Confounding:
    groups: list  # lists of names (or a name and "calibration") the data cannot tell apart
    details: list  # {"names", "correlation", ["share"], "why"} per finding
    mimicked: dict  # name -> {"correlation", "looks_like"}: the calibration change that imitates it


@dataclass(frozen=True)
class Signatures:
    """The candidates' whitened sensitivity columns with the calibration's span projected out."""

    names: list  # observable candidates that were fitted
    resid: dict  # name -> projected columns
    raw: dict  # name -> norm of the unprojected columns

    def empty(self, n) -> bool:
        """Nothing of ``n``'s signature is left once the calibration is projected out."""
        return bool(np.linalg.norm(self.resid[n]) <= 1e-6 * self.raw[n])

    def corr(self, a, b) -> float:
        if self.empty(a) or self.empty(b):
            return 0.0
        return observe.canonical_correlation(self.resid[a], self.resid[b])

    def span_corr(self, b, among) -> float:
        """Multiple (canonical) correlation of b's signature with the joint span of ``among``'s."""
        among = [a for a in among if not self.empty(a)]
        if not among or self.empty(b):
            return 0.0
        return observe.canonical_correlation(self.resid[b], np.hstack([self.resid[a] for a in among]))


def signatures(sens, Q, cand_rep) -> Signatures:
    names = [n for n, ts in sens.items() if ts.observable and cand_rep.get(n, {}).get("p_value") is not None]
    return Signatures(names, {n: observe.project_out(sens[n].Jfree, Q) for n in names},
                      {n: np.linalg.norm(sens[n].Jfree) for n in names})


def separated_pairs(sel: Selection, rivals, margin) -> tuple[set, set]:
    """(pairs the data did separate, pairs where the rival could not fit at all in the named effect's place):
    a rival that fitted worse, in its round or with the other named effects in place, by more than
    ``margin`` (or could not fit)."""
    separated, unfit = set(), set()
    for a, checked in rivals.items():
        for b, d, _ in checked:
            if d >= margin:
                separated.add(frozenset((a, b)))
            if not np.isfinite(d):
                unfit.add(frozenset((a, b)))
    for a in sel.selected:  # rivals not re-checked: the selection round's evidence
        r = sel.round_of(a)
        info = sel.rounds[r] if r < len(sel.rounds) else {}
        if a not in info:
            continue
        for b, d in info.items():
            done = any(b == x for x, _, _ in rivals.get(a, []))
            if b != a and not done and (d["fit"].chi2 - info[a]["fit"].chi2 >= margin or not d["converged"]
                                        or d["clipped"]):
                separated.add(frozenset((a, b)))
            if b != a and not done and (not d["converged"] or d["clipped"]):
                unfit.add(frozenset((a, b)))
    return separated, unfit


def collinear_groups(sig: Signatures, separated) -> tuple[list, list]:
    """Rule 1: connected components of the pairs (not separated) with correlation >= COLLINEAR."""
    parent = {n: n for n in sig.names}

    def find(a):
        while parent[a] != a:
            a = parent[a]
        return a

    pair_c = {}
    for i, a in enumerate(sig.names):
        for b in sig.names[i + 1:]:
            if frozenset((a, b)) in separated:
                continue
            c = sig.corr(a, b)
            if c >= COLLINEAR:
                parent[find(b)] = find(a)
                pair_c[(a, b)] = c
    comps: dict = {}
    for n in sig.names:
        comps.setdefault(find(n), []).append(n)
    groups = [g for g in comps.values() if len(g) > 1]
    details = []
    for g in groups:
        cs = [c for (a, b), c in pair_c.items() if a in g]
        details.append({"names": list(g), "correlation": min(cs),
                        "why": f"{' or '.join(g)}: this data cannot tell them apart (signature correlations "
                               f"{min(cs):.3f}-{max(cs):.3f} once the calibration is projected out)"})
    return groups, details


def _join(groups, a, members) -> None:
    """Add ``members`` to the group holding ``a`` (a new group [a, *members] if there is none)."""
    grp = next((g for g in groups if a in g), None)
    if grp is None:
        groups.append([a] + list(members))
    else:
        grp.extend(b for b in members if b not in grp)


def near_rivals(sel: Selection, rivals, sig: Signatures, margin, groups) -> tuple[list, list]:
    """Rule 2: a named effect and the rivals that fit within ``margin`` with the other named effects in place."""
    groups = [list(g) for g in groups]
    details = []
    for a in sel.selected:
        alt = []
        for b, d, c in rivals.get(a, []):
            if b in sig.resid and d < margin:
                alt.append(b)
                details.append({"names": [a, b], "correlation": c,
                                "why": f"{a} or {b}: this data cannot tell them apart (signature correlation "
                                       f"{c:.3f}; with the other named effects in place {b} fits worse by only "
                                       f"{d:.1f} in chi-square)"})
        if alt:
            _join(groups, a, alt)
    return groups, details


def named_signal(prob, final, named, Q) -> np.ndarray:
    """What the named effects explain: the whitened residuals with them at their null values minus
    the final ones (the other terms at their final values), the calibration's span ``Q`` projected out."""
    th = [np.array([p.null for p in prob.terms[nm].params]) if nm in named else final.term_theta(prob, nm)
          for nm in final.names]
    s = prob.residuals(final.names, np.concatenate(th)) - prob.residuals(final.names, final.theta)
    return observe.project_out(s[:, None], Q)[:, 0]


def hidden_inside(prob, sel: Selection, sig: Signatures, Q, margin, unfit, groups) -> tuple[list, list]:
    """Rule 3: an effect not named that could hide inside the named ones.

    A named effect with several parameters imitates it with one of them, or two named effects do it
    together.  The swap test only shows whether it can replace a named effect entirely, not whether
    it can be present besides it: it joins the group when the data cannot exclude that it carries a
    tenth or more of what the named effects explain along its signature."""
    groups = [list(g) for g in groups]
    details: list = []
    named = [a for a in sel.selected if a in sig.resid]
    if not named:
        return groups, details
    signal = named_signal(prob, sel.final, named, Q)
    z = float(np.sqrt(margin))
    for b in sig.names:
        if b in sel.selected or sig.empty(b):
            continue
        specs = prob.terms[b].params  # the observable (fitted) parameters: the columns of resid[b]
        R, share = observe.hiding_share(sig.resid[b], np.hstack([sig.resid[a] for a in named]), signal, z,
                                        [observe.reach(p) for p in specs])
        if R < COLLINEAR or share < HIDDEN_SHARE:
            continue
        # the named effects it cannot do without (or, when any subset imitates it, the closest one)
        carriers = [a for a in named if sig.span_corr(b, [x for x in named if x != a]) < COLLINEAR]
        for a in carriers or [max(named, key=lambda a: sig.corr(a, b))]:
            grp = next((g for g in groups if a in g), None)
            # a linearised imitation the fit itself could not reach (out of range, no convergence):
            # with one parameter (its size) b only needed more than its range to replace a, which
            # the share's range cap accounts for; with several, a bound can mean its shape does not fit
            if (grp is not None and b in grp) or (frozenset((a, b)) in unfit and len(specs) > 1):
                continue
            _join(groups, a, [b])
            with_ = f" with {', '.join(x for x in named if x != a)}" if len(named) > 1 else ""
            part = "all" if share >= 1.0 else f"{100 * share:.0f} %"
            details.append({"names": [a, b], "correlation": R, "share": share,
                            "why": f"{a} or {b}: this data cannot tell them apart (the signature of {b} lies in that "
                                   f"of {a}{with_}, multiple correlation {R:.4f} once the calibration is projected "
                                   f"out: {b} could carry {part} of what the named effects explain along it, "
                                   f"unseen)"})
    return groups, details


def calibration_flagged(prob, final) -> bool:
    """The fitted calibration is at a bound of its range or implausibly far from nominal."""
    return (any(not (PLAUSIBLE[0] <= v <= PLAUSIBLE[1]) for v in final.term_theta(prob, CALIBRATION))
            or bool(clipped(prob, final, CALIBRATION)))


def calibration_mimicry(prob, sel: Selection, sens, cal_cols, names, cand_rep) -> tuple[list, list, dict]:
    """Rule 4: candidates the calibration reproduces: (new groups, details, {name: the imitating change})."""
    cal_params = prob.terms[CALIBRATION].params
    flagged = calibration_flagged(prob, sel.final)
    groups, details, mimicked = [], [], {}
    for n in names:
        R, coef = observe.mimicry(sens[n].Jfree, cal_cols)
        if R < MIMIC:
            continue
        c = cand_rep.get(n, {})
        # the calibration change imitating the candidate at its round-1 fitted value (or one typical step)
        ps = prob.terms[n].params
        if c.get("params"):
            dth = np.array([c["params"][p.name]["value"] - p.null for p in ps])
        else:
            dth = np.array([p.scale for p in ps])
        spans = np.array([observe.span(p) for p in ps])
        dcal = (coef @ (dth / spans)) * np.array([p.scale for p in cal_params])
        looks = {p.name: float(p.null + v) for p, v in zip(cal_params, dcal)}
        words = ", ".join(f"{k} = {v:.3g}" for k, v in looks.items())
        mimicked[n] = {"correlation": R, "looks_like": looks}
        # a named effect was significant on top of the calibration: the data did separate them
        if n not in sel.selected and flagged:
            groups.append([n, CALIBRATION])
            details.append({"names": [n, CALIBRATION], "correlation": R,
                            "why": f"{n} or calibration: on these postures and loads {n} looks like a calibration "
                                   f"change ({words}; correlation {R:.3f})"})
    return groups, details, mimicked


def confounding(prob, sel: Selection, sens, cal_cols, cand_rep, alpha, rivals=None) -> Confounding:
    """The four rules in turn (``cand_rep``: the round-1 candidate entries, for p-values and fits)."""
    rivals = rivals or {}
    Q = observe._orth(cal_cols)
    sig = signatures(sens, Q, cand_rep)
    margin = chi2_margin(alpha, 1)
    separated, unfit = separated_pairs(sel, rivals, margin)
    groups, d1 = collinear_groups(sig, separated)
    groups, d2 = near_rivals(sel, rivals, sig, margin, groups)
    groups, d3 = hidden_inside(prob, sel, sig, Q, margin, unfit, groups)
    extra, d4, mimicked = calibration_mimicry(prob, sel, sens, cal_cols, sig.names, cand_rep)
    return Confounding(groups + extra, d1 + d2 + d3 + d4, mimicked)
