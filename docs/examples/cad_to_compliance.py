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

from linkfea.beam import cantilever_compliance, rect_section
from linkfea.materials import get_material
from linkfea.pipeline import compute
from linkfea.post import write_png

OUT = Path("out/examples/cad_to_compliance")
L = 100.0
res = compute("bar", params={"length": L}, mesh_size=5.0)
C = res.matrix                       # compliance at the tip frame, mm/N, rad/N, mm/(N mm), rad/(N mm)
np.set_printoptions(precision=3, linewidth=120)
print(f"{res.link.name}: {len(res.mesh.tets)} P2 tetrahedra; compliance at the tip frame, origin {res.link.frame.origin}")
print(C)

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
# The deformed shape under a unit tip load, rendered off screen with pyvista.

# %%
png = write_png(OUT / "deformed.png", res)
print(f"wrote {png}")
