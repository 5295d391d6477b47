"""Core VJM machinery: transforms, semi-analytic Jacobians (eq. 3-5), springs in series, batching."""
import numpy as np

from linkfea.beam.closed_form import cantilever_compliance, rect_section
from linkfea.mechanics.frames import transform_compliance
from vjm.kinematics.chain import ChainBuilder, forward, jacobian, jacobian_semi_analytic
from vjm.kinematics.transforms import elementary, generator, homogeneous, rotation_vector, vee
from vjm.stiffness.linear import chain_stiffness, spring_compliance

rng = np.random.default_rng(7)


def rand_rot():
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return q * np.sign(np.linalg.det(q))


def rand_spd(scale_t=1e-3, scale_r=1e-7):
    A = rng.normal(size=(6, 6))
    D = np.diag([scale_t] * 3 + [scale_r] * 3) ** 0.5
    return D @ (A @ A.T + 6 * np.eye(6)) @ D


def test_generator_is_standard_and_right_handed():
    """dRx/da at 0 = [[0,0,0],[0,0,-1],[0,1,0]] (the seed's eq. 4 prints its transpose);
    a small rotation about z turns x towards y, and omega = vee(dR R^T) = +a e_z."""
    assert np.array_equal(generator("rx")[:3, :3], [[0, 0, 0], [0, 0, -1], [0, 1, 0]])
    a = 1e-3
    R = elementary("rz", np.array([a]))[0, :3, :3]
    assert R[1, 0] > 0
    assert np.allclose(vee(R - np.eye(3)), [0, 0, a], rtol=1e-6)
    for k in ("tx", "ty", "tz", "rx", "ry", "rz"):
        h = 1e-6
        d = (elementary(k, np.array([0.3 + h])) - elementary(k, np.array([0.3 - h])))[0] / (2 * h)
        assert np.allclose(d, elementary(k, np.array([0.3]))[0] @ generator(k), atol=1e-9)


def _random_chain():
    b = ChainBuilder("rnd")
    b.const(homogeneous(rand_rot(), rng.normal(size=3) * 100))
    b.actuated("tx", "q0")
    b.spring6("foot")
    b.passive("rz", "q1")
    b.passive("ry", "q2")
    b.const(homogeneous(p=(310.0, 0, 0)))
    b.passive("ry", "q2", coef=-1.0)
    b.spring6("leg")
    b.passive("rx", "q3")
    b.passive("ty", "q4")
    b.const(homogeneous(rand_rot(), rng.normal(size=3) * 50))
    return b.build()


def test_jacobian_equals_literal_product_and_finite_difference():
    """jacobian() (closed-form read-out of P V G S T^-1) equals the literal eq. 3-5 product
    to 1e-12, and a central finite difference of the forward kinematics (omega = vee(dR R^T))
    to 1e-6 relative (truncation error h^2 ~ 1e-10 times derivatives of order L)."""
    ch = _random_chain()
    v = rng.normal(size=(5, ch.n_vars)) * 0.3
    T, J = jacobian(ch, v)
    assert np.allclose(T, forward(ch, v), atol=1e-12)
    Jl = jacobian_semi_analytic(ch, v)
    assert np.max(np.abs(J - Jl)) < 1e-12 * np.max(np.abs(J))
    h = 1e-6
    for j in range(ch.n_vars):
        vp, vm = v.copy(), v.copy()
        vp[:, j] += h
        vm[:, j] -= h
        Tp, Tm = forward(ch, vp), forward(ch, vm)
        dp = (Tp[:, :3, 3] - Tm[:, :3, 3]) / (2 * h)
        w = rotation_vector(Tp[:, :3, :3] @ np.swapaxes(Tm[:, :3, :3], 1, 2)) / (2 * h)
        assert np.allclose(J[:, :3, j], dp, atol=1e-6 * 400)
        assert np.allclose(J[:, 3:, j], w, atol=1e-8)


def test_serial_six_dof_springs_equal_adjoint_sum():
    """Issue 4 test 1.  A serial chain of 6-dof springs only: its end compliance is the sum of
    each spring's compliance moved to the end point by the adjoint map (linkfea.mechanics.frames,
    C_B = X C_A X^T), components in world axes.  Same algebra, different code: 1e-12 relative."""
    b = ChainBuilder("serial")
    frames = []
    b.const(homogeneous(rand_rot(), rng.normal(size=3) * 100))
    Cs = {}
    for k in range(3):
        b.spring6(f"s{k}")
        Cs[f"s{k}"] = rand_spd()
        b.const(homogeneous(rand_rot(), rng.normal(size=3) * 200))
    ch = b.build()
    v = np.zeros((1, ch.n_vars))
    # spring frames: prefix products up to each spring
    P = np.eye(4)
    for f in ch.factors:
        if f.kind == "const":
            P = P @ f.T
        elif f.kind == "tx":
            frames.append(P.copy())
    T, J = jacobian(ch, v)
    pe = T[0, :3, 3]
    C_ref = np.zeros((6, 6))
    for k, F in enumerate(frames):
        R, o = F[:3, :3], F[:3, 3]
        C_ref += transform_compliance(Cs[f"s{k}"], R.T, R.T @ (pe - o))
    S = spring_compliance(ch, J, Cs)[0]
    assert np.max(np.abs(S - C_ref)) < 1e-12 * np.max(np.abs(C_ref))
    K, rank = chain_stiffness(ch, J, Cs)
    assert rank[0] == 0
    # K is the inverse of that compliance; compared after Jacobi scaling (mixed units)
    d = np.sqrt(np.diag(C_ref))
    KC = (K[0] * d[:, None] * d[None, :]) @ (C_ref / d[:, None] / d[None, :])
    assert np.max(np.abs(KC - np.eye(6))) < 1e-10


def test_cantilever_chain_matches_eq14_sign_convention():
    """A beam spring at the tip of a chain with no other compliance: tip force Fy gives
    rz = +F L^2 / 2 E Iz (project convention, seed eq. 14)."""
    C = cantilever_compliance(200.0, rect_section(20.0, 10.0, 0.3), 210e3, 0.3, shear=False)
    b = ChainBuilder("beam")
    b.const(homogeneous(p=(200.0, 0, 0)))
    b.spring6("beam")
    ch = b.build()
    T, J = jacobian(ch, np.zeros((1, ch.n_vars)))
    S = spring_compliance(ch, J, {"beam": C})[0]
    Iz = 10.0 * 20.0**3 / 12.0
    assert np.isclose(S[5, 1], 200.0**2 / (2 * 210e3 * Iz), rtol=1e-12)
