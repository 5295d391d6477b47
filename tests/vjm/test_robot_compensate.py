"""Compensation of the self-weight sag (vjm.robot.compensate) against independent truth: pinocchio's
equilibrium of a UR10 with compliant joints (tests/truth_serial.py, no vjm code) evaluates the commands vjm
computes, and a planar 2R arm with torsional springs gives the command in closed form."""
import os
import warnings

import numpy as np
import pytest
from test_robot_closed_form import L1, L2, G, arm, grad_potential, tip

import vjm
from vjm.errors import VjmError
from vjm.robot.model import JointSpring

truth = pytest.importorskip("truth_serial")

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
URDF = os.path.join(ROOT, "data", "robots", "ur10", "ur10.urdf")
#: joint compliances of the truth, rad/(N m); vjm's stiffness is 1000 / c N mm/rad
COMPLIANCE = {"shoulder_lift_joint": 4e-6, "elbow_joint": 8e-6, "wrist_1_joint": 2e-5, "wrist_2_joint": 2e-5}
TOL = 1e-6   # mm
#: how far vjm's and pinocchio's evaluations of one configuration may differ (their kinematics and the two
#: equilibria, each converged far below this), mm
AGREE = 1e-6
#: target offsets from the home tool point, mm: across the workspace in front of the arm
OFFSETS = np.array([[0.0, 0.0, 0.0], [100.0, -200.0, 50.0], [-150.0, 300.0, -100.0], [200.0, 100.0, 150.0]])


@pytest.fixture(scope="module")
def ur10():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m = vjm.load_model(os.path.join(ROOT, "data", "robots", "ur10", "ur10.yaml"))
    springs = {j: JointSpring(stiffness=1000.0 / c) for j, c in COMPLIANCE.items()}
    return m.replace(joint_springs=springs, links={})


def _truth_points(model, q, marker=(0.0, 0.0, 0.0)):
    """Where the truth's deflected arm puts a point of tool0 (mm, base frame) at commands q."""
    hidden = truth.Hidden(compliance=COMPLIANCE, marker=np.asarray(marker, dtype=float))
    return truth.measure(URDF, "tool0", model.q_names, q, hidden)


def _targets(model):
    home = np.array(model.home)
    return home, model.forward(home)[:3, 3] + OFFSETS


def test_commands_land_on_target_points_in_the_truths_equilibrium(ur10):
    home, pts = _targets(ur10)
    c = ur10.compensate(pts, home, tol=TOL)
    assert np.all(c.converged) and np.all(c.reached) and not np.any(c.singular)
    assert np.all(c.residual <= TOL) and np.all((c.iterations >= 1) & (c.iterations <= 10))
    landed = _truth_points(ur10, c.commanded)
    assert np.max(np.linalg.norm(landed - pts, axis=1)) < TOL + AGREE
    # the plain (rigid IK) commands miss by the sag, as the truth sees it: the test can fail
    missed = np.linalg.norm(_truth_points(ur10, c.plain) - pts, axis=1)
    assert np.all(missed > 0.3)
    assert c.miss == pytest.approx(missed, abs=AGREE)


def test_a_payload_is_compensated_too(ur10):
    """A 5 kg point mass at tool0 (the truth's payload at its marker): the commands that carry it land on the
    targets; those computed without it fall short by the payload's extra sag."""
    from vjm.robot.model import Payload

    home, pts = _targets(ur10)
    c = ur10.compensate(pts[:2], home, payload=Payload("tool0", 5.0), tol=TOL)
    assert np.all(c.converged)
    hidden = truth.Hidden(compliance=COMPLIANCE, payload=5.0)
    landed = truth.measure(URDF, "tool0", ur10.q_names, c.commanded, hidden)
    assert np.max(np.linalg.norm(landed - pts[:2], axis=1)) < TOL + AGREE
    bare = ur10.compensate(pts[:2], home, tol=TOL)
    short = np.linalg.norm(truth.measure(URDF, "tool0", ur10.q_names, bare.commanded, hidden) - pts[:2], axis=1)
    assert np.all(short > 0.1)


def test_commands_reach_target_poses_orientation_included(ur10):
    """Poses: three points of the tool frame (its origin and 100 mm along x and y) land where the target frame
    puts them, so position and orientation are both reached."""
    home, pts = _targets(ur10)
    T = np.repeat(ur10.forward(home)[None], len(pts), axis=0)
    T[:, :3, 3] = pts
    T[1, :3, :3] = T[1, :3, :3] @ vjm.kinematics.poses.rotation_matrix(np.array([0.2, -0.1, 0.3]))
    c = ur10.compensate(T, home, tol=TOL)
    assert np.all(c.converged) and not c.positions_only
    for marker in ([0.0, 0.0, 0.0], [100.0, 0.0, 0.0], [0.0, 100.0, 0.0]):
        want = T[:, :3, :3] @ np.array(marker) + T[:, :3, 3]
        assert np.max(np.linalg.norm(_truth_points(ur10, c.commanded, marker) - want, axis=1)) < TOL + AGREE
    # the rigid IK's tool frame turns by the sag too: the plain commands miss the 100 mm point by more
    plain_x = _truth_points(ur10, c.plain, [100.0, 0.0, 0.0])
    assert np.all(np.linalg.norm(plain_x - (T[:, :3, :3] @ np.array([100.0, 0, 0]) + T[:, :3, 3]), axis=1) > 0.3)


def test_planar_2r_command_in_closed_form():
    """The link angles phi that put the tip on the target are the rigid IK's; the springs hold them when the
    command is q = phi + K^-1 dV/dphi (the equilibrium K (phi - q) + dV/dphi = 0, solved for q).  Sag of a
    few hundredths of a radian: far outside the linear range, so the rigid-Jacobian step is tested too."""
    k = np.array([3.0e6, 1.0e6])
    m = arm(k[0], k[1])
    target = np.array([[900.0, 500.0, 0.0], [600.0, -300.0, 0.0], [1100.0, 200.0, 0.0]])
    c = m.compensate(target, [0.2, 0.8], tol=1e-8)
    assert np.all(c.converged)
    for t, q in zip(target, c.commanded):
        c2 = (t[0] ** 2 + t[1] ** 2 - L1**2 - L2**2) / (2 * L1 * L2)
        p2 = np.arccos(c2)   # elbow positive: the seed's branch
        p1 = np.arctan2(t[1], t[0]) - np.arctan2(L2 * np.sin(p2), L1 + L2 * np.cos(p2))
        assert tip(p1, p2) == pytest.approx(t[:2], abs=1e-9)
        want = np.array([p1, p2]) + grad_potential(p1, p2, (0.0, -G), np.zeros(2)) / k
        assert np.max(np.abs(want - np.array([p1, p2]))) > 0.01   # the compensation is large
        assert q == pytest.approx(want, abs=1e-10)


def test_unreachable_and_bad_targets_are_said(ur10):
    home, pts = _targets(ur10)
    far = np.vstack([pts[:1], [[5000.0, 0.0, 0.0]]])
    c = ur10.compensate(far, home, tol=TOL)
    assert c.converged.tolist() == [True, False] and c.reached.tolist() == [True, False]
    assert c.iterations[1] == 0 and np.isnan(c.miss[1])
    with pytest.raises(VjmError, match="q must have 6 values"):
        ur10.compensate(pts, home[:5])
    with pytest.raises(VjmError, match="targets must be poses"):
        ur10.compensate(np.zeros((2, 2)), home)


def test_cli_writes_commands_that_the_model_confirms(tmp_path, capsys):
    """``vjm compensate`` on the shipped UR10 (joint and link springs): each row's joint values, evaluated by the
    model's own equilibrium, put the deflected tool on its target; the unreachable row has none and is flagged;
    its own file is replaced, a user's file never."""
    import csv

    from vjm.cli import main

    ur = os.path.join(ROOT, "data", "robots", "ur10", "ur10.yaml")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m = vjm.load_model(ur)
    home, pts = _targets(m)
    (tmp_path / "t.csv").write_text("x,y,z,label\n" + "".join(f"{p[0]},{p[1]},{p[2]},a\n" for p in pts)
                                    + "5000,0,0,far\n")
    out = tmp_path / "c.csv"
    args = ["compensate", ur, str(tmp_path / "t.csv"), "--seed", "home", "--out", str(out)]
    assert main(args) == 0
    captured = capsys.readouterr()
    assert "4 of 5 targets commanded" in captured.out and captured.err.count("warning:") == 1
    rows = list(csv.DictReader(out.read_text().splitlines()[1:]))
    assert [r["status"] for r in rows] == ["ok"] * 4 + ["unreachable"] and rows[4]["converged"] == "0"
    assert rows[4][m.q_names[0]] == ""
    q = np.array([[float(r[n]) for n in m.q_names] for r in rows[:4]])
    landed = m.forward(q)[:, :3, 3] + m.self_weight(q)[:, :3]
    assert np.max(np.linalg.norm(landed - pts, axis=1)) < TOL
    assert all(float(r["sag_mm"]) > 0.5 for r in rows[:4])
    assert main(args) == 0                        # its own file: replaced
    from linkfea.files.outputs import recognised

    assert recognised(tmp_path) == {"c.csv"}      # known as the tools' own by a folder command (not t.csv)
    (tmp_path / "mine.csv").write_text("my notes\n")
    capsys.readouterr()
    assert main(args[:-1] + [str(tmp_path / "mine.csv")]) == 2
    assert capsys.readouterr().err.count("error:") == 1 and (tmp_path / "mine.csv").read_text() == "my notes\n"
