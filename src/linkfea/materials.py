"""Isotropic materials in N, mm, MPa."""
from __future__ import annotations

from dataclasses import dataclass

from .errors import LinkFeaError


@dataclass(frozen=True)
class Material:
    """Isotropic linear-elastic material.

    Parameters
    ----------
    name : str
    E : float
        Young's modulus in MPa (N/mm^2).
    nu : float
        Poisson's ratio.
    """

    name: str
    E: float
    nu: float

    def __post_init__(self):
        if not (self.E > 0):
            raise LinkFeaError(f"material {self.name!r}: Young's modulus must be > 0 MPa, got {self.E}")
        if not (-1.0 < self.nu < 0.5):
            raise LinkFeaError(f"material {self.name!r}: Poisson's ratio must be in (-1, 0.5), got {self.nu}")

    @property
    def G(self) -> float:
        """Shear modulus in MPa."""
        return self.E / (2.0 * (1.0 + self.nu))


MATERIALS = {
    "steel": Material("steel", 210_000.0, 0.30),
    "aluminium": Material("aluminium", 70_000.0, 0.33),
    "titanium": Material("titanium", 110_000.0, 0.34),
    "cast_iron": Material("cast_iron", 120_000.0, 0.26),
}
MATERIALS["aluminum"] = MATERIALS["aluminium"]


def get_material(name: str) -> Material:
    """Look a material up by name.

    >>> get_material("steel").E
    210000.0
    """
    try:
        return MATERIALS[name.lower()]
    except (KeyError, AttributeError):
        known = ", ".join(sorted(MATERIALS))
        raise LinkFeaError(f"unknown material {name!r}; known materials: {known}") from None
