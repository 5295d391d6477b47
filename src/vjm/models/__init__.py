"""Architectures known to the model file (``architecture:`` key)."""
from .base import Architecture
from .delta import DeltaRRPaR
from .orthoglide import OrthoglidePRPaR, OrthoglidePUU

ARCHITECTURES: dict[str, Architecture] = {a.name: a for a in (OrthoglidePUU(), OrthoglidePRPaR(), DeltaRRPaR())}

__all__ = ["ARCHITECTURES", "Architecture"]
