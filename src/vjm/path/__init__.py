"""Deflection of the tool along a toolpath, and the compensated toolpath (``vjm path``).

One concept per module: :mod:`~vjm.path.gcode` (a strict G-code subset, read and written back),
:mod:`~vjm.path.toolpath` (CSV and G-code toolpaths), :mod:`~vjm.path.wrench` (process wrench:
per point, constant, a milling model), :mod:`~vjm.path.deflect` (TCP deflection, linear and
nonlinear with the model's effects), :mod:`~vjm.path.compensate` (fixed-point compensation),
:mod:`~vjm.path.uncertainty` (the calibration's band), :mod:`~vjm.path.result` (the value, its
plots), :mod:`~vjm.path.output` (the files), :mod:`~vjm.path.run` (the pipeline).
"""
import sys
import types

from .run import path
from .wrench import Constant, Milling, PerPoint

__all__ = ["path", "Constant", "Milling", "PerPoint"]


class _CallableModule(types.ModuleType):
    """``vjm.path(...)`` calls :func:`vjm.path.run.path` while ``vjm.path`` stays this package."""

    def __call__(self, *args, **kwargs):
        return path(*args, **kwargs)


sys.modules[__name__].__class__ = _CallableModule
