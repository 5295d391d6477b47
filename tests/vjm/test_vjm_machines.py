"""Machines from description files: general chains, numeric inverse kinematics, 6-dof platforms,
and the per-pose kinematics object (``model.kinematics(P)``)."""
import csv

import numpy as np
import pytest
import yaml

import vjm
from vjm import VjmError
from vjm.kinematics.chain import forward
from vjm.kinematics.poses import as_poses, rotation_matrix
from vjm.modelio.read import model_from_dict

HEXAPOD = "data/machines/hexapod_6ups.yaml"
PAIRS = {  # description file, built-in model file, random-pose box (lo, hi), z offset
    "puu": ("data/machines/orthoglide_puu.yaml", "data/orthoglide/puu.yaml", -73.65, 126.35, 0.0),
    "prpar": ("data/machines/orthoglide_prpar.yaml", "data/orthoglide/prpar.yaml", -73.65, 126.35, 0.0),
    "delta": ("data/machines/delta_rrpar.yaml", "data/orthoglide/delta.yaml", -150.0, 150.0, -450.0),
}


def _seed_points(arch):
    """The seed's Q0, Q1, Q2 (data/seed_table1.csv) for the Orthoglide; for the Delta (not in the
    seed's Table 1) the centre of its workspace and two corners of the box of data/orthoglide."""
    if arch == "delta-3RRPaR":
        return np.array([[0.0, 0.0, -450.0], [-100.0, -100.0, -550.0], [100.0, 100.0, -380.0]])
    with open("data/seed_table1.csv") as fh:
        rows = [r for r in csv.DictReader(line for line in fh if not line.startswith("#"))]
    return np.array([[float(r[k]) for k in "xyz"] for r in rows if r["architecture"] == arch])


def _rel(A, B):
    return np.max(np.abs(A - B) / np.max(np.abs(B), axis=(-2, -1), keepdims=True))


@pytest.mark.parametrize("name", sorted(PAIRS))
@pytest.mark.parametrize("joint_springs", [None, 2e6])
def test_description_equals_builtin_module(name, joint_springs):
    """The description file of each built-in architecture gives the built-in module's K to 1e-10
    relative at the seed's Q0, Q1, Q2 and at 20 random reachable poses: same chain product (eq. 1)
    written differently (elementary constants, copies by symmetry) and a numeric inverse kinematics
    against the module's closed form.  With elastic passive joints as well."""
    desc_path, builtin_path, lo, hi, off = PAIRS[name]
    A, B = vjm.load_model(builtin_path), vjm.load_model(desc_path)
    if joint_springs:
        A, B = (m.replace(joints=vjm.Joints(joint_springs)) for m in (A, B))
    rng = np.random.default_rng(7)
    P = rng.uniform(lo, hi, (200, 3))
    P[:, 2] += off
    P = P[A.arch.reachable(A, P)][:20]
    assert len(P) == 20
    P = np.vstack([_seed_points(A.architecture), P])
    ka, kb = A.stiffness_map(P), B.stiffness_map(P)
    assert _rel(kb.K, ka.K) <= 1e-10
    assert np.allclose(B.inverse_kinematics(P), A.inverse_kinematics(P), rtol=0, atol=1e-9)


def _hexapod_geometry(g):
    """Base joints b (6, 3) and platform joints p (6, 3) in the platform frame, from the file's
    geometry, written out here independently of the description: pairs at 0/120/240 deg, base
    joints at +-ab, platform joints at +-(60 - ap) deg, in the order A1 A2 A3 B1 B2 B3."""
    b, p = [], []
    for s in (1.0, -1.0):
        for k in range(3):
            t = np.radians(120.0 * k)
            tb, tp = t + s * np.radians(g["ab"]), t + s * np.radians(60.0 - g["ap"])
            b.append([g["Rb"] * np.cos(tb), g["Rb"] * np.sin(tb), 0.0])
            p.append([g["Rp"] * np.cos(tp), g["Rp"] * np.sin(tp), 0.0])
    return np.array(b), np.array(p)


def _hexapod_poses(n, seed=3):
    rng = np.random.default_rng(seed)
    X = np.zeros((n, 6))
    X[:, :2] = rng.uniform(-80.0, 80.0, (n, 2))
    X[:, 2] = rng.uniform(480.0, 620.0, n)
    X[:, 3:] = rng.uniform(-0.12, 0.12, (n, 3))
    X[0] = [0.0, 0.0, 550.0, 0.0, 0.0, 0.0]
    return X


@pytest.fixture(scope="module")
def hexapod():
    return vjm.load_model(HEXAPOD)


def test_hexapod_rigid_legs_equal_inverse_jacobian_closed_form():
    """6-UPS with rigid struts and only the actuator springs: K = J^T diag(k_act) J with J the
    hexapod's inverse Jacobian, row i = (u_i, a_i x u_i), u_i the unit leg vector from the base
    joint to the platform joint, a_i = R p_i the platform joint relative to the platform point
    (world axes); leg length change = J twist.  20 poses with orientations up to 0.12 rad about
    each axis; 1e-10 relative (round-off)."""
    with open(HEXAPOD) as fh:
        d = yaml.safe_load(fh)
    d["leg"] = {"rigid": True}
    m = model_from_dict(d, "data/machines")
    X = _hexapod_poses(20)
    res = m.stiffness_map(X)
    b, p = _hexapod_geometry(m.geometry)
    k = m.actuator.stiffness
    for x, K in zip(X, res.K):
        R = rotation_matrix(x[3:][None])[0]
        a = p @ R.T
        d = x[:3] + a - b
        u = d / np.linalg.norm(d, axis=1)[:, None]
        J = np.hstack([u, np.cross(a, u)])
        Kc = k * J.T @ J
        assert np.max(np.abs(K - Kc)) <= 1e-10 * np.max(np.abs(Kc))
    assert np.all(res.rank == 6)


def test_hexapod_linear_compliance_is_slope_of_nonlinear_equilibrium(hexapod):
    """6-dof platform, flexible struts (6-dof springs) and actuator springs: the linear C equals
    the central-difference slope of vjm.stiffness.nonlinear (finite rotations, loop closure of every chain,
    its own derivatives) under +-20 N and +-2e4 N mm, column by column to 1e-4 relative, at a
    tilted pose."""
    from vjm.stiffness.nonlinear import deflection_map
    x = np.array([30.0, -40.0, 580.0, 0.05, -0.08, 0.1])
    C = hexapod.stiffness(x).C
    e = np.array([20.0, 20.0, 20.0, 2e4, 2e4, 2e4])
    W = np.concatenate([np.diag(e), -np.diag(e)])
    D = deflection_map(hexapod, np.broadcast_to(x, (12, 6)), W)
    fd = ((D[:6] - D[6:]) / (2 * e[:, None])).T
    for j in range(6):
        assert np.linalg.norm(fd[:, j] - C[:, j]) <= 1e-4 * np.linalg.norm(C[:, j])


@pytest.mark.parametrize("path,P", [
    (HEXAPOD, _hexapod_poses(20, seed=5)),
    ("data/machines/delta_rrpar.yaml", np.array([[0.0, 0.0, -450.0], [120.0, -90.0, -560.0], [-140.0, 30.0, -380.0]])),
])
def test_inverse_kinematics_round_trip(path, P):
    """Forward kinematics (the chain product, eq. 1) of the numeric IK solution lands on the
    requested platform frame: positions to 1e-9 mm, orientations to 1e-12 rad."""
    m = vjm.load_model(path)
    kin = m.kinematics(P)
    F = as_poses(P, m.dof)
    for ch, v in zip(kin.chains, kin.values):
        T = forward(ch, v)
        assert np.max(np.abs(T[:, :3, 3] - F[:, :3, 3])) <= 1e-9
        assert np.max(np.abs(T[:, :3, :3] - F[:, :3, :3])) <= 1e-12
    assert np.allclose(kin.q, np.stack([v[:, ch.actuated[0]] for ch, v in zip(kin.chains, kin.values)], 1))


def test_unreachable_pose_gives_clear_error(hexapod):
    with pytest.raises(VjmError, match=r"pose \(0, 0, 1500, 0, 0, 0\) is unreachable by chain A1"):
        hexapod.stiffness([0.0, 0.0, 1500.0, 0.0, 0.0, 0.0])
    m = vjm.load_model("data/machines/orthoglide_puu.yaml")
    with pytest.raises(VjmError, match="unreachable"):
        m.stiffness([0.0, 0.0, 400.0])
    ok = m.arch.reachable(m, np.array([[0.0, 0.0, 400.0], [0.0, 0.0, 0.0]]))
    assert ok.tolist() == [False, True]


def _cli(args):
    from typer.testing import CliRunner

    from vjm.cli import app
    return CliRunner().invoke(app, args)


def _edit(tmp_path, src, fn, name="bad.yaml"):
    with open(src) as fh:
        d = yaml.safe_load(fh)
    fn(d)
    p = tmp_path / name
    p.write_text(yaml.safe_dump(d, sort_keys=False))
    return p


def _set_transform(k, text):
    def f(d):
        d["chains"][0]["transforms"][k] = text
    return f


@pytest.mark.parametrize("src,edit,message", [
    ("data/machines/orthoglide_puu.yaml", _set_transform(3, "Tq(q1)"),
     r"chain x, element 4 'Tq\(q1\)': unknown transform 'Tq'"),
    ("data/machines/orthoglide_puu.yaml", _set_transform(11, "Tz(2 * L)"),
     r"chain x does not close at the seed posture"),
    ("data/machines/orthoglide_puu.yaml", _set_transform(7, "spring strut"),
     r"chain x, element 8 'spring strut': no link 'strut'"),
    (HEXAPOD, lambda d: d["platform"].update(dof=4), r"platform.dof must be 3 \(translations\) or 6"),
    (HEXAPOD, lambda d: d["platform"].update(dof=3), r"platform.dof is 3, but .* move in 6 independent directions"),
])
def test_bad_descriptions_one_clear_line_and_no_output(tmp_path, src, edit, message):
    """Each bad description: exit status 2, one line 'error: ...' naming the chain and element,
    and no output file."""
    p = _edit(tmp_path, src, edit)
    out = tmp_path / "map"
    r = _cli(["map", str(p), "--grid", "3", "--out", str(out)])
    assert r.exit_code == 2
    lines = [s for s in r.output.splitlines() if s.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: ")
    assert __import__("re").search(message, lines[0]), lines[0]
    assert not out.exists()


def test_cli_six_dof_pose_and_map(tmp_path):
    """--at x,y,z,rx,ry,rz on a 6-dof platform equals the Python API; a map slices the workspace
    at a fixed orientation; a 3-dof platform refuses an orientation."""
    import json
    r = _cli(["stiffness", HEXAPOD, "--at", "10,-20,560,0.02,0.05,-0.1", "--json"])
    assert r.exit_code == 0, r.output
    K = np.array(json.loads(r.output)["K"])
    Kp = vjm.load_model(HEXAPOD).stiffness([10, -20, 560, 0.02, 0.05, -0.1]).K
    assert np.allclose(K, Kp, rtol=1e-12, atol=0)
    r = _cli(["map", HEXAPOD, "--grid", "5", "--slice", "z=560", "--orientation", "0,0,0.1", "--out",
              str(tmp_path / "m")])
    assert r.exit_code == 0, r.output
    z = np.load(tmp_path / "m" / "map.npz")
    assert np.allclose(z["points"][:, 3:], [0, 0, 0.1]) and np.allclose(z["points"][:, 2], 560)
    r = _cli(["stiffness", "data/orthoglide/puu.yaml", "--at", "0,0,0,0.1,0,0"])
    assert r.exit_code == 2 and "3 dof" in r.output


def test_kinematics_object_is_reused_and_checked(hexapod):
    """model.kinematics(P) holds IK and Jacobians once: stiffness_map from it equals stiffness_map
    from the poses; a model changed only in its springs accepts it (and shares the cache), one with
    another geometry refuses it."""
    X = _hexapod_poses(30, seed=9)
    kin = hexapod.kinematics(X)
    assert hexapod.kinematics(X) is kin
    r1, r2 = hexapod.stiffness_map(kin), hexapod.stiffness_map(X)
    assert np.array_equal(r1.K, r2.K)
    soft = hexapod.replace(actuator=vjm.Actuator(5e4))
    assert soft.kinematics(X) is kin
    rs = soft.stiffness_map(kin)
    assert np.all(rs.k_tran > r1.k_tran)
    g = dict(hexapod.geometry, h=560.0)
    with pytest.raises(VjmError, match="another architecture, geometry"):
        hexapod.replace(geometry=g).stiffness_map(kin)
    f = hexapod.joint_forces(kin, [0, 0, -1000.0, 0, 0, 0])
    assert np.allclose(f["chain_wrench"].sum(axis=1), [0, 0, -1000.0, 0, 0, 0], atol=1e-8)


def test_description_saves_and_loads_back(tmp_path, hexapod):
    vjm.save_model(hexapod, tmp_path / "h.yaml")
    m = vjm.load_model(tmp_path / "h.yaml")
    X = _hexapod_poses(5)
    assert np.allclose(m.stiffness_map(X).K, hexapod.stiffness_map(X).K, rtol=1e-13, atol=0)
