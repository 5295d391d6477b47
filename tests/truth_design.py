"""Closed-form truth for design synthesis: a one-link arm whose lightest feasible beam is known.

The arm: one revolute joint (rigid) about z at the base and a straight link of length ``L`` (mm) along
x, its tool at the link's end, where its beam spring sits (``links: {arm: {at: arm, xyz: [L, 0, 0]}}``).
The tool's translational compliance is the cantilever's tip compliance, whatever the joint's value.

For a rectangular section ``b x h`` (width along y, height along z) Timoshenko's cantilever gives
the tip's transverse compliances ``L^3 / (3 E I) + L / (kappa G A)`` with ``I = h b^3 / 12`` (y) and
``b h^3 / 12`` (z), ``A = b h``, Cowper's ``kappa = 10 (1 + nu) / (12 + 11 nu)``; the axial one
``L / (E A)`` is far smaller.  At a given area the square has the larger smaller inertia, so the
lightest section whose largest transverse compliance is at most ``t`` is the square whose side ``s``
solves ``4 L^3 / (E s^4) + L / (kappa G s^2) = t``: a quadratic in ``1 / s^2``.  Written here from
those formulas, not from linkfea's beam module.
"""
from __future__ import annotations

import math

URDF = """<robot name="one_link">
  <link name="base"><inertial><origin xyz="0 0 0"/><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="arm"><inertial><origin xyz="{half} 0 0"/><mass value="2"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="tool0"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="arm"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="100" velocity="1"/></joint>
  <joint name="tool_joint" type="fixed"><parent link="arm"/><child link="tool0"/><origin xyz="{L} 0 0"/></joint>
</robot>
"""


def write_arm(folder, L: float, material: str = "aluminium") -> str:
    """The one-link arm (URDF and vjm model file) in ``folder``; returns the model file's path."""
    import os

    os.makedirs(folder, exist_ok=True)
    with open(os.path.join(folder, "arm.urdf"), "w") as fh:
        fh.write(URDF.format(L=L / 1000.0, half=L / 2000.0))
    path = os.path.join(folder, "arm.yaml")
    with open(path, "w") as fh:
        fh.write(f"name: one-link arm\nurdf: arm.urdf\ntools: [tool0]\ngravity: [0, 0, -9.80665]\nhome: [0]\n"
                 f"links:\n  arm:\n    at: arm\n    xyz: [{L}, 0, 0]\n"
                 f"    beam: {{section: rect, width: 20, height: 20, length: {L}, material: {material}}}\n")
    return path


def lightest_square(L: float, E: float, nu: float, t: float) -> float:
    """The side (mm) of the lightest rectangular section whose largest transverse tip compliance is ``t`` (mm/N)."""
    G = E / (2.0 * (1.0 + nu))
    kappa = 10.0 * (1.0 + nu) / (12.0 + 11.0 * nu)
    a, b = 4.0 * L ** 3 / E, L / (kappa * G)
    x = (-b + math.sqrt(b * b + 4.0 * a * t)) / (2.0 * a)   # x = 1 / s^2
    return 1.0 / math.sqrt(x)
