"""The conventions linkfea and vjm share, in one place: wrench and twist order, units.

Both packages import these names (linkfea's results, vjm's models and measurement files),
so a label or a unit is written once.  Units: N, mm, MPa, rad.
"""
from __future__ import annotations

#: wrench order (N, N mm)
WRENCH = ("Fx", "Fy", "Fz", "Mx", "My", "Mz")
#: twist order (mm, rad)
TWIST = ("dx", "dy", "dz", "rx", "ry", "rz")
#: units of a saved compliance and stiffness, by block, and of the base quantities
UNITS = {
    "compliance": {"force->translation": "mm/N", "moment->rotation": "rad/(N*mm)",
                   "moment->translation": "mm/(N*mm) = 1/N", "force->rotation": "rad/N"},
    "stiffness": {"translation->force": "N/mm", "rotation->moment": "N*mm/rad",
                  "rotation->force": "N/rad", "translation->moment": "N*mm/mm = N"},
    "length": "mm", "force": "N", "moment": "N*mm", "stress": "MPa", "time": "s",
}
#: the same in one line, for matrices printed to a terminal
UNITS_SHORT = "t = C w; mm/N, rad/N, mm/(N mm), rad/(N mm) by block"
