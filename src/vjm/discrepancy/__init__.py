"""Discrepancy workflow: locate where a VJM model and measurements disagree,
name the missing physical effect from a library, fit it, and report.

Modules: ``data`` (CSV in/out), the effects in :mod:`vjm.effects`, ``predict``
(batched predictions), ``workflow`` (:func:`~vjm.discrepancy.workflow.diagnose`:
runs the ``stages``, listed in run order in :mod:`vjm.discrepancy.stages`),
``diagnosis`` (:class:`~vjm.discrepancy.diagnosis.Diagnosis`, the result, and
:func:`~vjm.discrepancy.diagnosis.write_diagnosis`), ``summary`` (the verdict
line, the summary), ``suggest`` (next measurements), ``loads`` (load levels),
``localize`` (where a gap is), ``observe`` (what a data set can see),
``simulate``, ``report`` (JSON/HTML/PNG), ``cli`` (the commands and
:func:`~vjm.cli.diagnose.run`).  The statistics engine is :mod:`vjm.stats`.
"""
