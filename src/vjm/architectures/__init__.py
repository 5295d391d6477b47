"""Architectures known to the model file (``architecture:`` key)."""
from .base import Architecture
from .delta import DeltaRRPaR
from .described import Described
from .orthoglide import OrthoglidePRPaR, OrthoglidePUU

#: the registry: a new architecture is one module and one entry here (docs/add_architecture.md)
ARCHITECTURES: dict[str, Architecture] = {a.name: a for a in (OrthoglidePUU(), OrthoglidePRPaR(), DeltaRRPaR(),
                                                              Described())}

__all__ = ["ARCHITECTURES", "Architecture"]
