"""``vjm map robot.yaml``: the joint-space map equals the Python API's; a Cartesian grid point's stiffness
equals K = (J C J^T)^-1 from pinocchio's Jacobian at the IK's configuration, which pinocchio places at the
grid point; an unreachable point is masked and counted; the seed's configuration is kept over the grid."""
import csv
import json
import os

import numpy as np
import pytest

import vjm
from vjm.cli import main

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
UR10_DIR = os.path.join(ROOT, "data", "robots", "ur10")
UR10 = os.path.join(UR10_DIR, "ur10.yaml")
SEED = [0.0, -1.2, 1.5, -1.8707963267948966, -1.5707963267948966, 0.0]


def test_cli_joint_map_equals_the_api(tmp_path):
    out = tmp_path / "jm"
    spec = "shoulder_lift_joint=-2.4:-0.6:5,elbow_joint=0.5:2.4:4"
    q0 = [0.3, -1.0, 1.2, -1.7, -1.5, 0.2]
    assert main(["map", UR10, "--joints", spec, "--q", ",".join(map(str, q0)), "--self-weight",
                 "--out", str(out)]) == 0
    m = vjm.load_model(UR10)
    jm = m.joint_map(q0, ("shoulder_lift_joint", "elbow_joint"), ((-2.4, -0.6), (0.5, 2.4)), (5, 4),
                     self_weight=True)
    d = np.load(out / "map.npz")
    assert d["k_tran"].shape == (5, 4)
    assert np.allclose(d["k_tran"], jm.k_tran, rtol=1e-13, atol=0)
    assert np.allclose(d["k_rot"], jm.k_rot, rtol=1e-13, atol=0)
    assert np.allclose(d["K"], jm.K, rtol=1e-13, atol=0)
    assert np.allclose(d["sag"], jm.sag, rtol=1e-12, atol=1e-15)
    # the map's own configurations, one joint at a time, against vjm stiffness at a configuration
    assert np.allclose(m.stiffness(d["q"][3, 2]).K, d["K"][3, 2], rtol=1e-12, atol=0)
    with open(out / "map.csv", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 20
    assert float(rows[7]["k_tran_mm_per_N"]) == pytest.approx(jm.k_tran.ravel()[7], rel=1e-9)
    assert float(rows[7]["elbow_joint"]) == pytest.approx(jm.q.reshape(-1, 6)[7, 2], rel=1e-9)
    s = json.loads((out / "summary.json").read_text())
    assert s["kind"] == "joint space" and s["n"] == [5, 4]
    assert s["k_tran_max"] == pytest.approx(jm.k_tran.max(), rel=1e-12)
    assert {p.name for p in out.iterdir()} >= {"map.npz", "map.csv", "k_tran.png", "k_rot.png", "sag.png",
                                              "summary.json"}


def test_cartesian_grid_stiffness_matches_pinocchio_and_unreachable_points_are_masked(tmp_path):
    """Joint springs only (K has a closed form from the Jacobian); a 3 x 3 grid at z = 400 mm whose far
    column (y = 2000 mm) is out of the UR10's reach (1.3 m)."""
    pin = pytest.importorskip("pinocchio")
    from test_robot_pinocchio import _pin_model, _pin_q

    kq = [1.5e8, 1.2e8, 8.0e7, 2.5e7, 2.0e7, 1.5e7]
    names = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
             "wrist_3_joint"]
    urdf = os.path.join(UR10_DIR, "ur10.urdf")
    (tmp_path / "r.yaml").write_text(f"urdf: {urdf}\ntools: [tool0]\nhome: {SEED}\njoints:\n"
                                     + "".join(f"  {n}: {{stiffness: {k:g}}}\n" for n, k in zip(names, kq)))
    out = tmp_path / "cm"
    assert main(["map", str(tmp_path / "r.yaml"), "--grid", "3", "--slice", "z=400",
                 "--box", "500:900,-200:2000,300:500", "--out", str(out)]) == 0
    d = np.load(out / "map.npz")
    P, ok, reached = d["points"], d["ok"], d["reached"]
    far = P[:, 1] == 2000.0
    assert far.sum() == 3 and not reached[far].any() and np.all(np.isnan(d["k_tran"][far]))
    assert ok.sum() >= 3
    s = json.loads((out / "summary.json").read_text())
    assert s["unreachable"] == int((~reached).sum()) and s["evaluated"] == int(ok.sum()) and s["points"] == 9
    with open(out / "map.csv", encoding="utf-8") as fh:
        status = [r["status"] for r in csv.DictReader(fh)]
    assert [st == "unreachable" for st in status] == list(~reached)
    pm = _pin_model(urdf)
    pd = pm.createData()
    tool = pm.getFrameId("tool0")
    tree = vjm.load_model(str(tmp_path / "r.yaml")).tree
    for i in np.flatnonzero(ok):
        qp = _pin_q(pm, tree, d["q"][i])
        pin.forwardKinematics(pm, pd, qp)
        pin.updateFramePlacements(pm, pd)
        pin.computeJointJacobians(pm, pd, qp)
        assert 1000.0 * np.asarray(pd.oMf[tool].translation) == pytest.approx(P[i], abs=1e-6)
        assert np.allclose(pd.oMf[tool].rotation, d["rotation"], atol=1e-9)
        J = np.array(pin.getFrameJacobian(pm, pd, tool, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED))
        J[:3] *= 1000.0  # mm/rad
        K = np.linalg.inv(J @ np.diag(1.0 / np.array(kq)) @ J.T)
        assert np.linalg.norm(d["K"][i] - K) <= 1e-8 * np.linalg.norm(K)
        # the seed's configuration (elbow up, wrist 2 negative) is kept
        assert d["q"][i, 2] > 0 and d["q"][i, 4] < 0


def test_cartesian_map_default_box_is_the_tools_reach():
    from vjm.maps.robot_cartesian import reach_box

    m = vjm.load_model(UR10)
    box = reach_box(m)
    # no tool point is further from the base axis than the links laid end to end (a2 + a3 + d4 + d5 + d6
    # of the UR10: 612 + 572.3 + 163.941 + 115.7 + 92.2 mm, plus the 10 mm rounding); the sampled
    # configurations come near the stretched arm (a2 + a3 = 1184.3 mm) on every side
    assert np.all(box.hi[:2] <= 1566.2) and np.all(box.lo[:2] >= -1566.2)
    assert np.all(box.hi[:2] >= 1100.0) and np.all(box.lo[:2] <= -1100.0)
    again = reach_box(m)
    assert np.array_equal(box.lo, again.lo) and np.array_equal(box.hi, again.hi)


def test_a_map_result_saves_the_set_the_cli_writes(tmp_path, capsys):
    """``JointMap.save`` and ``CartesianMap.save`` write the files ``vjm map`` writes (the same arrays, rows and
    summary); ``summary()`` is the line the command prints; ``_repr_html_`` shows the ranges."""
    from vjm.maps.grid import Workspace
    from vjm.maps.robot_cartesian import cartesian_grid_map

    m = vjm.load_model(UR10)
    spec, q0 = "shoulder_lift_joint=-2.4:-0.6:4,elbow_joint=0.5:2.4:3", [0.3, -1.0, 1.2, -1.7, -1.5, 0.2]
    assert main(["map", UR10, "--joints", spec, "--q", ",".join(map(str, q0)), "--out", str(tmp_path / "cli")]) == 0
    line = capsys.readouterr().out
    jm = m.joint_map(q0, ("shoulder_lift_joint", "elbow_joint"), ((-2.4, -0.6), (0.5, 2.4)), (4, 3))
    assert jm.save(tmp_path / "api") == tmp_path / "api"
    assert line.startswith(jm.summary() + "; wrote")
    box = "400:900,-300:300,300:500"
    assert main(["map", UR10, "--grid", "3", "--box", box, "--self-weight", "--out", str(tmp_path / "ccli")]) == 0
    line = capsys.readouterr().out
    grid = Workspace(np.array([400.0, -300.0, 300.0]), np.array([900.0, 300.0, 500.0])).grid(3)
    cm = cartesian_grid_map(m, grid, m.home, self_weight=True, n=3, box_from="--box")
    assert cm.save(tmp_path / "capi") == tmp_path / "capi"
    assert line.startswith(cm.summary() + "; wrote")
    for cli, api, names in (("cli", "api", ("map.csv",)), ("ccli", "capi", ("map.csv", "sag.png"))):
        for name in names + ("summary.json",):
            assert (tmp_path / cli / name).read_bytes() == (tmp_path / api / name).read_bytes(), name
        a, b = np.load(tmp_path / cli / "map.npz"), np.load(tmp_path / api / "map.npz")
        assert list(a.keys()) == list(b.keys())
        assert all(np.array_equal(a[k], b[k], equal_nan=a[k].dtype.kind == "f") for k in a.keys())
    assert "k_tran_max" in jm._repr_html_() and "unreachable" in cm._repr_html_()
    assert cm.summary_dict()["evaluated"] == int(cm.ok.sum()) > 0
