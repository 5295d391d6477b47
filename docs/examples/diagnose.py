# %% [markdown]
# # What did the model leave out?
#
# Measurements are simulated on a "true" machine: the 3-PUU model plus a 15 N weight on the
# platform that the model does not know about, at 12 random postures under +-100 N along each
# axis, with 1 um of noise.  The diagnosis calibrates the model, tests each candidate effect
# of its library and names the one the data need, with a verdict: "explained" when the named
# effects leave only noise, "unexplained" when a significant gap remains, "no_discrepancy", or
# "insufficient_data" when an effect fits but the design is too weak to name it.

# %%
from pathlib import Path

import numpy as np

import vjm
from vjm.discrepancy.simulate import axes_loads, design_loads, design_poses, simulate

OUT = Path("out/examples/diagnose")
model = vjm.load_model("data/orthoglide/puu.yaml")
rng = np.random.default_rng(1)
P0 = design_poses(model, "random:12", rng)          # mm
L = design_loads(axes_loads(100.0), len(P0))        # (postures, loads per posture, 6): N, N mm ("axes:100")
P, W = np.repeat(P0, L.shape[1], axis=0), L.reshape(-1, 6)
data = simulate(model, [("gravity", {"weight": 15.0})], P, W, 1e-3, None, seed=1)

# %%
dg = vjm.diagnose(model, data, progress=print)     # progress: a line per selection round
print(dg.verdict, dg.named)
print(dg.summary())
dg.save(OUT)                                        # report.html, report.json, model_updated.yaml

# %% [markdown]
# The updated model carries the named effect with its fitted parameters (the `effects` of
# `model_updated.yaml`); it loads and computes like any other model.

# %%
updated = dg.updated_model
print(updated.effects)
