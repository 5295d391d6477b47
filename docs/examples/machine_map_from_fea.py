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
from vjm.maps import compute_map, workspace_grid

OUT = Path("out/examples/machine_map_from_fea")
foot = linkfea.compute("orthoglide_foot", mesh_size=8.0)
foot_json = foot.save(OUT / "foot.json", vtu=False)       # compliance, frame and units, as `linkfea compute` writes

model = vjm.load_model("data/orthoglide/puu.yaml", foot=foot_json)
beam_model = vjm.load_model("data/orthoglide/puu.yaml")  # the same machine with the file's beam foot
print("foot from", model.foot.source)

# %%
axes, G, fixed = workspace_grid(model, 21, "z=0")
smap = compute_map(model, G.reshape(-1, 3), axes, fixed)
print(smap.summary())
smap.save(OUT / "map")                                    # map.npz, k_tran.png, k_rot.png

# %% [markdown]
# How much does the FEA foot change the machine against the beam foot?

# %%
beam_map = compute_map(beam_model, smap.points, axes, fixed)
ratio = smap.k_tran / beam_map.k_tran
print(f"k_tran (FEA foot) / k_tran (beam foot): {np.nanmin(ratio):.3f} .. {np.nanmax(ratio):.3f}")
