"""The machine's error bars from its links' FEA error bars: the spread of k_tran and k_rot.

A link computed by linkfea carries the estimated relative discretization error ``e_k`` of each
diagonal entry of its compliance (:attr:`vjm.model.links.LinkSpring.error`, from
:mod:`linkfea.fem.estimate`).  Moving a link ``t`` times along its bar means
``C(t) = D C D`` with ``D = diag(sqrt(1 + t e_k))`` (:meth:`~vjm.model.links.LinkSpring.scaled`):
``t = +-1`` are the ends of the bar, every diagonal entry at ``C_kk (1 +- e_k)``.  A link used
in several chains (the three feet of an Orthoglide are one FEA result) moves in all of them
at once.

The spread of k (``k_tran`` or ``k_rot``) is the sum over the links of ``|dk/dt_i|`` at
``t = 0``: the half-width of the range k covers, to first order, when every link moves
anywhere within its own bar.  The links' errors are added in magnitude, not in quadrature:
FEA errors are not independent random errors (a P2 compliance is too small for every link),
so the bound over the box of the bars is the honest figure.

Two ways to get ``dk/dt_i``, :data:`METHODS`:

* ``"linear"`` (the default): the linear sensitivity, a forward difference at ``t = STEP``.
  One extra evaluation of the spring part per link with a bar; the geometry (kinematics,
  wrench bases) is shared with the nominal evaluation.  The bars are a few percent, so the
  linearisation is off by about ``e^2`` relative, well inside the bar's own uncertainty (the
  estimate carries a safety factor of 3).
* ``"ends"``: the bar's ends sampled, half of ``max - min`` over ``t in {-1, 0, +1}``; two
  extra evaluations per link.  It checks the linear figure (tests/vjm/test_vjm_spread.py).

Links without an estimate (analytic beams, inline matrices, rigid links) contribute none;
a model none of whose links has a bar gets a spread of zero at no cost.
Units are those of k: k_tran mm/N, k_rot rad/(N mm) (scalars: no frame).
"""
from __future__ import annotations

import numpy as np

from ..errors import VjmError

#: the ways of computing the spread: the linear sensitivity, or the bar's ends sampled
METHODS = ("linear", "ends")
#: the forward-difference step of the linear sensitivity, in units of each link's bar
STEP = 1e-3


def bars(model) -> dict:
    """``{link name: relative error (6,)}`` of the model's links that carry an FEA error bar."""
    return {name: link.error for name, link in model.links.items()
            if link.error is not None and link.compliance is not None}


class Spread:
    """Accumulates the spread of k_tran and k_rot over the blocks of one stiffness evaluation.

    ``model`` is the nominal model; for each link with a bar, the moved models are built once
    (``t = STEP``, or ``t = +-1`` for ``"ends"``) and each block is evaluated on the same
    kinematics as the nominal one (:meth:`vjm.model.machine.ParallelModel._block_stiffness`).
    """

    def __init__(self, model, n: int, method: str = "linear"):
        if method not in METHODS:
            raise VjmError(f"spread method must be one of {', '.join(METHODS)}, got {method!r}")
        self.method = method
        ts = (STEP,) if method == "linear" else (1.0, -1.0)
        self.moved = {name: [model.replace(links={name: model.links[name].scaled(t)}) for t in ts]
                      for name in bars(model)}
        self.k_tran = np.zeros(n)
        self.k_rot = np.zeros(n)
        self.by_link = {name: (np.zeros(n), np.zeros(n)) for name in self.moved}

    def block(self, kin, a: int, kt0: np.ndarray, kr0: np.ndarray, tol: float) -> None:
        """Poses ``a : a + kin.n``, whose nominal k_tran and k_rot are ``kt0``, ``kr0``."""
        from ..stiffness.linear import assemble_soa

        b = a + kin.n
        for name, models in self.moved.items():
            kts, krs = [], []
            for m in models:
                K, _ = m._block_stiffness(kin, tol)
                kt, kr = assemble_soa(K)[3:]
                kts.append(kt)
                krs.append(kr)
            with np.errstate(invalid="ignore"):
                if self.method == "linear":
                    dt, dr = np.abs(kts[0] - kt0) / STEP, np.abs(krs[0] - kr0) / STEP
                else:
                    dt, dr = _half_range(kt0, *kts), _half_range(kr0, *krs)
            # a singular pose (k = inf) has no spread: NaN
            dt = np.where(np.isfinite(kt0), dt, np.nan)
            dr = np.where(np.isfinite(kr0), dr, np.nan)
            self.by_link[name][0][a:b] = dt
            self.by_link[name][1][a:b] = dr
            self.k_tran[a:b] += dt
            self.k_rot[a:b] += dr


def _half_range(k0: np.ndarray, *ks: np.ndarray) -> np.ndarray:
    stack = np.stack((k0, *ks))
    return 0.5 * (stack.max(axis=0) - stack.min(axis=0))
