"""One model type, two kinds: a parallel machine and a serial robot answer the same calls by the same names,
and a call of one kind asked of the other is one VjmError naming the model."""
import dataclasses
import pathlib

import numpy as np
import pytest

import vjm
from vjm.model.base import NotForKind

PUMA = "data/robots/puma560/puma560.yaml"
UR10 = "data/robots/ur10/ur10.yaml"
Q = np.array([[0.1, 0.5, -0.4, 0.2, 0.3, -0.1], [-0.3, 0.8, -1.0, 0.5, -0.6, 0.4], [0.0, 0.2, 0.1, -0.7, 0.9, 1.1]])


@pytest.fixture(scope="module")
def puma():
    return vjm.load_model(PUMA)


@pytest.fixture(scope="module")
def puu():
    return vjm.load_model("puu")


def test_one_type_two_kinds(puma, puu):
    assert isinstance(puma, vjm.Model) and isinstance(puu, vjm.Model)
    assert (puma.kind, puu.kind) == ("serial", "parallel")
    assert type(puma) is not type(puu)


def test_serial_stiffness_map_is_the_joint_springs_through_the_jacobian(puma):
    """stiffness_map(Q) of an arm with joint springs only: C = J diag(1/k) J^T at every configuration, J the
    tool Jacobian (checked against pinocchio in test_robot_pinocchio); one configuration gives the same C."""
    res = puma.stiffness_map(Q)
    k = np.array([puma.joint_springs[n].stiffness for n in puma.q_names])
    for i, q in enumerate(Q):
        J = puma.jacobian(q)
        C = J @ np.diag(1.0 / k) @ J.T
        assert np.allclose(res.C[i], C, rtol=1e-10, atol=1e-12 * np.abs(C).max())
        assert np.allclose(puma.stiffness(q).C, res.C[i], rtol=1e-12, atol=0.0)
    w = np.array([10.0, -20.0, 30.0, 1e3, 0.0, -2e3])
    assert np.allclose(puma.deflection(Q, w), np.einsum("nij,j->ni", res.C, w), rtol=1e-12, atol=0.0)


def test_replace_is_validated_and_immutable(puma):
    """Doubling every joint stiffness halves C exactly (the springs are the only compliance); the original
    model is unchanged; an unknown field or a joint the robot lacks is a VjmError."""
    stiffer = puma.replace(joint_springs={n: dataclasses.replace(s, stiffness=2 * s.stiffness)
                                          for n, s in puma.joint_springs.items()})
    assert np.allclose(stiffer.stiffness_map(Q).C, 0.5 * puma.stiffness_map(Q).C, rtol=1e-12, atol=0.0)
    assert puma.joint_springs["q2"].stiffness == 2.0e8
    with pytest.raises(vjm.VjmError, match="no field 'geometry'"):
        puma.replace(geometry={})
    with pytest.raises(vjm.VjmError, match="no joint 'elbow'"):
        puma.replace(joint_springs={"elbow": puma.joint_springs["q2"]})
    with pytest.raises(vjm.VjmError, match="home must be 6 joint values"):
        puma.replace(home=(0.0, 1.0))


def test_calls_of_the_other_kind_are_one_clear_error(puma, puu):
    with pytest.raises(NotForKind, match=r"puu\.yaml: a parallel machine; self_weight is for serial robots"):
        puu.self_weight([0.0, 0.0, 0.0])
    with pytest.raises(NotForKind, match=r"puu\.yaml: a parallel machine; joint_map is for serial robots"):
        puu.joint_map(None, None, None)
    with pytest.raises(NotForKind, match=r"puma560\.yaml: a serial robot; map is for parallel machines"):
        puma.map(11)
    with pytest.raises(NotForKind, match="joint_forces is for parallel machines"):
        puma.joint_forces(Q[0], np.zeros(6))
    for name in ("geometry", "workspace", "actuator", "kinematic_key"):  # fields and properties alike
        with pytest.raises(NotForKind, match=f"{name} is for parallel machines"):
            getattr(puma, name)
        assert not hasattr(puma, name)
    with pytest.raises(NotForKind, match="q_names is for serial robots"):
        puu.q_names  # noqa: B018
    with pytest.raises(vjm.VjmError, match="vjm sweep is for parallel machines"):
        puma.require("parallel", "vjm sweep")
    with pytest.raises(AttributeError) as err:  # a name neither kind has stays a plain AttributeError
        puma.no_such_thing  # noqa: B018
    assert not isinstance(err.value, vjm.VjmError)


def test_robot_save_round_trip_and_refusals(tmp_path, puma):
    """save writes a file load_model reads to the same stiffness (from any folder: its paths are absolute);
    the file is replaced by the next save, a file vjm did not write is never overwritten, and a model whose
    springs were replaced has no file that says what it holds."""
    out = tmp_path / "sub" / "r.yaml"
    out.parent.mkdir()
    for m in (vjm.load_model(UR10), puma.replace(gravity=(0.0, 9.80665, 0.0), name="wall PUMA")):
        vjm.save_model(m, out)
        back = vjm.load_model(out)
        assert back.kind == "serial" and back.name == m.name and back.gravity == pytest.approx(m.gravity)
        assert np.allclose(back.stiffness_map(Q).K, m.stiffness_map(Q).K, rtol=1e-12, atol=0.0)
        assert np.allclose(back.self_weight(Q[0]), m.self_weight(Q[0]), rtol=1e-9, atol=1e-12)
    mine = tmp_path / "notes.yaml"
    mine.write_text("urdf: my.urdf\n")
    with pytest.raises(vjm.VjmError, match="not a model file vjm wrote"):
        puma.save(mine)
    assert mine.read_text() == "urdf: my.urdf\n"
    with pytest.raises(vjm.VjmError, match="tree or springs were replaced"):
        puma.replace(joint_springs={}).save(tmp_path / "x.yaml")
    assert not (tmp_path / "x.yaml").exists()


def test_a_urdf_alone_is_a_rigid_serial_model():
    """load_model of a .urdf: the same kinematics as the model YAML naming it, no spring (C = 0)."""
    urdf = pathlib.Path(UR10).with_suffix(".urdf")
    rigid, sprung = vjm.load_model(urdf), vjm.load_model(UR10)
    assert isinstance(rigid, vjm.Model) and rigid.kind == "serial" and rigid.q_names == sprung.q_names
    assert np.allclose(rigid.forward(Q, "tool0"), sprung.forward(Q, "tool0"), rtol=0.0, atol=1e-9)
    r = rigid.stiffness(Q[0], "tool0")
    assert np.all(r.C == 0.0) and not r.invertible
