# %% [markdown]
# # A machine's stiffness map from FEA links
#
# The Orthoglide 3-PUU model file (`data/orthoglide/puu.yaml`) describes its foot as a beam.
# Here the foot's 6x6 compliance comes from the finite-element model of its CAD
# (`cad/orthoglide_foot.py`, coarse mesh for speed) instead, and the translational and
# rotational compliance k_tran (mm/N) and k_rot (rad/(N mm)) are mapped over the z = 0 slice
# of the workspace.  k_tran spans more than a decade there, so its map has a log colour scale.

# %%
from pathlib import Path

import numpy as np

import linkfea
import vjm

OUT = Path("out/examples/machine_map_from_fea")
foot = linkfea.compute("orthoglide_foot", linkfea.ComputeOptions(mesh_size=8.0))
foot.save(OUT / "foot.json", vtu=False)                   # compliance, frame and units, as `linkfea compute` writes

model = vjm.load_model("data/orthoglide/puu.yaml", foot=foot)  # the result itself: the same K as foot.json gives
beam_model = vjm.load_model("data/orthoglide/puu.yaml")  # the same machine with the file's beam foot
print("foot from", model.foot.source)

# %%
smap = model.map(grid=21, slice="z=0")
print(smap.summary())
smap.save(OUT / "map")                                    # map.npz, k_tran.png, k_rot.png

# %% [markdown]
# How much does the FEA foot change the machine against the beam foot?

# %%
beam_map = beam_model.map(grid=21, slice="z=0")
ratio = smap.k_tran / beam_map.k_tran
print(f"k_tran (FEA foot) / k_tran (beam foot): {np.nanmin(ratio):.3f} .. {np.nanmax(ratio):.3f}")
