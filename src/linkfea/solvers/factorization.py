"""What a factorizer returns (:class:`Factorization`) and what a solve records of its solver
(:class:`SolverRecord`, the result JSON's ``solver`` object)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Optional

import numpy as np


@dataclass(frozen=True)
class Factorization:
    """A factored system: ``solve(B)`` for an (n, k) right-hand side, and what the result records of it."""

    solve: Callable[[np.ndarray], np.ndarray]
    factorizer: str
    """The method that ran: ``pardiso``, ``superlu``, ``cg+p1mg``, ``cg+amg`` or an injected one's name."""
    fallback_reason: Optional[str] = None
    """Why PARDISO was wanted but SuperLU ran (None: no fallback)."""
    convergence: Optional[dict] = None
    """The iterative solvers' statistics (levels, iterations, residuals), filled in by ``solve``."""
    choice: Optional[dict] = None
    """:func:`auto_factorizer`'s choice and the memory figures it was made on."""

    def __call__(self, B: np.ndarray) -> np.ndarray:
        return self.solve(B)


@dataclass(frozen=True)
class SolverRecord:
    """The linear solver of one FEA solve, as the result JSON's ``solver`` object records it."""

    assembler: str
    factorizer: str
    fallback_reason: Optional[str] = None
    convergence: Optional[dict] = None
    choice: Optional[dict] = None

    @classmethod
    def of(cls, assembler: str, f: Factorization) -> "SolverRecord":
        return cls(assembler, f.factorizer, f.fallback_reason, f.convergence, f.choice)

    def to_dict(self) -> dict[str, Any]:
        """The JSON object: ``convergence`` and ``choice`` only when there are."""
        d: dict[str, Any] = {"assembler": self.assembler, "factorizer": self.factorizer,
                             "fallback_reason": self.fallback_reason}
        d.update({k: v for k, v in (("convergence", self.convergence), ("choice", self.choice)) if v is not None})
        return d

    @classmethod
    def from_dict(cls, d: dict) -> "SolverRecord":
        return cls(str(d.get("assembler", "")), str(d.get("factorizer", "")), d.get("fallback_reason"),
                   d.get("convergence"), d.get("choice"))
