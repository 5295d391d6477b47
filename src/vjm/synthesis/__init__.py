"""Design synthesis: the lightest machine whose stiffness constraints hold, its links from their CAD by FEA.

``vjm design SPEC --out DIR`` and :func:`vjm.design`.  The modules: :mod:`~vjm.synthesis.spec` (the
spec file, checked), :mod:`~vjm.synthesis.links` (link designs by FEA through the sweep's cache, or
closed-form beams), :mod:`~vjm.synthesis.surrogate` (a link's compliance and mass between its
evaluated designs), :mod:`~vjm.synthesis.machine` (the constraints' values on a parallel machine or a
robot), :mod:`~vjm.synthesis.search` (the rounds), :mod:`~vjm.synthesis.run` (the function) and
:mod:`~vjm.synthesis.result` (:class:`DesignResult` and its files).
"""
from .result import DESIGN_FILES, ConstraintValue, DesignResult
from .run import design
from .spec import DesignSpec, parse_spec, read_spec

__all__ = ["DESIGN_FILES", "ConstraintValue", "DesignResult", "DesignSpec", "design", "parse_spec", "read_spec"]
