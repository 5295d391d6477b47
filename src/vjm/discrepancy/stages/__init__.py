"""The stages of the discrepancy workflow, each a function returning a frozen dataclass.

``problem`` (reachability, candidates, the weighted residual problem) ->
``calibrate`` (inseparable calibration factors held, the calibrated baseline) ->
``observability`` (candidates the data cannot see are never fitted) ->
``select`` (forward selection, rival swaps, pair screen, backward elimination) ->
``goodness`` (lack of fit, reduced chi-square) -> ``locate`` (where the gap is, before and after) ->
``candidates`` (the per-candidate table) -> ``confounding`` (one function per rule) ->
``verdict`` (verdict and warnings) -> ``record`` (the typed report).  The data kinds
(deflections, stiffness observations) are strategy objects in ``kinds``.
"""
