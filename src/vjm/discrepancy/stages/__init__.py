"""The stages of the discrepancy workflow, each a function returning a frozen dataclass.

``problem`` (reachability, candidates, the weighted residual problem) ->
``calibrate`` (inseparable calibration factors held, the calibrated baseline) ->
``observability`` (candidates the data cannot see are never fitted) ->
``select`` (forward selection, ``rivals`` swapped in, backward elimination, pair screen) ->
``goodness`` (lack of fit, reduced chi-square) -> ``locate`` (where the gap is, before and after) ->
``candidates`` (the per-candidate table) -> ``confounding`` (one function per rule) ->
``verdict`` (verdict and warnings) -> ``record`` (the typed report) -> ``outliers`` (rows holding a
gross outlier set aside, the stages rerun without them) -> ``design`` (suggested
measurements, on request); ``update`` builds the updated model.  The data kinds (deflections,
stiffness observations) are strategy objects in ``kinds``; ``thresholds`` holds the levels,
``norms`` the RMS helpers.  :func:`vjm.discrepancy.workflow.diagnose` runs them in turn.
"""
