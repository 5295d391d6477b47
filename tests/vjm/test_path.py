"""``vjm path``: deflection along a toolpath against independent references, and its compensation
checked by a separate nonlinear equilibrium (not the compensation loop's own state)."""
import json
import os

import numpy as np
import pytest
import truth as tr
import yaml
from typer.testing import CliRunner

import vjm
from linkfea.files.outputs import MANIFEST
from vjm import VjmError
from vjm.cli import app
from vjm.kinematics.poses import rotation_matrix
from vjm.stiffness import nonlinear
from vjm.toolpath import Constant, Milling
from vjm.toolpath import deflect as dfl
from vjm.toolpath.points import read_csv_text

PUU = "data/orthoglide/puu.yaml"
HEXAPOD = "data/machines/hexapod_6ups.yaml"
E_AL = 70_000.0  # MPa, the aluminium of puu.yaml's beams


def _csv(tmp_path, P, W=None, name="p.csv", rot=None):
    cols = ["x", "y", "z"] + (["rx", "ry", "rz"] if rot is not None else []) + \
        (["Fx", "Fy", "Fz", "Mx", "My", "Mz"] if W is not None else [])
    A = np.hstack([P] + ([rot] if rot is not None else []) + ([W] if W is not None else []))
    f = tmp_path / name
    f.write_text(",".join(cols) + "\n" + "\n".join(",".join(repr(float(v)) for v in r) for r in A) + "\n")
    return f


def _tcp_loaded(model, cmd_tcp, W_tcp, tool):
    """Loaded TCP positions (n, 3) of commanded TCP points by vjm.stiffness.nonlinear directly, with the lever
    written out here: platform point = cmd - tool, wrench moved by M += tool x F, TCP = p + u + R tool."""
    P = cmd_tcp - tool
    W = np.array(W_tcp, dtype=float)
    W[:, 3:] += np.cross(np.broadcast_to(tool, P.shape), W[:, :3])
    t = nonlinear.deflection_map(model, P, W)
    return P + t[:, :3] + np.einsum("nij,j->ni", rotation_matrix(t[:, 3:]), tool)


def test_linear_deflection_is_C_w_from_model_stiffness_at_every_point(tmp_path):
    """Linear TCP deflection (tool at the platform point) = model.stiffness(p).C @ w, pose by pose."""
    m = vjm.load_model(PUU)
    rng = np.random.default_rng(4)
    P = rng.uniform(-40, 90, (12, 3))
    W = rng.normal(0, 50, (12, 6)) * [1, 1, 1, 20, 20, 20]
    res = vjm.path(m, _csv(tmp_path, P, W), method="linear", compensate=False)
    ref = np.stack([m.stiffness(p).C @ w for p, w in zip(P, W)])
    np.testing.assert_allclose(res.deflection, ref, rtol=1e-10, atol=1e-15)


def test_orthoglide_beam_links_closed_form_at_q0(tmp_path):
    """At the isotropic point Q0 of the 3-PUU every leg lies along its actuator, so a force along an
    axis is carried axially by one chain in series: dx = (1/k_a + L_f/(E A_f) + L_l/(E A_l)) Fx with
    the beams of puu.yaml (foot 60 x 10 x 50 mm, leg 30 x 10 x 310 mm, aluminium)."""
    m = vjm.load_model(PUU)
    c = 1.0 / m.actuator.stiffness + 50.0 / (E_AL * 600.0) + 310.0 / (E_AL * 300.0)
    F = np.array([[120.0, 0, 0, 0, 0, 0], [0, -80.0, 0, 0, 0, 0], [0, 0, 45.0, 0, 0, 0]])
    res = vjm.path(m, _csv(tmp_path, np.zeros((3, 3)), F), method="linear", compensate=False)
    np.testing.assert_allclose(res.deflection[:, :3], c * F[:, :3], rtol=1e-12, atol=1e-14)


def test_tool_lever_gives_a_symmetric_tcp_compliance(tmp_path):
    """Maxwell-Betti: the TCP's force -> translation compliance, built from unit forces at the TCP
    through the lever (M += r x F, d = t + rot x r), is symmetric and positive definite; a lever
    applied with the wrong sign on either side breaks the symmetry."""
    m = vjm.load_model(PUU)
    tool = np.array([10.0, -20.0, -150.0])
    p = np.array([20.0, 10.0, 5.0])
    tp = read_csv_text("x,y,z\n" + "\n".join(["20,10,5"] * 3) + "\n")
    Ct = dfl.linear(m, tp.poses + tool, np.hstack([np.eye(3), np.zeros((3, 3))]), tool)[:, :3].T
    assert np.allclose(Ct, Ct.T, rtol=1e-9, atol=1e-12 * np.abs(Ct).max())
    assert np.all(np.linalg.eigvalsh(Ct) > 0)
    C0 = m.stiffness(p).C[:3, :3]
    assert np.trace(Ct) > np.trace(C0)  # the lever only adds compliance


@pytest.mark.parametrize("tool", [(0.0, 0.0, 0.0), (0.0, 0.0, -80.0)])
def test_compensation_checked_by_a_separate_equilibrium(tmp_path, tool):
    """The compensated commands, solved again by vjm.stiffness.nonlinear (lever written out in this test), put the
    loaded TCP on the programmed points within 1e-3 of the uncompensated deflection or 1 nm."""
    m = vjm.load_model(PUU)
    tool = np.array(tool)
    rng = np.random.default_rng(5)
    P = rng.uniform(-50, 100, (15, 3))
    W = rng.normal(0, 300, (15, 6)) * [1, 1, 1, 0, 0, 0]
    res = vjm.path(m, _csv(tmp_path, P, W), tool=tool)
    d0 = np.linalg.norm(_tcp_loaded(m, P, W, tool) - P, axis=1)
    cmd = res.compensation.commanded
    err = np.linalg.norm(_tcp_loaded(m, cmd, W, tool) - P, axis=1)
    assert np.all((err <= 1e-3 * d0) | (err <= 1e-6))
    assert np.all(d0 > 1e-3)  # the check is not empty: the loads deflect the tool by micrometres
    # and the file written back (CSV) carries those commands
    back = read_csv_text(res.compensated_text)
    np.testing.assert_allclose(back.points, cmd, atol=1e-6)
    np.testing.assert_allclose(back.wrench, W)


def test_compensation_with_gravity_and_clearance_of_the_model(tmp_path):
    """A model carrying vjm diagnose's effects (a weight, actuator backlash): the compensated commands,
    checked by a separate equilibrium with the weight added and the backlash imposed here (each
    actuator's slip toward its force from the joint forces), land on the programmed points."""
    base = vjm.load_model(PUU)
    weight, b = 150.0, 0.002
    m = base.replace(effects={"gravity": {"weight": weight}, "clearance": {"backlash": b}})
    rng = np.random.default_rng(6)
    P = rng.uniform(-30, 80, (8, 3))
    W = rng.normal(0, 200, (8, 6)) * [1, 1, 1, 0, 0, 0]
    res = vjm.path(m, _csv(tmp_path, P, W))
    cmd = res.compensation.commanded
    Wt = W.copy()
    Wt[:, 2] -= weight
    tau = base.joint_forces(cmd, Wt)["actuator"]
    slip = {"actuator": (b * np.sign(tau))[:, :, None]}
    t = nonlinear.deflection_map(base, cmd, Wt, offsets=slip)
    d0 = np.linalg.norm(res.deflection[:, :3], axis=1)
    err = np.linalg.norm(cmd + t[:, :3] - P, axis=1)
    assert np.all((err <= 1e-3 * d0) | (err <= 1e-6))
    assert d0.min() > b  # the backlash and the weight are part of what was compensated


def test_actuator_clearance_equals_the_closed_form_slip_of_the_3puu(tmp_path):
    """The backlash imposed inside the equilibrium (rest value of the actuator springs) moves the TCP as
    tests/truth.py's closed form does: dp = J^-1 b sign(tau), tau = J^-T F, with J = dq/dp of the
    3-PUU's rigid inverse kinematics in closed form (no vjm chains)."""
    base = vjm.load_model(PUU)
    P = np.array([[10.0, 20.0, -5.0], [60.0, -30.0, 40.0]])
    W = np.array([[40.0, -25.0, 60.0, 0, 0, 0], [-35.0, 20.0, 10.0, 0, 0, 0]])
    b = 1e-3
    m = base.replace(effects={"clearance": {"backlash": b}})
    diff = dfl.nonlinear_tcp(m, P, W, np.zeros(3)) - dfl.nonlinear_tcp(base, P, W, np.zeros(3))
    ref = tr.backlash_twist(tr.Truth(backlash=b), P, W)
    # the slip acts on a loaded machine: the two agree to the order of its geometric nonlinearity
    np.testing.assert_allclose(diff[:, :3], ref[:, :3], rtol=2e-3, atol=1e-9)
    assert np.abs(diff[:, 3:]).max() < 1e-4 * b  # a slip of the actuators does not turn the platform


def test_rigid_links_closed_form_of_the_actuators(tmp_path):
    """Rigid foot, a leg 1e9 times stiffer than puu.yaml's, ideal U joints: the 3-PUU is a translational
    machine whose only springs are its actuators, so d = c_a J^-1 J^-T F with J = dq/dp of
    tests/truth.py's closed-form inverse kinematics (tau = J^-T F, dq = c_a tau, dp = J^-1 dq), at random
    points of the workspace; the leg's residual compliance is < 1e-6 of the actuators' (its bending too)."""
    m0 = vjm.load_model(PUU)
    m = m0.replace(foot=vjm.LinkSpring.rigid(), leg=vjm.LinkSpring.inline(m0.leg.compliance * 1e-9))
    rng = np.random.default_rng(9)
    P = tr.postures(10, rng)
    W = np.hstack([rng.normal(0, 100, (10, 3)), np.zeros((10, 3))])
    res = vjm.path(m, _csv(tmp_path, P, W), method="linear", compensate=False)
    J = tr.actuator_jacobian(P, 310.0)
    Ji = np.linalg.inv(J)
    ref = np.einsum("nij,nkj,nk->ni", Ji, Ji, W[:, :3]) / m.actuator.stiffness
    np.testing.assert_allclose(res.deflection[:, :3], ref, rtol=1e-5, atol=1e-6 * np.abs(ref).max())


def test_hexapod_pose_path_compensates_position_and_orientation(tmp_path):
    """A 6-dof platform: poses x,y,z,rx,ry,rz; the compensated poses, solved again, give a loaded TCP on
    the programmed position and orientation (rotation error within 1e-3 of the uncompensated one)."""
    m = vjm.load_model(HEXAPOD)
    P = np.array([[0.0, 0.0, 550.0], [20.0, -10.0, 560.0], [-30.0, 15.0, 540.0]])
    R = np.array([[0.0, 0.0, 0.0], [0.02, -0.01, 0.05], [-0.03, 0.02, -0.04]])
    W = np.array([[500.0, -300, 800, 2e4, -1e4, 3e4]] * 3)
    res = vjm.path(m, _csv(tmp_path, P, W, rot=R))
    cmd = res.compensation.commanded
    t = nonlinear.deflection_map(m, cmd, W)
    pos_err = np.linalg.norm(cmd[:, :3] + t[:, :3] - P, axis=1)
    Rl = rotation_matrix(t[:, 3:]) @ rotation_matrix(cmd[:, 3:])
    rot_err = np.linalg.norm(vjm.kinematics.transforms.rotation_vector(rotation_matrix(R) @ np.swapaxes(Rl, 1, 2)), axis=1)
    d0 = np.linalg.norm(res.deflection[:, :3], axis=1)
    r0 = np.linalg.norm(res.deflection[:, 3:], axis=1)
    assert np.all((pos_err <= 1e-3 * d0) | (pos_err <= 1e-6))
    assert np.all(rot_err <= 1e-3 * r0)


def test_three_dof_machine_refuses_orientations(tmp_path):
    f = _csv(tmp_path, np.zeros((2, 3)), np.zeros((2, 6)), rot=np.zeros((2, 3)))
    with pytest.raises(VjmError, match="only translates"):
        vjm.path(PUU, f)


def test_compensated_point_leaving_the_workspace_names_the_line(tmp_path):
    """A point on the face x = 126.35 of the Orthoglide's workspace cube, pushed in -x: its compensated
    command lies outside the cube."""
    f = _csv(tmp_path, np.array([[0.0, 0, 0], [126.35, 0, 0]]), np.array([[-100.0, 0, 0, 0, 0, 0]] * 2))
    with pytest.raises(VjmError, match=r"p.csv line 3: the compensated pose .* outside the workspace"):
        vjm.path(PUU, f)
    vjm.path(PUU, f, wrench=Constant((100.0, 0, 0, 0, 0, 0)))  # pushed inward: fine


def test_milling_model_force_opposes_the_feed(tmp_path):
    tp = read_csv_text("x,y,z\n0,0,0\n10,0,0\n10,5,0\n")
    mm = Milling(kc=800.0, feed_per_tooth=0.05, depth=2.0, width=4.0, diameter=8.0)
    W = mm.wrenches(tp)
    assert mm.force == pytest.approx(800 * 0.05 * 0.5 * 2.0)
    np.testing.assert_allclose(W[1, :3], [-40.0, 0, 0])
    np.testing.assert_allclose(W[2, :3], [0, -40.0, 0])


def test_gcode_path_compensated_program_keeps_its_structure(tmp_path):
    """The pocket program on the 3-PUU with the milling model: the compensated G-code has the same lines,
    words and comments; its end points, solved again, land on the programmed ones."""
    m = vjm.load_model(PUU)
    prog = "G21 G90 G17\nG0 X10 Y10 Z5\nG1 Z0 F300 (plunge)\nG1 X40 F900\nG3 X50 Y20 I0 J10\nG1 Y40\nM5\n"
    f = tmp_path / "part.nc"
    f.write_text(prog)
    res = vjm.path(m, f, wrench=Milling(700.0, 0.05, 1.0, 8.0), step=5.0)
    out = res.compensated_text.splitlines()
    src = prog.splitlines()
    assert len(out) == len(src) and out[0] == src[0] and out[-1] == "M5" and "(plunge)" in out[2]
    from vjm.toolpath import gcode as gc

    a, b = gc.parse_text(prog), gc.parse_text(res.compensated_text)
    assert [ln.gcodes for ln in a.lines] == [ln.gcodes for ln in b.lines]
    ends = np.array([mv.end for mv in gc.moves(b)])
    prog_ends = np.array([mv.end for mv in gc.moves(a)])
    W = res.wrench[res.toolpath.vertex]
    loaded = _tcp_loaded(m, ends, W, np.zeros(3))
    d0 = np.linalg.norm(res.deflection[res.toolpath.vertex, :3], axis=1)
    err = np.linalg.norm(loaded - prog_ends, axis=1)
    assert np.all((err <= 1e-3 * d0 + 1e-4) | (err <= 1e-6))  # + the 0.1 um the file's decimals allow


def test_band_from_covariance_is_the_weights_sensitivity_times_its_se(tmp_path):
    """A model with a calibration block {gravity.weight: 100 N, se 10 N}: the band on each deflection
    component is 1.96 * 10 * |dd/dW|, with dd/dW from two equilibria of vjm.stiffness.nonlinear solved here
    (weights 100 +- 1 N along -z); and 1.96 * 10 * |C(p) g| to first order."""
    from vjm.modelio.write import model_to_dict

    m0 = vjm.load_model(PUU)
    m = m0.replace(effects={"gravity": {"weight": 100.0}})
    d = model_to_dict(m, str(tmp_path))
    d["calibration"] = {"parameters": ["gravity.weight"], "values": [100.0], "covariance": [[100.0]]}
    f = tmp_path / "model_updated.yaml"
    f.write_text(yaml.safe_dump(d))
    P = np.array([[0.0, 0, 0], [50.0, 20.0, -10.0]])
    res = vjm.path(str(f), _csv(tmp_path, P, np.zeros((2, 6))), compensate=False)
    g = np.array([0, 0, -1.0, 0, 0, 0])
    dd = (nonlinear.deflection_map(m0, P, 101.0 * g) - nonlinear.deflection_map(m0, P, 99.0 * g)) / 2.0
    big = np.abs(dd[:, :3]).max()
    np.testing.assert_allclose(res.band.components, 1.959963984540054 * 10.0 * np.abs(dd[:, :3]),
                               rtol=1e-4, atol=1e-6 * big)
    # to first order C(p) g: the preload's geometric stiffness moves it by < 1 % of the largest
    Cg = np.stack([m.stiffness(p).C[:3, 2] for p in P])
    np.testing.assert_allclose(res.band.components, 1.959963984540054 * 10.0 * np.abs(Cg),
                               atol=0.01 * 19.6 * big)


def test_diagnose_writes_the_covariance_and_the_file_loads_back(tmp_path):
    """model_updated.yaml carries calibration: names, values, a symmetric PSD covariance whose diagonal
    gives the report's standard errors; load_model accepts the file."""
    from vjm.discrepancy.diagnosis import write_diagnosis
    from vjm.discrepancy.simulate import simulate
    from vjm.discrepancy.workflow import diagnose

    m = vjm.load_model(PUU)
    rng = np.random.default_rng(2)
    P = np.repeat(rng.uniform(-50, 100, (12, 3)), 3, axis=0)
    W = np.tile(np.array([[100.0, 0, 0, 0, 0, 0], [0, 100.0, 0, 0, 0, 0], [0, 0, 100.0, 0, 0, 0]]), (12, 1))
    data = simulate(m, [("gravity", {"weight": 300.0})], P, W, 1e-4, None, 1)
    dg = diagnose(m, data, effects=["gravity", "clearance"], folds=2)
    write_diagnosis(dg, tmp_path / "rep")
    d = yaml.safe_load(open(tmp_path / "rep" / "model_updated.yaml"))
    cal = d["calibration"]
    cov = np.array(cal["covariance"])
    assert np.allclose(cov, cov.T) and np.all(np.linalg.eigvalsh(cov) >= -1e-12 * np.abs(cov).max())
    fp = dg.report["final_params"]
    for i, nm in enumerate(cal["parameters"]):
        term, p = nm.split(".")
        assert cal["values"][i] == pytest.approx(fp[term][p]["value"])
        assert np.sqrt(cov[i, i]) == pytest.approx(fp[term][p]["se"], rel=1e-9)
    assert "gravity.weight" in cal["parameters"]
    vjm.load_model(tmp_path / "rep" / "model_updated.yaml")


def test_cli_writes_the_output_set_and_errors_are_one_line(tmp_path):
    runner = CliRunner()
    f = tmp_path / "part.nc"
    f.write_text("G21 G90\nG0 X0 Y0 Z5\nG1 Z0 F200\nG1 X20 F800\nG2 X30 Y-10 I0 J-10\n")
    out = tmp_path / "out"
    r = runner.invoke(app, ["path", PUU, str(f), "--out", str(out), "--kc", "700", "--feed-per-tooth", "0.05",
                            "--depth", "1", "--width", "8", "--tolerance", "0.5", "--step", "4"])
    assert r.exit_code == 0, r.output
    assert "PASS" in r.output
    assert sorted(n for n in os.listdir(out) if n != MANIFEST) == [
        "deflection.png", "part_compensated.nc", "path.csv", "plan.png", "summary.json"]
    s = json.load(open(out / "summary.json"))
    assert s["passed"] is True and s["compensated_residual_max_mm"] < 1e-4
    bad = tmp_path / "bad.nc"
    bad.write_text("G21\nG1 X0 Y0 Z0\nG1 X1 Q3\n")
    r = runner.invoke(app, ["path", PUU, str(bad), "--out", str(tmp_path / "o2"), "--wrench", "1,0,0,0,0,0"])
    assert r.exit_code == 2 and r.output.count("\n") == 1 and "line 3" in r.output
    assert not (tmp_path / "o2").exists()
    r = runner.invoke(app, ["path", PUU, str(f), "--out", str(tmp_path / "o3"), "--kc", "700"])
    assert r.exit_code == 2 and "needs all of" in r.output


def test_split_moves_compensate_along_the_moves_and_the_kept_structure_warns(tmp_path):
    """Where the milling force turns at a corner, a kept move starts with the previous move's correction
    (the summary warns); split into pieces, every written point is compensated: the pieces' ends,
    solved again, land on the programmed path."""
    from vjm.toolpath import gcode as gc

    f = tmp_path / "corner.nc"
    f.write_text("G21 G90\nG0 X0 Y0 Z0\nG1 X20 F500\nG1 Y20\n")
    mill = Milling(700.0, 0.05, 1.0, 8.0)
    kept = vjm.path(PUU, f, wrench=mill, tool=(0, 0, -40), step=5.0)
    assert any("farther from the path than the original" in n for n in kept.notes)
    split = vjm.path(PUU, f, wrench=mill, tool=(0, 0, -40), step=5.0, split_moves=True)
    prog = gc.parse_text(split.compensated_text)
    assert len(prog.lines) == 2 + 4 + 4  # two 20 mm moves in 5 mm pieces
    ends = np.array([m.end for m in gc.moves(prog)])[1:]
    W = split.wrench[1:]
    prog_pts = split.toolpath.points[1:]
    loaded = _tcp_loaded(vjm.load_model(PUU), ends, W, np.array([0, 0, -40.0]))
    d0 = np.linalg.norm(split.deflection[1:, :3], axis=1)
    err = np.linalg.norm(loaded - prog_pts, axis=1)
    assert np.all(err <= 1e-3 * d0 + 1e-5)  # + the file's 5 decimals
    assert np.nanmax(np.linalg.norm(split.after[:, :3], axis=1)) <= 1e-3 * d0.max()


def test_cli_refuses_a_folder_with_files_it_did_not_write(tmp_path):
    f = tmp_path / "p.nc"
    f.write_text("G21 G90\nG0 X0 Y0 Z0\nG1 X5 F100\n")
    out = tmp_path / "out"
    out.mkdir()
    (out / "path.csv").write_text("mine\n")
    r = CliRunner().invoke(app, ["path", PUU, str(f), "--out", str(out), "--wrench", "10,0,0,0,0,0"])
    assert r.exit_code == 2 and "path.csv is there and was not written by linkfea or vjm" in r.output
    assert (out / "path.csv").read_text() == "mine\n" and sorted(os.listdir(out)) == ["path.csv"]
    r = CliRunner().invoke(app, ["path", PUU, str(f), "--out", str(tmp_path / "o"), "--wrench", "10,0,0,0,0,0"])
    assert r.exit_code == 0
    r = CliRunner().invoke(app, ["path", PUU, str(f), "--out", str(tmp_path / "o"), "--wrench", "20,0,0,0,0,0"])
    assert r.exit_code == 0  # its own earlier output is replaced


@pytest.mark.parametrize("text,words", [
    ("x,y\n1,2\n", "line 1: columns x,y,z come all together"),
    ("x,y,z,Fx\n1,2,3,4\n", "line 1: columns Fx,Fy,Fz,Mx,My,Mz come all together"),
    ("x,y,z,q\n1,2,3,4\n", "line 1: unknown columns ['q']"),
    ("# a comment\nx,y,z\n1,2,3\n1,2\n", "line 4: 2 fields, the header has 3"),
    ("x,y,z\n1,2,3\n1,a,3\n", "line 3: a value is not a number"),
    ("x,y,z\n1,2,nan\n", "line 2: values must be finite"),
    ("x,y,z\n", "no data rows"),
])
def test_bad_csv_toolpath_is_one_line_naming_the_line(text, words):
    with pytest.raises(VjmError) as e:
        read_csv_text(text, "t.csv")
    assert "\n" not in str(e.value) and str(e.value).startswith("t.csv") and words in str(e.value)


def test_csv_comment_and_blank_rows_with_the_header_s_fields_are_skipped():
    """Rows with as many fields as the header that are comments or empty are not data; the others keep
    their line numbers, and a non-finite value further down is named by its line."""
    tp = read_csv_text("x,y,z\n1,2,3\n# a,b,c\n,,\n\n4, 5 ,6e0\n", "t.csv")
    np.testing.assert_array_equal(tp.poses, [[1, 2, 3], [4, 5, 6]])
    np.testing.assert_array_equal(tp.lines, [2, 6])
    with pytest.raises(VjmError, match="t.csv: line 4: values must be finite"):
        read_csv_text("x,y,z\n1,2,3\n#\n1,inf,3\n", "t.csv")


@pytest.mark.parametrize("kw,words", [
    ({"tolerance": -1.0}, "--tolerance"), ({"step": 0.0}, "--step"), ({"workers": 0}, "workers"),
    ({"method": "quadratic"}, "--method"), ({"tool": (0, 0)}, "tool must be three"),
])
def test_bad_options_are_refused_before_any_work(tmp_path, kw, words):
    f = _csv(tmp_path, np.zeros((1, 3)), np.zeros((1, 6)))
    with pytest.raises(VjmError, match=words):
        vjm.path(PUU, f, **kw)


def test_passive_clearance_against_truths_joint_slips_in_the_equilibrium(tmp_path):
    """The passive joints' clearance that vjm path adds by its unit-load influence equals tests/truth.py's:
    the U joints' crosses tilted toward their moments and imposed as rest values of stiff joint springs
    in a separate, load-free nonlinear equilibrium of the whole machine."""
    base = vjm.load_model(PUU)
    P = np.array([[10.0, 20.0, -5.0], [60.0, -30.0, 40.0]])
    W = np.array([[40.0, -25.0, 60.0, 0, 0, 0], [-35.0, 20.0, 10.0, 2000.0, 0, -1000.0]])
    b = 1e-4
    m = base.replace(effects={"passive_clearance": {"backlash": b}})
    diff = dfl.nonlinear_tcp(m, P, W, np.zeros(3)) - dfl.nonlinear_tcp(base, P, W, np.zeros(3))
    ref = tr.joint_slip_twist(tr.Truth(joint_backlash=b), P, W)
    np.testing.assert_allclose(diff, ref, rtol=1e-3, atol=1e-3 * np.abs(ref).max())


def test_a_long_path_says_how_long_before_it_starts(monkeypatch):
    """A path estimated to take more than a minute reports the estimate first, then its stages; a short one
    reports its stages only."""
    import vjm.toolpath.passes as passes
    import vjm.toolpath.points as points
    from vjm.toolpath.run import path
    from vjm.toolpath.wrench import Constant

    said: list = []
    path("puu", "data/toolpaths/pocket.nc", wrench=Constant((10.0, 0, 0, 0, 0, 0)), compensate=False,
         method="linear", progress=said.append)
    assert said and not any(s.startswith("vjm path: ") for s in said)
    said.clear()
    monkeypatch.setattr(points, "PATH_SECONDS", 100.0)
    monkeypatch.setattr(passes, "CHUNK", 64)  # several passes of the nonlinear equilibrium, each reported
    res = path("puu", "data/toolpaths/pocket.nc", wrench=Constant((10.0, 0, 0, 0, 0, 0)), compensate=False,
               progress=said.append)
    n = len(res.deflection)
    assert said[0].startswith(f"vjm path: {n:,} points, about") and "progress follows" in said[0]
    assert said[1] == f"nonlinear deflection at {n:,} points"
    assert said[2].startswith(f"  64 of {n:,} points, ") and said[2].endswith(" s left") and len(said) >= 3


def test_a_wrench_far_beyond_the_model_is_refused_at_once():
    """``--wrench 1e300,...`` spent 80 s in failing equilibria: the linear deflection at the most loaded point
    answers first (inf mm here; 1e5 N on the 3-PUU deflects it by more than a tenth of its workspace)."""
    from vjm.toolpath.run import path
    from vjm.toolpath.wrench import Constant

    for w in (1e300, 1e7):
        with pytest.raises(VjmError, match="deflects the tool by .* beyond 0.1 x the workspace"):
            path("puu", "data/toolpaths/pocket.nc", wrench=Constant((w, 0, 0, 0, 0, 0)))


def test_rows_are_written_as_the_f_string_formats_write_them():
    """The compensated CSV and path.csv format whole blocks by ``%`` (points.format_rows): the same text as
    csv.writer rows of f-string formats of the same specs, over magnitudes 1e-12..1e12, signed zeros and
    NaN, and whole line numbers."""
    import csv
    import io

    from vjm.toolpath.points import format_rows

    rng = np.random.default_rng(1)
    A = rng.normal(size=(40, 8)) * 10.0 ** rng.integers(-12, 13, size=(40, 8))
    A[0, 0], A[1, 1], A[2, 2] = -0.0, np.nan, -5e-7
    for spec in (".6f", ".9f", ".12g", ".6g", ".6e", ".3e"):
        buf = io.StringIO()
        csv.writer(buf, lineterminator="\n").writerows([f"{v:{spec}}" for v in r] for r in A)
        assert format_rows(["%" + spec] * 8, A) == buf.getvalue(), spec
    lines = np.array([3, 17, 123456789])
    assert format_rows(["%d", "%.6g"], np.column_stack([lines, np.full(3, 1.5)])) == "3,1.5\n17,1.5\n123456789,1.5\n"
