"""Discrepancy workflow: locate where a VJM model and measurements disagree,
name the missing physical effect from a library, fit it, and report.

Modules: ``data`` (CSV in/out), the effects in :mod:`vjm.effects`,
``fit.select`` (statistics), ``predict`` (batched predictions), ``workflow``
(the workflow) running the typed ``stages``, ``diagnosis`` (the result),
``diagnose`` (the public names), ``simulate``, ``report`` (JSON/HTML/PNG), ``cli``.
"""
