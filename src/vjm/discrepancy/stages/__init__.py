"""The stages of the discrepancy workflow, each a function returning a frozen value, in run order.

1. ``problem``: the rows, postures and candidates, the weighted residual problem (``Setup``).
2. ``calibrate``: the calibration factors this data can separate, the calibrated baseline (``Baseline``).
3. ``observability``: the candidates (and parameters) this data can see; the others are never fitted
   (``Observability``).
4. ``select``: the candidates to name: forward selection, each named effect against its ``rivals``,
   backward elimination, pair screen, other explanations in Occam's window (``Selected``).
5. ``goodness``: whether the final model fits: lack of fit, reduced chi-square (``Goodness``).
6. ``noise``: whether the stated sigmas are right; too small and noise-like, the workflow runs 2-5 again at
   the residuals' scale (``NoiseCheck``).
7. ``load_levels``: whether the compliance differs between load levels (a ``dict``, or None).
8. ``locate``: where the gap is, before and after naming (``Located``).
9. ``candidates``: the table of candidates (``Candidates``).
10. ``confounding``: the groups this data cannot tell apart, one function per rule (``Confounding``).
11. ``strength``: whether the design is strong enough to name what was chosen (reasons, a list).
12. ``verdict``: the verdict and its warnings (``Verdict``).
13. ``outliers``: the rows holding a gross outlier; the workflow runs 1-12 again without them until the
    set aside is the set flagged (``Outliers``).
14. ``update``: the updated model (calibration and named effects).
15. ``design``: the measurements to make next, on request (``Suggested``).
16. ``record``: the report, assembled once from the values above (``Report``, frozen).

:func:`vjm.discrepancy.workflow.diagnose` runs them in turn; the reruns (6, 13) are the workflow's.
The data kinds (deflections, stiffness observations) are strategy objects in ``kinds``;
``thresholds`` holds the levels, ``norms`` the RMS helpers.
"""
