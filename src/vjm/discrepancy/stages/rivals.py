"""Each named effect against its rivals, with the other named effects in the model."""
from __future__ import annotations

import dataclasses

import numpy as np

from ...stats.fit import clipped, fit_terms
from ...stats.selection import Selection
from .. import observe
from .thresholds import NEAR_COLLINEAR


def rival_check(prob, sel: Selection, tested, sens, cal_cols, alpha) -> tuple[Selection, dict]:
    """Each named effect against its rivals, with the OTHER named effects in the model.

    Forward selection compares candidates one round at a time, so an effect can
    win its round only because a second effect was not in the model yet.  Here
    every named effect A is swapped for each tested candidate B whose signature
    is correlated with A's (partial correlation >= NEAR_COLLINEAR) and the
    model refitted: B with a lower BIC replaces A; B within the chi-square(1)
    (1 - alpha) margin is a rival the data cannot exclude.  Returns the
    (possibly updated) selection and ``{A: [(B, chi2_B - chi2_A, corr), ...]}``
    over every B checked (fits that failed or were clipped have ``inf``).
    """
    Q = observe._orth(cal_cols)

    def corr(a, b):
        ra, rb = observe.project_out(sens[a].Jfree, Q), observe.project_out(sens[b].Jfree, Q)
        if np.linalg.norm(ra) <= 1e-6 * np.linalg.norm(sens[a].Jfree) or \
                np.linalg.norm(rb) <= 1e-6 * np.linalg.norm(sens[b].Jfree):
            return 0.0
        return observe.canonical_correlation(ra, rb)

    selected, final = list(sel.selected), sel.final
    rivals: dict = {}
    for k in range(len(selected)):
        a = selected[k]
        checked = []
        for b in tested:
            if b in final.names:
                continue
            c = corr(a, b)
            if c < NEAR_COLLINEAR:
                continue
            others = tuple(x for x in final.names if x != a)
            fb = fit_terms(prob, others + (b,), warm=final)
            ok = fb.success and not clipped(prob, fb, b)
            checked.append((b, (fb.chi2 - final.chi2) if ok else float("inf"), c, fb if ok else None))
        # swap on BIC, as the selection chose (a rival with more parameters must fit better by more)
        best = min((t for t in checked if t[3] is not None), key=lambda t: t[3].bic, default=None)
        if best is not None and best[3].bic < final.bic:
            # the rival explains the data better with the other named effects in place: swap
            b, d, c, fb = best
            selected[k] = b
            checked = [(a, -d, c, final)] + [(x, dx - d, cx, f) for x, dx, cx, f in checked if x != b]
            final, a = fb, b
        rivals[a] = [(x, dx, cx) for x, dx, cx, _ in checked]
    if selected != list(sel.selected):
        sel = dataclasses.replace(sel, selected=tuple(selected), final=final)
    return sel, rivals
