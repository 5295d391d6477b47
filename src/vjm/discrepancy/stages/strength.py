"""Design strength: whether the design is strong enough to name what the selection chose.

The selection's tests hold their level on any design, but a significant
effect is not yet a *name*: on a weak design the winner may be whichever
candidate the few rows happen to favour.  The verdict is
``insufficient_data`` instead of ``explained`` when effects were named and
any of these holds (each reason is reported):

* **one posture**: every effect of the library is told apart from the others
  by how it changes over the workspace; at one posture none does, and the
  held-out-posture cross-validation of the selection cannot be made;
* **too few observations per parameter**: fewer than ``OBS_PER_PARAM``
  measured values per fitted parameter (calibration and named effects): the
  chi-square tests rest on asymptotics that so few rows do not reach.

A named effect whose linearised (Wald) 95 % interval touches its null value is
not a reason: the selection's likelihood-ratio test, which named it, is the
better test of the null on a nonlinear fit, and the two disagree only at the
edge (a coupling factor of 0.81 +- 0.19 against a null of 1, significant by
the likelihood ratio, is a real effect).

A design that names an effect only as a group ("A or B: this data cannot
tell them apart", :mod:`.confounding`) keeps the verdict ``explained``: the
group holds the effect, and ``--suggest`` designs the rows that separate it.
"""
from __future__ import annotations

from .problem import Setup
from .select import Selected

#: measured values needed per fitted parameter (the common "ten observations per parameter")
OBS_PER_PARAM = 10
#: distinct postures needed
MIN_POSTURES = 2


def weak_design(s: Setup, chosen: Selected) -> list:
    """Why this data cannot support naming the selected effects (one sentence each; empty: it can)."""
    sel = chosen.sel
    if not sel.selected:
        return []
    prob, final = s.prob, sel.final
    why = []
    if len(s.U) < MIN_POSTURES:
        why.append(f"the data hold {len(s.U)} posture: no effect's change over the workspace shows, and the "
                   f"held-out-posture cross-validation cannot be made (at least {MIN_POSTURES} postures needed)")
    k = len(final.theta)
    if prob.n < OBS_PER_PARAM * k:
        why.append(f"{prob.n} measured values for {k} fitted parameters: fewer than {OBS_PER_PARAM} per "
                   f"parameter ({OBS_PER_PARAM * k} needed)")
    return why
