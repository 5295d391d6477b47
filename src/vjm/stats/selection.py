"""Forward selection of model terms, backward elimination, the pair screen and the swaps within Occam's
window (the evidence they weigh: :mod:`vjm.stats.fit`)."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .fit import FitResult, clipped, compare, cv_error, fit_terms, grouped_folds
from .terms import Problem


@dataclass(frozen=True)
class Selection:
    """Outcome of forward selection."""

    baseline: FitResult
    final: FitResult
    selected: tuple
    rounds: list  # per round: dict name -> {delta_bic, p_value, cv_error, fit, eligible}
    cv_baseline: float
    alpha: float
    #: round (0-based) in which each selected term entered; empty = ``range(len(selected))``
    entered: tuple = ()
    #: terms selected and later removed by :func:`backward_eliminate`: name -> (chi-square and BIC
    #: change on removing it from the final model, p-value of that removal)
    dropped: dict = field(default_factory=dict)

    def round_of(self, name: str) -> int:
        """Index into ``rounds`` of the round in which ``name`` was selected."""
        entered = self.entered or tuple(range(len(self.selected)))
        return entered[self.selected.index(name)]


def forward_select(problem: Problem, candidates, alpha: float = 0.01, max_effects: int = 3,
                   folds: int = 5, seed: int = 0, progress=None, extra_tests: int = 0) -> Selection:
    """Forward selection of candidate terms on top of the baseline.

    At each round every remaining candidate is fitted together with the terms
    already chosen.  A candidate is *eligible* when its fit converged with no
    parameter clipped on a bound (see :func:`clipped`), its test p-value is
    below ``alpha / (m + extra_tests)`` (Bonferroni over the ``m`` candidates
    of the round plus ``extra_tests`` other tests sharing the family-wise
    level, e.g. the lack-of-fit test; clean data then names nothing with
    probability >= 1 - alpha), its BIC is lower and its held-out-posture CV
    error is not larger than the current model's.
    The eligible candidate with the lowest BIC is added.  Selection stops when
    no candidate is eligible: "no missing effect" if that happens at round 1.
    """
    fold_masks = grouped_folds(problem.groups, folds, seed)
    base = fit_terms(problem, problem.baseline)
    cur = base
    cv_cur = cv_error(problem, problem.baseline, fold_masks, warm=base)
    cv_base = cv_cur
    remaining = [c for c in candidates if c not in problem.baseline]
    selected, rounds = [], []
    while remaining and len(selected) < max_effects:
        m = len(remaining)
        thr = alpha / (m + extra_tests)
        info: dict[str, dict[str, Any]] = {}
        for c in remaining:
            fr = fit_terms(problem, cur.names + (c,), warm=cur)
            dbic, p = compare(problem, cur, fr)
            info[c] = {"fit": fr, "delta_bic": dbic, "p_value": p, "cv_error": float("nan"),
                       "converged": fr.success, "clipped": clipped(problem, fr, c), "threshold": thr}
        # CV only where it can decide (significant, lower BIC, converged, not clipped): it costs
        # k refits per candidate, and on clean data it would be spent on every candidate
        for c in remaining:
            if (info[c]["p_value"] < thr and info[c]["delta_bic"] < 0 and info[c]["converged"]
                    and not info[c]["clipped"]):
                info[c]["cv_error"] = cv_error(problem, cur.names + (c,), fold_masks, warm=info[c]["fit"])
        for c in remaining:
            d = info[c]
            cv_ok = not np.isfinite(d["cv_error"]) or not np.isfinite(cv_cur) or d["cv_error"] <= cv_cur
            d["eligible"] = bool(d["p_value"] < thr and d["delta_bic"] < 0 and cv_ok
                                 and d["converged"] and not d["clipped"])
        rounds.append(info)
        if progress:
            progress(f"round {len(rounds)}: " + ", ".join(
                f"{c} dBIC={info[c]['delta_bic']:.1f} p={info[c]['p_value']:.2g}" for c in remaining))
        elig = [c for c in remaining if info[c]["eligible"]]
        if not elig:
            break
        best = min(elig, key=lambda c: info[c]["delta_bic"])
        selected.append(best)
        cur = info[best]["fit"]
        cv_cur = info[best]["cv_error"]
        remaining.remove(best)
    return Selection(base, cur, tuple(selected), rounds, cv_base, alpha)


def _prune(problem: Problem, final: FitResult, levels: dict) -> tuple[FitResult, dict]:
    """Drop, weakest first, the terms of ``levels`` (name -> level) that ``final`` no longer needs.

    A term is not needed when removing it is not significant at its level, or lowers the BIC;
    the model is refitted after each removal.  Returns the pruned fit and
    ``{name: (chi-square change, BIC change, p-value) of its removal}``.
    """
    levels, dropped = dict(levels), {}
    while levels:
        worst = None
        for a, thr in levels.items():
            small = fit_terms(problem, tuple(x for x in final.names if x != a), warm=final)
            dbic, p = compare(problem, small, final)
            if small.success and (p >= thr or dbic >= 0) and (worst is None or p > worst[1]):
                worst = (a, p, dbic, small)
        if worst is None:
            break
        a, p, dbic, small = worst
        del levels[a]
        dropped[a] = (float(small.chi2 - final.chi2), float(-dbic), float(p))
        final = small
    return final, dropped


def _levels(sel: Selection) -> dict:
    """name -> the level each selected term had to pass to enter (its round's threshold)."""
    entered = sel.entered or tuple(range(len(sel.selected)))
    return {a: (sel.rounds[r][a]["threshold"] if r < len(sel.rounds) and a in sel.rounds[r] else sel.alpha)
            for a, r in zip(sel.selected, entered)}


def backward_eliminate(problem: Problem, sel: Selection) -> Selection:
    """Remove selected terms that the final model no longer needs (the backward step of stepwise selection).

    Forward selection adds a term because it is the best single addition at
    that round; a term added later can take over what it explained (terms
    with nearly collinear signatures).  Each selected term is tested against
    the final model without it, at the level it had to pass to enter
    (its round's ``threshold``): a term whose removal is not significant, or
    whose removal lowers the BIC, is dropped, the weakest first, and the
    model refitted; repeated until every remaining term is needed.
    """
    final, dropped = _prune(problem, sel.final, _levels(sel))
    if not dropped:
        return sel
    entered = sel.entered or tuple(range(len(sel.selected)))
    keep = [(a, r) for a, r in zip(sel.selected, entered) if a not in dropped]
    return dataclasses.replace(sel, final=final, selected=tuple(a for a, _ in keep),
                               entered=tuple(r for _, r in keep), dropped={**sel.dropped, **dropped})


#: Occam's window (Madigan and Raftery 1994): a set of terms whose BIC exceeds the best one's by at
#: most 2 ln 20 has posterior odds of at least 1:20 against it (the BIC approximation of the
#: Bayes factor), so the data do not exclude it
OCCAM_WINDOW = float(2.0 * np.log(20.0))


def screen_pairs(r: np.ndarray, columns: dict, top: int) -> list:
    """The ``top`` pairs of terms whose columns together remove most of ``r`` (linearised).

    ``columns``: name -> (m, k) sensitivity of each term's parameters.  A pair's
    linearised chi-square reduction is that of the least-squares projection of
    ``r`` onto the two terms' columns (bounds ignored): a cheap screen before
    nonlinear fits, since fitting every pair costs as much as the rest of a
    diagnosis.  Returns ``[(a, b), ...]``, the largest reduction first.
    """
    names = [n for n, c in columns.items() if c.shape[1]]
    rr = float(r @ r)
    scored = []
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            M = np.hstack([columns[a], columns[b]])
            x, *_ = np.linalg.lstsq(M, r, rcond=None)
            e = r - M @ x
            scored.append((rr - float(e @ e), a, b))
    scored.sort(key=lambda t: -t[0])
    return [(a, b) for _, a, b in scored[:top]]


def swap_alternatives(problem: Problem, sel: Selection, swaps: dict, window: float = OCCAM_WINDOW,
                      tries=()) -> list:
    """Other sets of terms that explain the data about as well as the selected one.

    Selection is greedy: a term that wins its round by a hair can pull in a
    later term that only patches what it fits less well than the runner-up
    would have, and two terms whose signatures partly cancel are each weak
    alone, so neither is chosen first.  Each selected term ``a`` is swapped
    for each term of ``swaps[a]`` (its rivals: terms with nearly collinear
    signatures), and each set of ``tries`` (e.g. pairs from
    :func:`screen_pairs`) is fitted on the baseline; every model is then
    pruned as in :func:`backward_eliminate` (each term must stay significant
    at the level it had, or for a tried term at its first round's level).
    Returns the selections reached, ``sel`` included, whose BIC is within
    ``window`` of the lowest among them, lowest BIC first; fits that did not
    converge or ended clipped on a bound are left out.
    """
    levels = _levels(sel)
    entered = dict(zip(sel.selected, sel.entered or range(len(sel.selected))))
    first = sel.rounds[0] if sel.rounds else {}
    found = {frozenset(sel.selected): sel}
    jobs = [(tuple(b if x == a else x for x in sel.final.names), sel.final,
             {(b if x == a else x): v for x, v in levels.items()}, {**entered, b: entered[a]})
            for a in sel.selected for b in swaps.get(a, ())
            if b not in sel.final.names and b in problem.terms]
    for t in tries:
        t = tuple(t)
        if frozenset(t) in found or any(x not in first for x in t):
            continue
        jobs.append((tuple(problem.baseline) + t, first[t[0]]["fit"], {x: first[x]["threshold"] for x in t},
                     {**entered, **{x: 0 for x in t if x not in entered}}))
    for names, warm, lv, ent in jobs:
        fr = fit_terms(problem, names, warm=warm)
        if not fr.success:
            continue
        fr, dropped = _prune(problem, fr, lv)
        kept = tuple(x for x in fr.names if x not in problem.baseline)
        if not kept or frozenset(kept) in found or any(clipped(problem, fr, x) for x in kept):
            continue
        found[frozenset(kept)] = dataclasses.replace(
            sel, final=fr, selected=kept, entered=tuple(ent[x] for x in kept),
            dropped={**sel.dropped, **{x: d for x, d in dropped.items() if x in sel.selected}})
    out = sorted(found.values(), key=lambda s: s.final.bic)
    return [s for s in out if s.final.bic - out[0].final.bic <= window]
