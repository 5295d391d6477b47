"""The calibrated robot in memory (vjm.calibration.write.calibrated_model) is the robot that the written
calibrated.urdf and calibrated.yaml describe, loaded back: the same tools, forward kinematics, Jacobians,
stiffness and self-weight sag at several configurations, to round-off (the fitted stiffnesses are the file's,
rounded at their standard deviations, in both)."""
import os
import warnings

import numpy as np
import pytest

import vjm
from vjm.calibration.engine import Calibration
from vjm.calibration.write import calibrated_model, write_calibrated

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
UR10 = os.path.join(ROOT, "data", "robots", "ur10", "ur10.yaml")
URDF = os.path.join(ROOT, "data", "robots", "ur10", "ur10.urdf")
Q = np.array([[0.0, -1.2, 1.5, -1.87, -1.57, 0.0], [0.4, -0.7, 0.9, 0.3, 1.1, -0.6],
              [-1.3, -2.1, 2.2, -0.4, 0.2, 2.5], [2.0, -0.2, -1.4, 1.9, -2.3, 0.8]])
#: a calibration as the engine leaves it: joint offsets, origin errors, compliances, two measured points
VALUES = {"shoulder_lift_joint.offset": 2e-3, "elbow_joint.offset": -1.5e-3, "elbow_joint.dx": 0.4,
          "elbow_joint.dz": -0.3, "elbow_joint.ex": 5e-4, "wrist_1_joint.ey": -3e-4, "wrist_2_joint.dy": 0.2,
          "shoulder_lift_joint.compliance": 4e-6, "elbow_joint.compliance": 8e-6, "wrist_1_joint.compliance": 0.0,
          "tool0.px": 1.5, "reg[A].tx": 3.0}
#: their standard deviations where the file rounds them
STD = {"shoulder_lift_joint.compliance": 3e-8, "elbow_joint.compliance": 1.2e-7}


def _source(tmp_path, masses: bool):
    if not masses:
        return UR10
    p = tmp_path / "ur10_masses.yaml"   # the same robot with a point mass added by its robot file
    text = open(UR10).read().replace("urdf: ur10.urdf", f"urdf: {URDF}")
    p.write_text(text + "masses:\n  forearm_link: {mass: 2.5, com: [0, 30, 200]}\n")
    return str(p)


@pytest.mark.parametrize("masses", [False, True])
def test_the_model_in_memory_is_the_model_written_back(tmp_path, masses):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        src = vjm.load_model(_source(tmp_path, masses))
    cal = Calibration(src, "tool0", dict(VALUES), dict(STD), {}, np.array([10.0, -20.0, 110.0]),
                      extra=(("wrist_2_link", np.array([0.0, 40.0, 60.0])),))
    mem = calibrated_model(cal)
    urdf, yml = tmp_path / "calibrated.urdf", tmp_path / "calibrated.yaml"
    write_calibrated(cal, src.tree.source, str(urdf), str(yml))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        back = vjm.load_model(str(yml))
    assert mem.kind == "serial" and isinstance(mem, vjm.Model)
    assert mem.tools == back.tools == ("tool0_marker", "wrist_2_link_marker", "tool0")   # the markers first
    assert mem.q_names == back.q_names and mem.name == back.name
    assert mem.gravity == pytest.approx(back.gravity, abs=0) and mem.home == back.home == src.home
    # every joint the source names: the fitted ones changed, the others (wrist_1's compliance 0) the source's
    assert set(mem.joint_springs) == set(back.joint_springs) == set(src.joint_springs)
    assert all(mem.joint_springs[j].stiffness == back.joint_springs[j].stiffness for j in mem.joint_springs)
    assert mem.joint_springs["wrist_1_joint"].stiffness == src.joint_springs["wrist_1_joint"].stiffness
    assert mem.joint_springs["elbow_joint"].stiffness != src.joint_springs["elbow_joint"].stiffness
    assert set(mem.links) == set(back.links) == set(src.links)   # the link springs carried: the fit deflects them
    # the written robot file carries the added masses: so does the model in memory
    assert sorted(b.name for b in mem.tree.bodies) == sorted(b.name for b in back.tree.bodies)
    mass = sum(b.mass for b in mem.tree.bodies)
    assert mass == pytest.approx(sum(b.mass for b in back.tree.bodies), rel=1e-12)
    assert sum(b.mass for b in src.tree.bodies) == pytest.approx(mass, rel=1e-12)
    for tool in mem.tools:
        Tm, Tb = mem.forward(Q, tool), back.forward(Q, tool)
        np.testing.assert_allclose(Tm[:, :3, 3], Tb[:, :3, 3], rtol=0, atol=1e-9)      # mm
        np.testing.assert_allclose(Tm[:, :3, :3], Tb[:, :3, :3], rtol=0, atol=1e-12)
        np.testing.assert_allclose(mem.jacobian(Q, tool), back.jacobian(Q, tool), rtol=0, atol=1e-9)
        rm, rb = mem.stiffness(Q, tool), back.stiffness(Q, tool)
        np.testing.assert_allclose(rm.C, rb.C, rtol=1e-9, atol=1e-12 * np.abs(rb.C).max())
        np.testing.assert_allclose(rm.k_tran, rb.k_tran, rtol=1e-9)
        np.testing.assert_allclose(mem.self_weight(Q, tool), back.self_weight(Q, tool), rtol=1e-9, atol=1e-12)
    # the calibration moved the marker: the model in memory is not the source with markers added
    assert np.max(np.abs(mem.forward(Q, "tool0_marker")[:, :3, 3] - src.forward(Q, "tool0")[:, :3, 3])) > 1.0
