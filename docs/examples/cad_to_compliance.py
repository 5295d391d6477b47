# %% [markdown]
# # CAD -> 6x6 compliance -> picture
#
# The bundled straight bar (`cad/bar.py`, steel, 20 x 10 mm section) is meshed with P2
# tetrahedra, clamped at its base, and its tip frame's 6x6 compliance is fitted from the six
# unit-wrench solutions.  A coarse mesh keeps this example fast; `mesh_size` is the edge
# length in mm.  Units: mm, N, MPa, rad; wrench order Fx Fy Fz Mx My Mz.

# %%
from pathlib import Path

import numpy as np

import linkfea
from linkfea.beam.closed_form import cantilever_compliance, rect_section
from linkfea.mechanics.materials import get_material

OUT = Path("out/examples/cad_to_compliance")
L = 100.0
res = linkfea.compute("bar", linkfea.ComputeOptions(mesh_size=5.0), params={"length": L})
print(res)                           # the matrices with their units (a table in Jupyter)
C = res.compliance                   # 6x6 at the tip frame: mm/N, rad/N, mm/(N mm), rad/(N mm)
print("frame origin (CAD, mm):", res.frame.origin)

# %% [markdown]
# A cantilever has a closed form: Timoshenko with Cowper's shear coefficient.  The FEA
# diagonal should be within a few percent of it (the rigid tip and the clamp differ slightly
# from the beam's assumptions; the coarse mesh adds a little).

# %%
steel = get_material("steel")
C_beam = cantilever_compliance(L, rect_section(20.0, 10.0, steel.nu), steel.E, steel.nu)
rel = np.diag(C) / np.diag(C_beam) - 1.0
print("FEA / Timoshenko - 1 on the diagonal:", np.round(rel, 3))

# %% [markdown]
# The deformed shape under a unit tip load, rendered off screen with pyvista; `save` writes
# the result JSON (compliance, frame, units, mesh and solver record) and the deformed mesh (.vtu).

# %%
png = OUT / "deformed.png"
res.plot(off_screen=True, screenshot=png)
path = res.save(OUT / "bar100.json")
same = linkfea.load(path)            # the same compliance, read back
print(f"wrote {png} and {path}")
