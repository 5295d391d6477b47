"""``vjm path`` on a serial robot, against an equilibrium written here with pinocchio: the compensated
commands, reached by a Newton IK on pinocchio's kinematics and loaded by joint springs under
pinocchio's generalized gravity and the process wrench through pinocchio's Jacobian (solved by
scipy's root), land on the programmed path; the IK holds the seed's configuration; unreachable
points and singular seeds are errors naming the line."""
import os

import numpy as np
import pytest

import vjm
from vjm.errors import VjmError
from vjm.toolpath import Constant

pin = pytest.importorskip("pinocchio")
optimize = pytest.importorskip("scipy.optimize")

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(__file__)))
UR10 = os.path.join(ROOT, "data", "robots", "ur10", "ur10.urdf")
K = {"shoulder_pan_joint": 1.5e8, "shoulder_lift_joint": 1.5e8, "elbow_joint": 8.0e7,
     "wrist_1_joint": 2.5e7, "wrist_2_joint": 2.5e7, "wrist_3_joint": 2.5e7}   # N mm/rad
HOME = [0.0, -1.2, 1.5, -1.8707963267948966, -1.5707963267948966, 0.0]
TOOL = np.array([0.0, 0.0, 150.0])     # mm in tool0's axes
# N at the TCP, world axes: a force (a dead load at the TCP, exact in vjm; an applied moment's work is
# vjm.stiffness.nonlinear's M . phi, exact to O(phi^2) only, so none here)
WRENCH = (40.0, -25.0, 15.0, 0.0, 0.0, 0.0)
PROGRAM = """G21 G90 G17
G0 X780 Y120 Z260
G1 Z250 F300
G1 X830 F1200
G3 X840 Y130 I0 J10
G1 Y170
G0 Z260
"""


def _model_file(tmp_path, home=HOME):
    joints = "".join(f"  {k}: {{stiffness: {v:g}}}\n" for k, v in K.items())
    f = tmp_path / "ur10_joints.yaml"
    f.write_text(f"urdf: {UR10}\ntools: [tool0]\nhome: {list(home)}\njoints:\n{joints}", encoding="utf-8")
    return f


class Pin:
    """The UR10 in pinocchio (m, kg) with a TCP frame 150 mm along tool0's z."""

    def __init__(self):
        self.m = pin.buildModelFromUrdf(UR10)
        self.m.gravity.linear = np.array([0.0, 0.0, -9.80665])
        t0 = self.m.getFrameId("tool0")
        f = self.m.frames[t0]
        place = f.placement * pin.SE3(np.eye(3), TOOL / 1000.0)
        self.tcp = self.m.addFrame(pin.Frame("tcp", f.parentJoint, t0, place, pin.FrameType.OP_FRAME))
        self.d = self.m.createData()
        self.k = np.array([K[self.m.names[j]] for j in range(1, self.m.njoints)]) / 1000.0   # N m/rad

    def pose(self, q):
        pin.framesForwardKinematics(self.m, self.d, q)
        return self.d.oMf[self.tcp]

    def jac(self, q):
        return pin.computeFrameJacobian(self.m, self.d, q, self.tcp, pin.LOCAL_WORLD_ALIGNED)

    def ik(self, p_mm, R, q):
        """Joint values putting the TCP at p (mm) with rotation R, Newton from q."""
        for _ in range(50):
            T = self.pose(q)
            e = np.r_[p_mm / 1000.0 - T.translation, pin.log3(R @ T.rotation.T)]
            if np.linalg.norm(e) < 1e-14:
                break
            q = q + np.linalg.solve(self.jac(q), e)
        assert np.linalg.norm(e) < 1e-12
        return q

    def loaded(self, q_cmd, w):
        """The loaded TCP (mm) of joint commands q_cmd: joint springs against gravity and the wrench w."""
        ws = np.r_[w[:3], np.asarray(w[3:]) / 1000.0]

        def f(q):
            return self.k * (q_cmd - q) - pin.computeGeneralizedGravity(self.m, self.d, q) + self.jac(q).T @ ws

        sol = optimize.root(f, q_cmd, method="hybr", options={"xtol": 1e-13})
        assert np.max(np.abs(f(sol.x))) < 1e-7     # N m, of gravity torques of ~100 N m
        return self.pose(sol.x).translation * 1000.0


def test_compensated_commands_land_on_the_path_in_pinocchio(tmp_path):
    nc = tmp_path / "p.nc"
    nc.write_text(PROGRAM, encoding="utf-8")
    res = vjm.path(str(_model_file(tmp_path)), str(nc), wrench=Constant(WRENCH), tool=tuple(TOOL), step=10.0,
                   chord_tol=0.05, split_moves=True)
    tp = res.toolpath
    P = Pin()
    R = P.pose(np.array(HOME)).rotation.copy()      # the seed's tool orientation, held
    q = np.array(HOME)
    cmd = res.compensation.commanded
    d = np.linalg.norm(res.deflection[:, :3], axis=1)
    assert d.min() > 0.1 and d.max() < 5.0          # sag plus the wrench: tenths of a mm to mm
    for i in range(tp.n):
        w = res.wrench[i]
        q = P.ik(tp.points[i], R, q)                # the programmed point, uncompensated
        before = P.loaded(q, w) - tp.points[i]
        assert np.linalg.norm(before - res.deflection[i, :3]) <= 1e-8 * d[i]
        qc = P.ik(cmd[i, :3], R, q)                 # the compensated command
        after = P.loaded(qc, w) - tp.points[i]
        assert np.linalg.norm(after) <= 1e-3 * d[i], (i, after, d[i])
        assert np.linalg.norm(cmd[i, :3] - tp.points[i]) > 0.5 * d[i]     # the commands did move
    assert np.any(res.wrench[~tp.cutting] == 0) and np.all(d[~tp.cutting] > 0.1)   # rapid moves sag
    # the written program carries those commands (every feed move split in pieces)
    from vjm.toolpath.points import read

    (tmp_path / "c.nc").write_text(res.compensated_text, encoding="utf-8")
    back = read(tmp_path / "c.nc", 0.05, 10.0).points
    gap = np.linalg.norm(cmd[tp.cutting][:, None, :3] - back[None], axis=2).min(axis=1)
    assert gap.max() < 1e-5


def test_configuration_of_the_seed_is_held(tmp_path):
    from vjm.toolpath import robot

    m = vjm.load_model(str(_model_file(tmp_path)))
    pts = np.array([[800.0, 160.0, 250.0 + z] for z in np.linspace(0.0, 80.0, 40)])
    out = {}
    for name, seed in (("up", HOME), ("down", [0.0, 0.2376, -1.5, -0.3084, -1.5707963267948966, 0.0])):
        rt = robot.setup(m, seed, None, tuple(TOOL))
        T = robot.targets(rt, vjm.toolpath.points.read_csv_text(
            "x,y,z\n" + "\n".join(",".join(map(str, p)) for p in pts), "pts.csv"))
        q = robot.follow(rt, T, str)
        P = Pin()
        for qi, Ti in zip(q, T):
            assert np.allclose(P.pose(qi).translation * 1000.0, Ti[:3, 3], atol=1e-6)
        out[name] = q
    assert np.all(out["up"][:, 2] > 0.3) and np.all(out["down"][:, 2] < -0.3)   # elbow up, elbow down


def test_unreachable_point_and_singular_seed_are_errors_naming_the_line(tmp_path):
    nc = tmp_path / "far.nc"
    nc.write_text("G21 G90\nG0 X800 Y160 Z250\nG1 X2500 F1000\n", encoding="utf-8")
    f = str(_model_file(tmp_path))
    with pytest.raises(VjmError, match=r"far.nc line 3: the programmed point \[.*\] mm is out of the robot's reach"):
        vjm.path(f, str(nc), wrench=Constant(WRENCH), step=20.0)
    with pytest.raises(VjmError, match="seed configuration .* is at a singular posture"):
        vjm.path(f, str(nc), wrench=Constant(WRENCH), seed=[0, 0, 0, 0, 0, 0])


def test_passes_of_a_long_program_carry_the_configuration(tmp_path, monkeypatch):
    from vjm.toolpath import passes

    nc = tmp_path / "p.nc"
    nc.write_text(PROGRAM, encoding="utf-8")
    f = str(_model_file(tmp_path))
    kw = dict(wrench=Constant(WRENCH), tool=tuple(TOOL), step=10.0, chord_tol=0.05)
    one = vjm.path(f, str(nc), **kw)
    monkeypatch.setattr(passes, "CHUNK", 3)         # passes of three points
    lines = []
    many = vjm.path(f, str(nc), progress=lines.append, **kw)
    assert one.toolpath.n > 12 and any("points/s" in s for s in lines)
    assert np.allclose(many.deflection, one.deflection, rtol=0, atol=1e-9)
    d = np.linalg.norm(one.deflection[:, :3], axis=1)
    gap = np.linalg.norm(many.compensation.commanded - one.compensation.commanded, axis=1)
    assert np.all(gap <= 2e-4 * d)               # both within 1e-4 of the deflection of the same commands


@pytest.mark.parametrize("kw, message", [
    (dict(seed=[0.0] * 3), "--seed must have 6 joint values"),
    (dict(tool_frame="elbow"), "no tool frame 'elbow'"),
    (dict(tool_frame="base_link"), "is fixed to the robot's base"),
    (dict(method="linear"), "--method linear is for parallel machines"),
])
def test_robot_options_are_checked(tmp_path, kw, message):
    nc = tmp_path / "p.nc"
    nc.write_text(PROGRAM, encoding="utf-8")
    with pytest.raises(VjmError, match=message):
        vjm.path(str(_model_file(tmp_path)), str(nc), wrench=Constant(WRENCH), **kw)


def test_seed_is_for_robots_only(tmp_path):
    with pytest.raises(VjmError, match="--seed and --tool-frame are for serial robots"):
        vjm.path("puu", str(tmp_path / "p.nc"), seed=HOME)


def test_a_path_through_a_wrist_singularity_is_an_error_naming_the_line(tmp_path):
    from vjm.kinematics.transforms import rotation_vector

    m = vjm.load_model(str(_model_file(tmp_path)))
    Q = np.tile(HOME, (30, 1))
    Q[:, 4] = np.linspace(-1.0, 0.47, 30)        # wrist 2 through 0 (between two points): wrists 1, 3 aligned
    T = m.forward(Q)
    rows = [",".join(f"{v:.17g}" for v in (*p, *r)) + ",0,0,0,0,0,0"
            for p, r in zip(T[:, :3, 3], rotation_vector(T[:, :3, :3]))]
    f = tmp_path / "wrist.csv"
    f.write_text("x,y,z,rx,ry,rz,Fx,Fy,Fz,Mx,My,Mz\n" + "\n".join(rows) + "\n", encoding="utf-8")
    # q5 = 0.014 at line 22 (row 21): the first point past the singular posture, or one just before it
    with pytest.raises(VjmError, match=r"wrist.csv line 2[0-2]: the robot is at a singular posture"):
        vjm.path(str(_model_file(tmp_path)), str(f))
    ok = tmp_path / "half.csv"                   # the same path stopping short of it is fine
    ok.write_text("x,y,z,rx,ry,rz,Fx,Fy,Fz,Mx,My,Mz\n" + "\n".join(rows[:12]) + "\n", encoding="utf-8")
    res = vjm.path(str(_model_file(tmp_path)), str(ok))
    assert res.compensation.residual.max() <= 1e-4 * np.linalg.norm(res.deflection[:, :3], axis=1).min()


def test_cli_writes_the_output_set_and_leaves_foreign_files_alone(tmp_path, capsys):
    from vjm.cli import main

    nc = tmp_path / "p.nc"
    nc.write_text(PROGRAM, encoding="utf-8")
    out = tmp_path / "out"
    argv = ["path", str(_model_file(tmp_path)), str(nc), "--tool", "0,0,150", "--wrench", "40,-25,15,0,0,0",
            "--seed", ",".join(map(str, HOME)), "--step", "10", "--out", str(out)]
    assert main(argv) == 0
    assert "serial robot" in capsys.readouterr().out
    names = {"path.csv", "deflection.png", "plan.png", "summary.json", "p_compensated.nc"}
    assert names <= {p.name for p in out.iterdir()}
    text = (out / "p_compensated.nc").read_text(encoding="utf-8")
    assert text.count("\n") == PROGRAM.count("\n") and text != PROGRAM    # the same lines, new numbers
    (out / "mine.txt").write_text("not the tool's", encoding="utf-8")
    before = {p.name: p.stat().st_mtime_ns for p in out.iterdir()}
    assert main(argv) == 2                        # a folder holding another file: refused before any work
    assert "error: " in capsys.readouterr().err
    assert {p.name: p.stat().st_mtime_ns for p in out.iterdir()} == before


def test_a_wrench_far_beyond_the_model_is_refused_at_once(tmp_path):
    nc = tmp_path / "p.nc"
    nc.write_text(PROGRAM, encoding="utf-8")
    with pytest.raises(VjmError, match=r"p.nc line 3: the wrench 1e\+300,0,0,0,0,0 .* deflects the tool by inf"):
        vjm.path(str(_model_file(tmp_path)), str(nc), wrench=Constant((1e300, 0, 0, 0, 0, 0)))
