"""The bundled robots (UR10 from its URDF, PUMA 560 from a DH table): batches, gravity direction,
payload, model files written and read back."""
import numpy as np
import pytest

import vjm
from vjm.robot.model import Payload

ROBOTS = ["data/robots/ur10/ur10.yaml", "data/robots/puma560/puma560.yaml"]


def _configs(m, n, seed=1):
    lo, hi = m.tree.limits
    lo, hi = np.maximum(lo, -2.0), np.minimum(hi, 2.0)
    return lo + (hi - lo) * np.random.default_rng(seed).random((n, m.nq))


@pytest.mark.parametrize("path", ROBOTS)
def test_a_batch_of_configurations_is_each_configuration_alone(path):
    m = vjm.load_model(path)
    Q = _configs(m, 5)
    batch = m.stiffness(Q)
    for i, q in enumerate(Q):
        one = m.stiffness(q)
        assert np.allclose(one.K, batch.K[i], rtol=1e-12, atol=0) and np.allclose(one.C, batch.C[i], rtol=1e-12, atol=0)
    w = np.array([10.0, -20.0, 30.0, 1e3, 0.0, -2e3])
    assert np.allclose(m.deflection(Q, w), np.einsum("nij,j->ni", batch.C, w), rtol=1e-14, atol=0)


@pytest.mark.parametrize("path", ROBOTS)
def test_ceiling_mount_reverses_the_sag_to_first_order(path):
    m = vjm.load_model(path)
    Q = _configs(m, 4, seed=2)
    g = np.asarray(m.gravity)
    down = m.self_weight(Q, gravity=g)
    up = m.self_weight(Q, gravity=-g)
    # the linear parts cancel; what remains is second order in the (sub-millimetre) sag
    assert np.max(np.abs(down + up)) < 0.05 * np.max(np.abs(down))
    assert np.max(np.abs(down[:, :3])) > 1e-3  # mm: a sag worth the name


def test_a_payload_adds_its_weight_at_its_frame():
    m = vjm.load_model(ROBOTS[0])
    q = np.array([0.0, -1.0, 1.2, -1.7, -1.57, 0.0])
    heavy = m.self_weight(q, payload=Payload("tool0", 10.0))
    light = m.self_weight(q, payload=Payload("tool0", 0.0))
    w = np.r_[10.0 * np.asarray(m.gravity), 0, 0, 0]
    # the payload as a body load is its weight as a dead load at the tool point (another path of the solver)
    assert heavy == pytest.approx(m.self_weight(q, payload=Payload("tool0", 0.0), wrench=w), rel=1e-9, abs=1e-12)
    # and to first order its share is C w
    lin = m.deflection(q, w)
    assert np.linalg.norm(heavy[:3] - light[:3] - lin[:3]) < 0.01 * np.linalg.norm(lin[:3])


@pytest.mark.parametrize("path", ROBOTS)
def test_model_file_written_and_read_back(path, tmp_path):
    m = vjm.load_model(path)
    out = tmp_path / "robot.yaml"
    m.save(out)
    back = vjm.load_model(out)
    q = _configs(m, 2)
    assert np.array_equal(back.stiffness(q).K, m.stiffness(q).K)


def test_joint_map_is_the_stiffness_and_sag_at_its_grid_points(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    m = vjm.load_model(ROBOTS[0])
    q0 = np.array([0.0, -1.0, 1.2, -1.7, -1.57, 0.0])
    jm = m.joint_map(q0, ("shoulder_lift_joint", "elbow_joint"), ((-2.0, -0.5), (0.5, 2.0)), n=4, self_weight=True)
    i, j = 2, 1
    q = q0.copy()
    q[1], q[2] = jm.a[i], jm.b[j]
    assert jm.k_tran[i, j] == pytest.approx(m.stiffness(q).k_tran, rel=1e-12)
    assert jm.sag[i, j] == pytest.approx(m.self_weight(q), rel=1e-9, abs=1e-12)
    jm.plot("sag").figure.savefig(tmp_path / "sag.png")


def test_a_mass_read_from_a_linkfea_result(tmp_path):
    """masses: {frame: {linkfea: result.json, com}} takes the result's CAD mass (mass_kg)."""
    import json

    from linkfea.mechanics.frames import Frame
    from vjm.modelio.read import model_from_dict

    C = np.diag([1e-4, 1e-4, 1e-4, 1e-8, 1e-8, 1e-8])
    doc = {"schema": "linkfea.result/1", "compliance": C.tolist(), "frame": Frame(np.zeros(3), np.eye(3)).to_dict(),
           "units": {"force": "N", "length": "mm", "angle": "rad", "moment": "N mm"}, "mass_kg": 2.5}
    (tmp_path / "arm.json").write_text(json.dumps(doc))
    urdf = vjm.load_model(ROBOTS[0]).tree.source
    com = [10.0, 0.0, 250.0]
    via = model_from_dict({"urdf": urdf, "masses": {"forearm_link": {"linkfea": "arm.json", "com": com}}},
                          str(tmp_path))
    plain = model_from_dict({"urdf": urdf, "masses": {"forearm_link": {"mass": 2.5, "com": com}}})
    q = _configs(plain, 3)
    assert np.array_equal(via.gravity_torques(q), plain.gravity_torques(q))
    del doc["mass_kg"]
    (tmp_path / "arm.json").write_text(json.dumps(doc))
    with pytest.raises(vjm.VjmError, match="states no mass"):
        model_from_dict({"urdf": urdf, "masses": {"forearm_link": {"linkfea": "arm.json", "com": com}}}, str(tmp_path))


@pytest.mark.parametrize("path", ROBOTS)
def test_compiled_stiffness_equals_the_chain_jacobian_formula(path):
    """The kernel's C and K against C = sum_s J_s C_s J_s^T from vjm.kinematics.chain.jacobian (numpy) and its inverse."""
    from vjm.kinematics.chain import jacobian
    from vjm.robot.tree import chain_values
    from vjm.stiffness.linear import spring_compliance

    m = vjm.load_model(path)
    Q = _configs(m, 50, seed=9)
    r = m.stiffness(Q)
    kin = m.kinematics(Q)
    ch = kin.chains[0]
    C = spring_compliance(ch, jacobian(ch, chain_values(ch, m.tree, Q))[1], m.compliances(kin)[0])
    assert np.allclose(r.C, C, rtol=1e-12, atol=1e-14 * np.abs(C).max())
    # K: the inverse of the same LDL^T as vjm.stiffness.linalg's (some configurations are close to singular: the
    # wrist's, where K reaches 1e13 and an inverse by another route differs in its last digits)
    from vjm.stiffness.linalg import psd_rank_inverse

    Kref, rank, inv = psd_rank_inverse(C)
    assert np.array_equal(r.rank, rank) and np.array_equal(r.invertible, inv)
    scale = np.sqrt(np.einsum("nii->ni", Kref))
    rel = (np.abs(r.K - Kref) / (scale[:, :, None] * scale[:, None, :])).max(axis=(1, 2))
    d = np.sqrt(np.einsum("nii->ni", C))
    cond = np.linalg.cond(C / (d[:, :, None] * d[:, None, :]))
    assert np.all(rel <= 1e-14 * cond)  # round-off of two orderings of the same LDL^T
