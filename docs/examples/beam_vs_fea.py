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

import linkfea

OUT = Path("out/examples/beam_vs_fea")
cmp = linkfea.compare("orthoglide_foot", beams=(1, 4), mesh_size=8.0)
print(cmp.errors)                    # one row per N: principal, diagonal and coupling errors
C_fea, C_1 = cmp.fea, cmp.beam(1)    # FEA and 1-beam (Timoshenko) compliances in the link frame
ax = cmp.plot()                      # matplotlib Axes: the error against N
print(cmp.link, f"{cmp.beam_length:.1f} mm", [b.n for b in cmp.beams])  # typed fields: compare.json's keys

# %% [markdown]
# Torsion is the worst: the open pocket's Saint-Venant J is far below what the closed
# flange and boss give the FEA (see docs/beam_vs_fea.md).  `OUT/compare.png` plots the errors against N; `compare.md` is the table and
# `compare.json` the full record (matrices in the link frame, units stated inside).

# %%
paths = cmp.save(OUT)
print(sorted(p.name for p in OUT.iterdir()))
