# %% [markdown]
# # Beam or FEA?
#
# The Orthoglide foot (`cad/orthoglide_foot.py`: a flange, a pocketed arm with a rib, a boss)
# is far from prismatic: is a beam model good enough for it?  The seed (section 3.2) says one
# beam is about 50 % off.  `compare` computes the foot's FEA compliance, cuts the body into N
# segments, gets each section from sectionproperties and chains N Timoshenko (and
# Euler-Bernoulli) beams; the errors are dimensionless (fractions).  Coarse mesh for speed.

# %%
from pathlib import Path

import numpy as np

from linkfea.compare import compare

OUT = Path("out/examples/beam_vs_fea")
record = compare("orthoglide_foot", beams=(1, 4), mesh_size=8.0, out=OUT)
C_fea = np.array(record["fea"]["compliance"])
for model in record["beams"]:
    s = model["timoshenko"]["summary"]
    print(f"N = {model['n']}: " + ", ".join(f"{k} {v:.3g}" for k, v in s.items()))

# %% [markdown]
# Torsion is the worst: the open pocket's Saint-Venant J is far below what the closed
# flange and boss give the FEA (see docs/beam_vs_fea.md).  `OUT/compare.png` plots the errors against N; `compare.md` is the table and
# `compare.json` the full record (matrices in the link frame, units stated inside).

# %%
print(sorted(p.name for p in OUT.iterdir()))
