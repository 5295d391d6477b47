"""Isotropic materials in N, mm, MPa; densities in t/mm^3 (the mass unit of the N-mm-s system)."""
from __future__ import annotations

from dataclasses import dataclass

from ..runtime.errors import LinkFeaError


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
    density : float
        Mass density in t/mm^3 (tonne per cubic millimetre, the unit consistent
        with N, mm and s: steel 7.85e-9 t/mm^3 = 7850 kg/m^3).  A link's mass in
        kg is ``density * volume_mm3 * 1000``.  None when unknown.
    """

    name: str
    E: float
    nu: float
    density: float | None = None

    def __post_init__(self):
        if not (self.E > 0):
            raise LinkFeaError(f"material {self.name!r}: Young's modulus must be > 0 MPa, got {self.E}")
        if not (-1.0 < self.nu < 0.5):
            raise LinkFeaError(f"material {self.name!r}: Poisson's ratio must be in (-1, 0.5), got {self.nu}")
        if self.density is not None and not self.density > 0:  # None = not given (no mass reported)
            raise LinkFeaError(f"material {self.name!r}: density must be > 0 t/mm^3, got {self.density}")

    @property
    def G(self) -> float:
        """Shear modulus in MPa."""
        return self.E / (2.0 * (1.0 + self.nu))

    def mass_kg(self, volume_mm3: float) -> float:
        """Mass in kg of ``volume_mm3`` mm^3 of this material.

        >>> round(get_material("steel").mass_kg(1e6), 6)  # one litre of steel
        7.85
        """
        if self.density is None:
            return float("nan")
        return float(self.density * volume_mm3 * 1000.0)


MATERIALS = {
    # typical handbook densities: structural steel, wrought aluminium alloy, Ti-6Al-4V, grey cast iron
    "steel": Material("steel", 210_000.0, 0.30, 7.85e-9),
    "aluminium": Material("aluminium", 70_000.0, 0.33, 2.70e-9),
    "titanium": Material("titanium", 110_000.0, 0.34, 4.43e-9),
    "cast_iron": Material("cast_iron", 120_000.0, 0.26, 7.20e-9),
}
MATERIALS["aluminum"] = MATERIALS["aluminium"]


DEFAULT_MATERIAL = "steel"
"""The material of a STEP or surface file computed without one (a cad/ script names its own); the
computation says so in one line (:func:`linkfea.pipeline.default_material_note`)."""


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
