"""A planar 2R arm with torsional joint springs under self-weight and a tip load, in closed form;
the large-sag equilibrium from separate solves written here; DH conventions against the textbook
matrices."""
import numpy as np
import pytest
from scipy.optimize import brentq, fsolve

from vjm.errors import EquilibriumError, VjmError
from vjm.modelio.read import model_from_dict as robot_from_dict

L1, L2, C1, C2 = 800.0, 600.0, 350.0, 250.0   # mm: link lengths, joint-to-centre-of-mass distances
M1, M2 = 30.0, 15.0                            # kg
G = 9.80665


def arm(k1, k2=None, gravity=(0.0, -G, 0.0)):
    joints = {"j1": {"stiffness": k1}}
    if k2 is not None:
        joints["j2"] = {"stiffness": k2}
    d = {"name": "planar 2R", "gravity": list(gravity), "joints": joints,
         "dh": {"joints": [{"name": "j1", "a": L1, "mass": M1, "com": [C1 - L1, 0, 0]},
                           {"name": "j2", "a": L2, "mass": M2, "com": [C2 - L2, 0, 0]}]}}
    return robot_from_dict(d)


def grad_potential(phi1, phi2, g, F):
    """dV/dphi of V = -sum m g . p_com - F . p_tip, absolute link angles phi1 and phi1 + phi2 (q2 relative)."""
    a, b = phi1, phi1 + phi2
    e = lambda t: np.array([-np.sin(t), np.cos(t)])  # noqa: E731  d(cos, sin)/dt
    gm = np.asarray(g[:2])
    f = np.asarray(F[:2])
    dV_da = -(M1 * C1 + M2 * L1) * gm @ e(a) - L1 * f @ e(a)
    dV_db = -M2 * C2 * gm @ e(b) - L2 * f @ e(b)
    return np.array([dV_da + dV_db, dV_db])  # joint 1 moves both links, joint 2 the second


def tip(phi1, phi2):
    return np.array([L1 * np.cos(phi1) + L2 * np.cos(phi1 + phi2), L1 * np.sin(phi1) + L2 * np.sin(phi1 + phi2)])


def test_small_deflection_stiffness_and_sag_in_closed_form():
    k1, k2 = 4.0e11, 1.5e11  # N mm/rad: sag of tens of nanometres, linear to 1e-6
    m = arm(k1, k2)
    q = np.array([0.4, -0.9])
    # stiffness: in the plane, C = J diag(1/k) J^T
    J = np.array([[-L1 * np.sin(q[0]) - L2 * np.sin(q.sum()), -L2 * np.sin(q.sum())],
                  [L1 * np.cos(q[0]) + L2 * np.cos(q.sum()), L2 * np.cos(q.sum())]])
    Cp = J @ np.diag([1 / k1, 1 / k2]) @ J.T
    r = m.stiffness(q)
    assert r.C[:2, :2] == pytest.approx(Cp, rel=1e-12)
    assert r.C[5, 5] == pytest.approx(1 / k1 + 1 / k2, rel=1e-12)
    # sag under self-weight and a tip force: theta = -K^-1 dV/dq, tip deflection J theta
    F = np.array([0.0, -200.0, 0.0])
    theta = -grad_potential(q[0], q[1], (0.0, -G), F) / np.array([k1, k2])
    t = m.self_weight(q, wrench=np.r_[F, 0, 0, 0])
    assert t[:2] == pytest.approx(J @ theta, rel=1e-4)
    assert t[5] == pytest.approx(theta.sum(), rel=1e-4)


@pytest.mark.parametrize("gamma", [-np.pi / 2, 0.0, 2.5], ids=["floor", "wall", "tilted"])
def test_large_sag_matches_a_scalar_solve(gamma):
    """Joint 2 rigid, joint 1 soft: the equilibrium angle solves one scalar equation; the sag is
    ~0.3 rad, far outside the linear range.  Gravity turned in the plane: floor, wall, tilted base."""
    k1 = 1.2e6  # above the largest gravity stiffness (~4e5 N mm/rad): one equilibrium
    g = (G * np.cos(gamma), G * np.sin(gamma), 0.0)
    m = arm(k1, gravity=g)
    q = np.array([0.2, 0.7])
    F = np.array([30.0, -120.0])
    theta = brentq(lambda th: k1 * th + grad_potential(q[0] + th, q[1], g, F)[0], -1.5, 1.5, xtol=1e-15)
    assert abs(theta) > 0.03  # rad: 30 mm and more at the tip, far beyond the linear range
    t, info = m.self_weight(q, wrench=[F[0], F[1], 0, 0, 0, 0], return_info=True)
    assert not info["fallback"]  # solved by the compiled Newton (vjm.robot.sagkernel)
    assert t[:2] == pytest.approx(tip(q[0] + theta, q[1]) - tip(*q), rel=1e-9)
    assert t[5] == pytest.approx(theta, rel=1e-9)


def test_large_sag_of_both_joints_matches_a_two_equation_solve():
    k1, k2 = 3.0e6, 1.0e6
    m = arm(k1, k2)
    Q = np.array([[0.1, 0.5], [-0.3, 1.2], [1.0, -0.8]])
    F = np.array([0.0, -80.0])
    t, info = m.self_weight(Q, wrench=[0.0, -80.0, 0, 0, 0, 0], return_info=True)
    assert not np.any(info["fallback"])
    for q, tq in zip(Q, t):
        def res(th, q=q):
            return np.array([k1, k2]) * th + grad_potential(q[0] + th[0], q[1] + th[1], (0.0, -G), F)
        th = fsolve(res, np.zeros(2), xtol=1e-13)
        assert np.max(np.abs(res(th))) < 1e-6 * k2  # N mm
        assert np.max(np.abs(th)) > 0.02
        assert tq[:2] == pytest.approx(tip(q[0] + th[0], q[1] + th[1]) - tip(*q), rel=1e-8)


def test_self_weight_that_does_not_converge_says_so():
    m = arm(2.0e4)  # a joint far too soft to hold the arm: it swings down by more than a right angle
    with pytest.raises(EquilibriumError, match="not found"):
        m.self_weight([0.0, 0.0], max_iter=1)
    t, info = m.self_weight(np.zeros((2, 2)), max_iter=1, strict=False, return_info=True)
    assert np.all(np.isnan(t)) and not np.any(info["converged"]) and np.all(info["fallback"])


def test_self_weight_needs_inertials_and_names_the_link():
    d = {"dh": {"joints": [{"name": "j1", "a": 500.0, "mass": 3.0, "com": [-250, 0, 0]}, {"name": "j2", "a": 300.0}]},
         "joints": {"j1": {"stiffness": 1e8}}}
    with pytest.raises(VjmError, match="link 'link2' .*j2.* no inertial"):
        robot_from_dict(d).self_weight([0.0, 0.0])


def _dh_standard(theta, d, a, alpha):
    ct, st, ca, sa = np.cos(theta), np.sin(theta), np.cos(alpha), np.sin(alpha)
    return np.array([[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st], [0, sa, ca, d], [0, 0, 0, 1]])


def _dh_modified(theta, d, a, alpha):
    ct, st, ca, sa = np.cos(theta), np.sin(theta), np.cos(alpha), np.sin(alpha)
    return np.array([[ct, -st, 0, a], [st * ca, ct * ca, -sa, -sa * d], [st * sa, ct * sa, ca, ca * d], [0, 0, 0, 1]])


def _ry(b):
    c, s = np.cos(b), np.sin(b)
    return np.array([[c, 0, s, 0], [0, 1, 0, 0], [-s, 0, c, 0], [0, 0, 0, 1]])


@pytest.mark.parametrize("convention", ["standard", "modified"])
def test_dh_tables_give_the_textbook_products(convention):
    rng = np.random.default_rng(5)
    rows = []
    for i in range(6):
        r = {"name": f"a{i + 1}", "a": float(rng.uniform(-300, 300)), "alpha": float(rng.uniform(-3, 3)),
             "d": float(rng.uniform(-200, 400)), "theta": float(rng.uniform(-1, 1))}
        if i == 3:
            r["type"] = "prismatic"
        if i == 2:  # Hayati: beta instead of d
            r["d"], r["beta"] = 0.0, 0.01
        rows.append(r)
    m = robot_from_dict({"dh": {"convention": convention, "joints": rows}})
    q = rng.uniform(-1, 1, 6)
    T = np.eye(4)
    for r, qi in zip(rows, q):
        rev = r.get("type", "revolute") == "revolute"
        th = r["theta"] + (qi if rev else 0.0)
        d = r["d"] + (0.0 if rev else qi)
        if convention == "standard":
            T = T @ _dh_standard(th, d, r["a"], r["alpha"]) @ _ry(r.get("beta", 0.0))
        else:  # Rx(alpha) Ry(beta) Tx(a) Rz(theta) Tz(d)
            A = _dh_modified(th, d, r["a"], r["alpha"])
            if "beta" in r:
                Rx = _dh_modified(0.0, 0.0, 0.0, r["alpha"])
                A = Rx @ _ry(r["beta"]) @ np.linalg.inv(Rx) @ A
            T = T @ A
    assert m.forward(q) == pytest.approx(T, rel=1e-12, abs=1e-9)


def test_joint_stiffness_as_table_and_expression_of_q():
    base = {"dh": {"joints": [{"name": "z", "type": "prismatic", "a": 0.0, "limits": [0, 1000]}]}}
    table = robot_from_dict({**base, "joints": {"z": {"stiffness": {"table": [[0, 4e4], [1000, 1e4]]}}}})
    expr = robot_from_dict({**base, "joints": {"z": {"stiffness": "4e4 - 30 * q"}}})
    q = np.array([[0.0], [500.0], [1000.0]])
    assert table.stiffness(q).C[:, 2, 2] == pytest.approx([1 / 4e4, 1 / 2.5e4, 1 / 1e4], rel=1e-12)
    assert expr.stiffness(q).C[:, 2, 2] == pytest.approx([1 / 4e4, 1 / 2.5e4, 1 / 1e4], rel=1e-12)
