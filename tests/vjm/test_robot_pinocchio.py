"""Serial and tree robots against pinocchio (the oracle): forward kinematics, frame Jacobians,
generalized gravity, and the VJM stiffness against K = (J C J^T)^-1 built from pinocchio's Jacobian."""
import os

import numpy as np
import pytest

pin = pytest.importorskip("pinocchio")

from vjm.modelio.urdf import read_urdf  # noqa: E402
from vjm.robot.model import GRAVITY, JointSpring, RobotModel  # noqa: E402

HERE = os.path.dirname(__file__)
ROOT = os.path.dirname(os.path.dirname(HERE))
UR10 = os.path.join(ROOT, "data", "robots", "ur10", "ur10.urdf")
TREE = os.path.join(HERE, "robots", "torso_two_arms.urdf")
RTOL = 1e-10


def _pin_model(path):
    m = pin.buildModelFromUrdf(path)  # mimic joints as independent joints: we set their values
    m.gravity.linear = np.array(GRAVITY)
    return m


def _pin_q(pm, tree, q):
    """pinocchio's configuration (m, cos/sin for continuous joints) of our q (mm, rad)."""
    out = np.zeros(pm.nq)
    qn = list(tree.q_names)
    for j in tree.joints:
        jid = pm.getJointId(j.name)
        v = q[qn.index(j.name)] if j.mimic is None else j.mimic[1] * q[qn.index(j.mimic[0])] + j.mimic[2]
        if j.type == "prismatic":
            v = v / 1000.0
        i = pm.idx_qs[jid]
        if pm.nqs[jid] == 2:
            out[i:i + 2] = np.cos(v), np.sin(v)
        else:
            out[i] = v
    return out


def _pin_columns(pm, tree, Jp):
    """Columns of pinocchio's (.., nv) array summed into our joints (a mimic joint adds to its master's)."""
    out = np.zeros(Jp.shape[:-1] + (tree.nq,))
    qn = list(tree.q_names)
    for j in tree.joints:
        col = Jp[..., pm.idx_vs[pm.getJointId(j.name)]]
        if j.mimic is None:
            out[..., qn.index(j.name)] += col
        else:
            out[..., qn.index(j.mimic[0])] += j.mimic[1] * col
    return out


def _random_q(tree, n, rng):
    lo, hi = tree.limits
    lo = np.where(np.isfinite(lo), lo, -np.pi)
    hi = np.where(np.isfinite(hi), hi, np.pi)
    return lo + (hi - lo) * rng.random((n, tree.nq))


def _rel(a, b):
    return np.linalg.norm(a - b) / np.linalg.norm(b)


@pytest.mark.parametrize("path", [UR10, TREE], ids=["ur10", "torso_two_arms"])
def test_kinematics_jacobians_and_gravity_match_pinocchio(path):
    tree = read_urdf(path)
    model = RobotModel(tree)
    pm = _pin_model(path)
    pd = pm.createData()
    rng = np.random.default_rng(7)
    Q = _random_q(tree, 12, rng)
    frames = [f.name for f in tree.frames if f.joint >= 0]
    for q in Q:
        qp = _pin_q(pm, tree, q)
        pin.forwardKinematics(pm, pd, qp)
        pin.updateFramePlacements(pm, pd)
        pin.computeJointJacobians(pm, pd, qp)
        for name in frames:
            fid = pm.getFrameId(name)
            T = pd.oMf[fid]
            ours = model.forward(q, name)
            assert _rel(ours[:3, 3], 1000.0 * np.asarray(T.translation)) <= RTOL
            assert np.max(np.abs(ours[:3, :3] - T.rotation)) <= RTOL
            Jp = np.array(pin.getFrameJacobian(pm, pd, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED))
            # pinocchio: m and rad per rad (per m for prismatic joints); ours: mm and rad per rad (per mm)
            Jp_mm = Jp.copy()
            for j in tree.joints:
                v = pm.idx_vs[pm.getJointId(j.name)]
                if j.type == "prismatic":
                    Jp_mm[3:, v] *= 1e-3
                else:
                    Jp_mm[:3, v] *= 1e3
            Jp_ours_units = _pin_columns(pm, tree, Jp_mm)
            J = model.jacobian(q, name)
            assert _rel(J, Jp_ours_units) <= RTOL, name
        g = pin.computeGeneralizedGravity(pm, pd, qp)
        scale_g = np.array([1000.0 if tree.joints[tree.joint_index(n)].type != "prismatic" else 1.0
                            for n in tree.q_names])
        g_ours = model.gravity_torques(q)
        assert _rel(g_ours, _pin_columns(pm, tree, np.asarray(g)[None])[0] * scale_g) <= RTOL


def test_vjm_stiffness_matches_the_jacobian_formula_with_link_springs_by_adjoint():
    """UR10 with joint springs and two beam link springs: K from vjm against (J C J^T)^-1 built from
    pinocchio's joint Jacobian and each link spring's frame, moved to the tool by the adjoint map."""
    from vjm.modelio.read import model_from_dict
    from vjm.modelio.yamldata import read_yaml

    d = read_yaml(os.path.join(ROOT, "data", "robots", "ur10", "ur10.yaml"))
    rng = np.random.default_rng(11)
    A = rng.standard_normal((6, 6))
    C6 = A @ A.T * 1e-7 + np.diag([1e-4, 2e-4, 1e-4, 1e-7, 2e-7, 1e-7])  # a bearing's 6x6 spring
    d["joints"]["elbow_joint"]["spring6"] = {"compliance": C6.tolist()}
    model = model_from_dict(d, os.path.dirname(UR10))
    tree = model.tree
    pm = _pin_model(UR10)
    pd = pm.createData()
    rng = np.random.default_rng(3)
    Q = _random_q(tree, 6, rng)
    res = model.stiffness(Q)
    tool = pm.getFrameId("tool0")
    for n, q in enumerate(Q):
        qp = _pin_q(pm, tree, q)
        pin.forwardKinematics(pm, pd, qp)
        pin.updateFramePlacements(pm, pd)
        pin.computeJointJacobians(pm, pd, qp)
        Jp = np.array(pin.getFrameJacobian(pm, pd, tool, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED))
        J = Jp.copy()
        J[:3] *= 1000.0  # mm/rad
        kq = np.array([model.joint_springs[name].stiffness for name in tree.q_names])
        C = J @ np.diag(1.0 / kq) @ J.T
        p_tool = 1000.0 * np.asarray(pd.oMf[tool].translation)
        placed = [(pd.oMf[pm.getFrameId(ps.at)], ps.offset, ps.spring.compliance) for ps in model.links.values()]
        placed.append((pd.oMi[pm.getJointId("elbow_joint")], np.eye(4), C6))
        for f, offset, Cs in placed:
            S = np.eye(4)
            S[:3, :3], S[:3, 3] = f.rotation, 1000.0 * np.asarray(f.translation)
            S = S @ offset
            R, o = S[:3, :3], S[:3, 3]
            # twist of the spring (local axes at its origin) -> tool twist (world axes at the tool point)
            r = p_tool - o
            rx = np.array([[0, -r[2], r[1]], [r[2], 0, -r[0]], [-r[1], r[0], 0]])
            Ad = np.zeros((6, 6))
            Ad[:3, :3] = R
            Ad[:3, 3:] = -rx @ R
            Ad[3:, 3:] = R
            C += Ad @ Cs @ Ad.T
        K = np.linalg.inv(C)
        assert _rel(res.C[n], C) <= 1e-10
        assert _rel(res.K[n], K) <= 1e-8  # through one inversion of a matrix of condition ~1e6
        assert res.points[n] == pytest.approx(p_tool, rel=1e-12)


def test_tree_has_a_stiffness_for_every_tool_and_a_rigid_urdf_has_zero_compliance():
    tree = read_urdf(TREE)
    rigid = RobotModel(tree)
    q = np.zeros(tree.nq)
    q[0] = 100.0
    assert np.all(rigid.stiffness(q).C == 0.0)
    springs = {n: JointSpring(5e5) for n in tree.q_names if n not in ("lift", "r_finger_a")}
    m = RobotModel(tree, springs)
    out = m.stiffness_tools(np.stack([q, q + 0.1]))
    assert set(out) == set(tree.tools)
    # a tool on the left arm is not moved by the right arm's springs, and conversely
    left = m.stiffness(q, "l_tool").C
    only_left = RobotModel(tree, {k: v for k, v in springs.items() if not k.startswith("r")}).stiffness(q, "l_tool").C
    assert np.allclose(left, only_left, rtol=1e-12, atol=0)


def test_masses_from_the_model_file_add_to_the_urdf_inertials():
    """A point mass under masses: against pinocchio with the same mass appended to the joint's body."""
    from vjm.modelio.read import model_from_dict

    d = {"urdf": UR10, "masses": {"forearm_link": {"mass": 3.5, "com": [20.0, -10.0, 300.0]}}}
    model = model_from_dict(d)
    pm = _pin_model(UR10)
    jid = pm.frames[pm.getFrameId("forearm_link")].parentJoint
    place = pm.frames[pm.getFrameId("forearm_link")].placement
    com = place.act(np.array([0.020, -0.010, 0.300]))
    pm.appendBodyToJoint(jid, pin.Inertia(3.5, com, np.eye(3) * 1e-3), pin.SE3.Identity())
    pd = pm.createData()
    for q in _random_q(model.tree, 5, np.random.default_rng(2)):
        g = np.asarray(pin.computeGeneralizedGravity(pm, pd, _pin_q(pm, model.tree, q))) * 1000.0
        assert _rel(model.gravity_torques(q), g) <= RTOL


def test_a_mimic_joint_moves_with_its_master_and_has_its_own_spring():
    """r_finger_b mimics r_finger_a (prismatic, axes -y and y): at the finger's tool the axial compliance
    is the master's spring seen through the multiplier plus the mimic joint's own."""
    tree = read_urdf(TREE)
    ka, kb = 2.0e3, 5.0e3  # N/mm
    m = RobotModel(tree, {"r_finger_a": JointSpring(ka), "r_finger_b": JointSpring(kb)})
    q = np.zeros(tree.nq)
    q[0], q[-1] = 100.0, 12.0
    Jb = m.jacobian(q, "r_fb")
    axis = Jb[:3, tree.q_names.index("r_finger_a")]  # the finger's direction of motion (mimic: -1 x master)
    assert np.linalg.norm(axis) == pytest.approx(1.0, rel=1e-12)
    u = axis / np.linalg.norm(axis)
    C = m.stiffness(q, "r_fb").C
    assert u @ C[:3, :3] @ u == pytest.approx(1.0 / ka + 1.0 / kb, rel=1e-12)
    # the master's tool sees its own spring only
    Ca = m.stiffness(q, "r_fa").C
    ua = m.jacobian(q, "r_fa")[:3, tree.q_names.index("r_finger_a")]
    assert ua @ Ca[:3, :3] @ ua == pytest.approx(1.0 / ka, rel=1e-12)


@pytest.mark.parametrize("path", [UR10, TREE], ids=["ur10", "torso_two_arms"])
def test_small_self_weight_sag_is_pinocchios_linear_sag(path):
    """Stiff joint springs: the equilibrium sag tends to -J K^-1 g(q), with pinocchio's generalized gravity
    g(q) (every body, the other arm of the tree included) and frame Jacobian."""
    tree = read_urdf(path)
    k = {n: (4e12 if tree.joints[tree.joint_index(n)].type != "prismatic" else 4e6) for n in tree.q_names}
    model = RobotModel(tree, {n: JointSpring(v) for n, v in k.items()})
    pm = _pin_model(path)
    pd = pm.createData()
    kv = np.array([k[n] for n in tree.q_names])
    # the left arm's tool on the tree (the default, its deepest leaf, is a finger whose sag is too small to
    # compare to 1e-5)
    tool = "l_tool" if path == TREE else tree.tools[0]
    for q in _random_q(tree, 3, np.random.default_rng(4)):
        qp = _pin_q(pm, tree, q)
        g = _pin_columns(pm, tree, np.asarray(pin.computeGeneralizedGravity(pm, pd, qp))[None])[0]
        g *= np.array([1000.0 if tree.joints[tree.joint_index(n)].type != "prismatic" else 1.0 for n in tree.q_names])
        lin = model.jacobian(q, tool) @ (-g / kv)
        sag = model.self_weight(q, tool)
        assert np.linalg.norm(sag - lin) <= 1e-5 * np.linalg.norm(lin)
