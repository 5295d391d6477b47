"""The statistics engine: nonlinear least squares, evidence and the selection of model terms.

It knows nothing of machines or of the diagnosis (the effect library declares its parameters with
:class:`~vjm.stats.terms.Param`; the diagnosis builds a :class:`~vjm.stats.terms.Problem`), so that the
effects and the model files can use it without importing :mod:`vjm.discrepancy`.

``terms`` (:class:`~vjm.stats.terms.Param`, :class:`~vjm.stats.terms.Term`, :class:`~vjm.stats.terms.Problem`),
``fit`` (fits, likelihood-ratio / F tests, BIC, grouped or interleaved cross-validation, lack of fit), ``selection``
(forward selection, backward elimination, pair screen, swaps within Occam's window), ``components``
(variance components fitted apart), ``staged`` (staged selection over nested least-squares fits: identifiable
columns, F tests and cross-validated error stage by stage, the backward re-test; the absolute-pose calibration's),
``uncertainty`` (standard deviations scaled by the lack of fit and a block jackknife robust to correlated residuals).
"""
