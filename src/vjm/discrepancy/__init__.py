"""Discrepancy workflow: locate where a VJM model and measurements disagree,
name the missing physical effect from a library, fit it, and report.

Modules: ``data`` (CSV in/out), ``effects`` (the effect registry),
``fit.select`` (statistics), ``predict`` (batched predictions), ``diagnose``
(the workflow), ``simulate``, ``report`` (JSON/HTML/PNG), ``cli``.
"""
