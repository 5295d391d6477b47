"""Deflection of the tool along a toolpath, and the compensated toolpath (``vjm path``).

One concept per module: :mod:`~vjm.toolpath.gcode` (a strict G-code subset, read and written back),
:mod:`~vjm.toolpath.points` (CSV and G-code toolpaths, sampled), :mod:`~vjm.toolpath.wrench` (process wrench:
per point, constant, a milling model), :mod:`~vjm.toolpath.deflect` (TCP deflection, linear and
nonlinear with the model's effects), :mod:`~vjm.toolpath.compensate` (fixed-point compensation),
:mod:`~vjm.toolpath.uncertainty` (the calibration's band), :mod:`~vjm.toolpath.result` (the value, its
plots), :mod:`~vjm.toolpath.output` (the files), :mod:`~vjm.toolpath.run` (the pipeline),
:mod:`~vjm.toolpath.robot` (the pipeline on a serial robot), :mod:`~vjm.toolpath.dispatch` (the one by the model).
"""
from .dispatch import path
from .wrench import Constant, Milling, PerPoint

__all__ = ["path", "Constant", "Milling", "PerPoint"]
