# %% [markdown]
# # A serial robot: stiffness and self-weight sag over its joint space
#
# The bundled UR10 (`data/robots/ur10/ur10.yaml`: the nominal URDF of ur_description with joint
# springs and two beam link springs) is mapped over its shoulder and elbow joints, the wrist held:
# the tool's largest compliance k_tran (mm/N) and its sag under the robot's own weight (mm, the
# equilibrium on the deflected geometry).  Then a straight line of tool points is reached by the
# IK in the elbow-up configuration, and its stiffness read along it.

# %%
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

import vjm
from vjm.kinematics.transforms import rotation_vector

OUT = Path("out/examples/serial_robot")
OUT.mkdir(parents=True, exist_ok=True)
robot = vjm.load_model("data/robots/ur10/ur10.yaml")
q0 = np.array([0.0, -1.2, 1.5, -1.9, -1.57, 0.0])          # elbow up, wrist down (rad)
jmap = robot.joint_map(q0, ("shoulder_lift_joint", "elbow_joint"), ((-2.6, -0.4), (0.3, 2.6)), n=15,
                       self_weight=True)
sag = np.linalg.norm(jmap.sag[..., :3], axis=-1)
print(f"sag over the map: {sag.min():.3f} to {sag.max():.3f} mm; k_tran {jmap.k_tran.min():.3g} to "
      f"{jmap.k_tran.max():.3g} mm/N")
for name in ("sag", "k_tran"):
    ax = jmap.plot(name)
    ax.figure.savefig(OUT / f"{name}.png", dpi=80)
    plt.close(ax.figure)

# %%
T0 = robot.forward(q0)
line = T0[:3, 3] + np.linspace(0.0, 300.0, 7)[:, None] * np.array([1.0, 0.0, 0.0])
ik, res, line_sag = robot.cartesian_map(line, q0, orientation=rotation_vector(T0[:3, :3]), self_weight=True)
print(f"line: {int(ik.reached.sum())} of {len(line)} points reached, singular: {int(ik.singular.sum())}; "
      f"k_tran {res.k_tran.min():.3g} to {res.k_tran.max():.3g} mm/N, sag z {line_sag[:, 2].min():.3f} mm")
