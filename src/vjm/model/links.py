"""A link's spring in a vjm model: linkfea's :class:`~linkfea.mechanics.compliance.Compliance`, or rigid.

:class:`LinkSpring` is the value a :class:`vjm.Model` holds for each of its named links
(``foot``, ``leg``, or a described machine's own).  It carries linkfea's Compliance --
matrix, frame and units, checked once by the one validator -- so a link computed in
memory keeps its frame on its way into a machine.  :func:`as_link` turns what a user
has at hand into one: a :class:`~linkfea.result.linkresult.LinkResult`, a Compliance, a 6x6
matrix, the path of a result JSON, or the name of a bundled CAD script (computed by
:func:`linkfea.compute`).

A spring computed by linkfea also carries the FEA's error bar (:attr:`LinkSpring.error`: the
estimated relative discretization error of each diagonal entry, :mod:`linkfea.fem.estimate`);
:mod:`vjm.sweep.spread` carries it to the machine's k_tran and k_rot.  Analytic beams, inline
matrices and rigid links have none.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any

import numpy as np

from linkfea.mechanics.compliance import Compliance
from linkfea.runtime.errors import LinkFeaError

from ..errors import VjmError


def checked_compliance(C, key: str, frame=None, units=None) -> Compliance:
    """``C`` (a Compliance or a 6x6 matrix) as a checked Compliance, or VjmError naming ``key``."""
    if isinstance(C, Compliance):
        return C
    try:
        if units is None:
            return Compliance(C, frame, what=f"{key}: compliance")
        return Compliance(C, frame, units, what=f"{key}: compliance")
    except LinkFeaError as exc:
        raise VjmError(str(exc)) from None


@dataclass(frozen=True, eq=False)
class LinkSpring:
    """A link's 6-dof spring: its Compliance (6x6 in the spring frame, with frame and units), or None if rigid.

    ``value`` may be given as a Compliance or as a 6x6 matrix; a matrix is checked when the
    spring enters a :class:`~vjm.model.machine.ParallelModel` (the message then names the link) and held as a
    Compliance without frame from there on.  ``source`` keeps what the model file said
    (``{"beam": ...}``, ``{"linkfea": path}`` ...) so that saving writes it back; None
    means "write the matrix inline".

    ``error`` is the FEA's error bar: the estimated relative discretization error of each
    diagonal entry (6,), order Fx..Mz (``LinkResult.error_diagonal``), or None where there is
    no estimate (analytic beams, inline matrices, results saved before the estimate existed).
    """

    value: Any
    source: dict | None = None
    error: np.ndarray | None = None

    def __post_init__(self):
        if self.error is not None:
            e = np.array(self.error, dtype=float)
            if e.shape != (6,) or not np.all(np.isfinite(e)) or np.any(e < 0) or np.any(e >= 1):
                raise VjmError(f"a link's error bar is 6 relative errors in [0, 1) (order Fx..Mz), got {self.error!r}")
            e.setflags(write=False)
            object.__setattr__(self, "error", e)

    @property
    def compliance(self) -> np.ndarray | None:
        """The 6x6 matrix (mm/N, rad/(N mm) by block, order Fx..Mz), or None for a rigid link."""
        v = self.value
        return v.matrix if isinstance(v, Compliance) else v

    def checked(self, key: str) -> "LinkSpring":
        """This spring with its compliance checked (VjmError naming ``key``)."""
        if self.value is None or isinstance(self.value, Compliance):
            return self
        return LinkSpring(checked_compliance(self.value, key), self.source, self.error)

    def scaled(self, t: float) -> "LinkSpring":
        """This spring with its compliance moved ``t`` times along its error bar: ``D C D`` with
        ``D = diag(sqrt(1 + t e_k))``, so each diagonal entry becomes ``C_kk (1 + t e_k)`` and each
        off-diagonal one moves by the geometric mean of its row's and column's factors (the
        bound ``|dC_ij| <= sqrt(dC_ii dC_jj)`` of :mod:`linkfea.fem.estimate`); the result stays
        symmetric positive definite for ``|t| <= 1``.  Frame and source are kept; the scaled
        spring carries no error bar of its own."""
        if self.error is None or self.value is None:
            raise VjmError("this link has no error bar to move along")
        c = self.value if isinstance(self.value, Compliance) else checked_compliance(self.value, "link")
        d = np.sqrt(1.0 + float(t) * self.error)
        return LinkSpring(Compliance(d[:, None] * c.matrix * d[None, :], c.frame, c.units, c.what), self.source)

    @property
    def frame(self):
        """The spring frame the matrix is stated in (:class:`linkfea.mechanics.frames.Frame`), or None if unknown."""
        return self.value.frame if isinstance(self.value, Compliance) else None

    @classmethod
    def rigid(cls) -> "LinkSpring":
        return cls(None, {"rigid": True})

    @classmethod
    def inline(cls, C) -> "LinkSpring":
        return cls(checked_compliance(C, "compliance"), None)


def linkfea_spring(path: str, key: str = "linkfea") -> LinkSpring:
    """The LinkSpring of a ``linkfea compute`` result JSON, read once by linkfea's one reader: its
    Compliance (6x6, frame, units), its source and its error bar
    (``diagnostics.discretization_error.diagonal``; None for a result saved before the estimate)."""
    from linkfea.result.linkresult import compliance_of
    from linkfea.result.schema import read_result

    path = os.path.abspath(path)
    if not os.path.isfile(path):
        raise VjmError(f"{key}: file not found: {path}")
    try:
        doc = read_result(path)
        C = compliance_of(doc, path)
    except LinkFeaError as exc:
        raise VjmError(f"{key}: {exc}") from None  # linkfea names the file
    est = (doc.get("diagnostics") or {}).get("discretization_error")
    err = est.get("diagonal") if isinstance(est, dict) else None
    try:
        return LinkSpring(C, {"linkfea": path}, None if err is None else np.asarray(err, dtype=float))
    except (VjmError, TypeError, ValueError):
        raise VjmError(f"{key}: {path}: discretization_error.diagonal must be 6 relative errors in [0, 1), "
                       f"got {err!r}") from None


def _result_path(text: str) -> bool:
    return text.endswith(".json") or os.path.isfile(text)


def as_link(obj, key: str = "link") -> LinkSpring:
    """What a user has for a link, as a :class:`LinkSpring` (VjmError naming ``key`` if it is none).

    * a LinkSpring (returned as is);
    * a :class:`linkfea.LinkResult` or a :class:`linkfea.Compliance` (frame and units kept);
    * a 6x6 matrix (no frame);
    * the path of a ``linkfea compute`` result JSON;
    * the name of a bundled link CAD script (``"orthoglide_foot"``), computed by
      :func:`linkfea.compute` with its default options (a finite-element run).
    """
    from linkfea.result.linkresult import LinkResult

    if isinstance(obj, LinkSpring):
        return obj
    if isinstance(obj, LinkResult):
        source = {"linkfea": os.path.abspath(obj.path)} if obj.path is not None else None
        return LinkSpring(obj.value, source, obj.error_diagonal)
    if isinstance(obj, Compliance):
        return LinkSpring(obj, None)
    if isinstance(obj, (str, os.PathLike)):
        text = os.fspath(obj)
        if _result_path(text):
            return linkfea_spring(text, key)
        import linkfea

        try:
            return as_link(linkfea.compute(text, progress=False), key)  # vjm says what fails, in one line
        except LinkFeaError as exc:
            raise VjmError(f"{key}: {text!r} is neither a result JSON nor a link that linkfea can compute: "
                           f"{exc}") from None
    if isinstance(obj, (list, tuple, np.ndarray)):
        return LinkSpring(checked_compliance(obj, key), None)
    raise VjmError(f"{key}: expected a linkfea LinkResult or Compliance, a 6x6 matrix, a result JSON path or a "
                   f"bundled link name, got {type(obj).__name__}")
