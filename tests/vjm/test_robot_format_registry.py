"""A robot format added in a test module alone (vjm.modelio.robotformats): a toy ``chain:`` key listing planar
revolute joints by their lengths.  Registered, ``vjm.load_model`` and ``vjm stiffness`` read it with no other
edit; the tool position and the compliance are checked against the planar 2R arm in closed form."""
import json
import types

import numpy as np
import pytest

import vjm
from vjm.cli import main
from vjm.errors import VjmError
from vjm.modelio import robotformats
from vjm.robot.tree import Frame, Tree, TreeJoint

L1, L2 = 400.0, 300.0          # mm
K1, K2 = 2.0e8, 5.0e7          # N mm/rad
Q = [(0.3, 0.9), (-1.1, 0.4), (2.0, -1.7)]


def _translate(x: float) -> np.ndarray:
    T = np.eye(4)
    T[0, 3] = x
    return T


def _read(mapping, base_dir):
    """``chain: [{name: j1, length: 400}, ...]``: revolute joints about z, each link along its x."""
    rows = mapping["chain"]
    if not isinstance(rows, list) or not rows:
        raise VjmError("chain must be a list of {name, length}")
    joints, x = [], 0.0
    for i, r in enumerate(rows):
        joints.append(TreeJoint(str(r["name"]), i - 1, _translate(x), "rz", "revolute", child=f"{r['name']}_link"))
        x = float(r["length"])
    frames = (Frame("tool", len(joints) - 1, _translate(x)),)
    return Tree(str(mapping.get("name", "chain")), tuple(joints), frames, (), ("tool",), "chain")


CHAIN = types.SimpleNamespace(KEYS=("chain",), DESCRIBES="chain: (planar links)",
                              recognises=lambda d: isinstance(d, dict) and "chain" in d, read=_read)


@pytest.fixture
def chain_file(tmp_path, monkeypatch):
    monkeypatch.setitem(robotformats.READERS, "chain", CHAIN)   # undone after the test
    p = tmp_path / "arm.yaml"
    p.write_text(f"name: arm\nchain:\n  - {{name: j1, length: {L1}}}\n  - {{name: j2, length: {L2}}}\n"
                 f"joints:\n  j1: {{stiffness: {K1}}}\n  j2: {{stiffness: {K2}}}\n")
    return p


def _truth(q1, q2):
    """Tool position (mm) and the translational compliance (3x3, mm/N) of a planar 2R arm with joint springs:
    ``C = Jv diag(1/k) Jv^T``, Jv's columns ``z x (p - p_joint)``."""
    e = np.array([L1 * np.cos(q1), L1 * np.sin(q1), 0.0])
    p = e + [L2 * np.cos(q1 + q2), L2 * np.sin(q1 + q2), 0.0]
    Jv = np.column_stack([np.cross([0, 0, 1.0], p), np.cross([0, 0, 1.0], p - e)])
    return p, Jv @ np.diag([1 / K1, 1 / K2]) @ Jv.T


def test_a_registered_format_loads_and_matches_the_closed_form(chain_file):
    m = vjm.load_model(chain_file)
    assert m.kind == "serial" and m.q_names == ("j1", "j2")
    for q in Q:
        p, C = _truth(*q)
        np.testing.assert_allclose(m.forward(np.array(q))[:3, 3], p, rtol=0, atol=1e-9)
        r = m.stiffness(np.array(q))
        np.testing.assert_allclose(r.C[:3, :3], C, rtol=1e-9, atol=1e-12 * np.abs(C).max())
        assert r.k_tran == pytest.approx(np.linalg.eigvalsh(C)[-1], rel=1e-9)


def test_vjm_stiffness_reads_it(chain_file, capsys):
    q = Q[0]
    assert main(["stiffness", str(chain_file), "--q", f"{q[0]},{q[1]}", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    p, C = _truth(*q)
    (tool,) = doc["tools"].values()
    np.testing.assert_allclose(tool["point_mm"], p, rtol=0, atol=1e-9)
    np.testing.assert_allclose(np.array(tool["C"])[:3, :3], C, rtol=1e-9, atol=1e-12 * np.abs(C).max())
    assert tool["k_tran_mm_per_N"] == pytest.approx(np.linalg.eigvalsh(C)[-1], rel=1e-9)


def test_without_the_entry_the_file_is_no_robot(tmp_path):
    p = tmp_path / "arm.yaml"
    p.write_text("name: arm\nchain:\n  - {name: j1, length: 400}\n")
    assert "chain" not in robotformats.READERS
    with pytest.raises(VjmError, match="unknown top-level keys"):
        vjm.load_model(p)


def test_two_formats_in_one_file_are_refused(chain_file, tmp_path):
    p = tmp_path / "both.yaml"
    p.write_text("chain:\n  - {name: j1, length: 400}\ndh:\n  joints: [{a: 100}]\n")
    with pytest.raises(VjmError, match=r"exactly one of urdf: \(a file\), dh: \(a table\) and chain: \(planar"):
        vjm.load_model(p)
