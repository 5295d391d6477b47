"""The calibration starts from the model as its file states it (vjm.calibration.nominal) and fits corrections.

- Clean data that ``vjm simulate`` makes from a model (its truth: the model's own nonlinear self-weight equilibrium,
  joint and link springs and payload) name nothing when ``vjm diagnose`` is given the same model: the bundled
  UR10 (3 seeds) and the PUMA 560 (a DH table).
- The measurement model's nominal deflection against that equilibrium: the first-order error is a tenth of the
  noise and less, while leaving the link springs out would be tens of noise sigmas.
- A PUMA 560 with hidden offsets and a stiffer-than-stated joint, calibrated, written back as a DH table and read
  again: the re-read file's forward kinematics and sag land on the simulating truth.
"""
import json
import os
import warnings

import numpy as np
import pytest
import yaml

import vjm
from vjm.calibration.engine import calibrate, instrument_frame
from vjm.calibration.nominal import model_torques, nominal_state, nominal_values
from vjm.calibration.poses import AbsolutePoses
from vjm.calibration.serial import Layout, Problem, predict
from vjm.calibration.simulate import design, measure, parse_hidden
from vjm.calibration.write import calibrated_files, calibrated_model
from vjm.cli import main
from vjm.robot.model import JointSpring

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
UR10 = os.path.join(ROOT, "data", "robots", "ur10", "ur10.yaml")
PUMA = os.path.join(ROOT, "data", "robots", "puma560", "puma560.yaml")
SIGMA = 0.01   # mm


def _load(path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return vjm.load_model(path)


@pytest.mark.parametrize("model, seed", [(UR10, 1), (UR10, 2), (UR10, 3), (PUMA, 1)])
def test_clean_simulated_data_name_nothing(tmp_path, model, seed):
    csv, out = tmp_path / "s.csv", tmp_path / "out"
    assert main(["simulate", model, "--poses", "random:60", "--noise-t", str(SIGMA), "--seed", str(seed),
                 "--out", str(csv)]) == 0
    assert main(["diagnose", model, str(csv), "--out", str(out)]) == 0
    rep = json.loads((out / "report.json").read_text())
    assert rep["named_effects"] == [] and rep["verdict"] == "no_discrepancy"
    files = set(os.listdir(out))
    assert "calibrated.yaml" in files and ("calibrated.urdf" in files) == (model == UR10)   # a DH table: no URDF


def _sag_errors(model, drop_links: bool = False):
    """|predicted - true| (n,) mm at 200 random poses: the nominal measurement model (no correction, the base
    frame) against the model's own equilibrium; and the true sag (n,) mm."""
    frame = model.tools[0]
    Q = design(model, "random:200", np.random.default_rng(5))
    rigid = model.forward(Q, frame)[:, :3, 3]
    true = rigid + model.self_weight(Q, frame)[:, :3]
    n = len(Q)
    nominal = model.replace(links={}) if drop_links else model
    prob = Problem(model, frame, Q, np.zeros(n, dtype=int), ("",), (np.eye(3),), (np.zeros(3),), np.zeros(3),
                   model_torques(model, Q), nominal=nominal_state(nominal, Q, frame, np.zeros(3)))
    pred = predict(prob, Layout((), (), ()), np.zeros(0))
    return np.linalg.norm(pred - true, axis=1), np.linalg.norm(true - rigid, axis=1)


def test_the_nominal_deflection_is_the_equilibrium_to_first_order():
    ur10 = _load(UR10)
    err, sag = _sag_errors(ur10)
    assert np.mean(sag) > 0.3                      # the UR10 sags: the test has teeth
    assert np.max(err) < 0.1 * SIGMA               # second order: a tenth of the tracker's noise
    without, _ = _sag_errors(ur10, drop_links=True)
    assert np.mean(without) > 5 * SIGMA            # the link beams are not negligible
    err, sag = _sag_errors(_load(PUMA))            # joint springs and the 2 kg payload
    assert np.mean(sag) > 0.1 and np.max(err) < 0.1 * SIGMA


def test_nominal_values_are_the_model_file_s():
    ur10, puma = _load(UR10), _load(PUMA)
    got = nominal_values(ur10, ["elbow_joint.compliance", "payload.mass", "elbow_joint.offset"])
    assert got == {"elbow_joint.compliance": 1 / 8.0e7, "payload.mass": 0.0, "elbow_joint.offset": 0.0}
    assert nominal_values(puma, ["payload.mass", "q6.compliance"]) == {"payload.mass": 2.0, "q6.compliance": 1e-7}
    # a spring varying with the joint's value: its smallest compliance (its stiffest) over the joint's limits
    table = ur10.replace(joint_springs={"elbow_joint": JointSpring(table=((-1.0, 1.0), (1e8, 4e8)))})
    assert nominal_values(table, ["elbow_joint.compliance"])["elbow_joint.compliance"] == pytest.approx(1 / 4e8)


@pytest.fixture(scope="module")
def puma_tool(tmp_path_factory):
    """The PUMA 560 carrying a 100 mm tool (the wrist centre alone would not show the wrist's offsets)."""
    d = yaml.safe_load(open(PUMA, encoding="utf-8"))
    d["dh"]["tool"] = {"xyz": [0, 0, 100]}
    path = tmp_path_factory.mktemp("puma") / "puma_tool.yaml"
    path.write_text(yaml.safe_dump(d, sort_keys=False), encoding="utf-8")
    return _load(str(path))


HIDDEN = ["offset:q2=0.002,q3=-0.0015,q5=0.001", "compliance:q2=3"]


def test_a_dh_robot_is_calibrated_and_written_back_as_a_dh_table(puma_tool, tmp_path):
    m = puma_tool
    hidden = parse_hidden(m, HIDDEN, "tool")
    Q = design(m, "random:200", np.random.default_rng(1))
    P = measure(m, Q, hidden, "tool", SIGMA, np.random.default_rng(2))
    cal = calibrate(m, AbsolutePoses(tuple(m.q_names), Q, {"tool": P}, group=np.full(len(Q), "A", dtype=object)),
                    "tool", effects=("geometry", "compliance"))
    assert [s.name for s in cal.stages if s.kept] == ["registration", "geometry", "compliance"]
    texts = calibrated_files(cal)
    assert set(texts) == {"calibrated.yaml"}
    written = yaml.safe_load(texts["calibrated.yaml"])
    assert "dh" in written and "urdf" not in written
    (tmp_path / "calibrated.yaml").write_text(texts["calibrated.yaml"], encoding="utf-8")
    back = _load(str(tmp_path / "calibrated.yaml"))
    # the truth at fresh poses: the robot with the hidden offsets and compliance, sagging (no noise)
    Qn = design(m, "random:100", np.random.default_rng(3))
    truth = measure(m, Qn, hidden, "tool", 0.0, np.random.default_rng(4))
    R, t = instrument_frame(cal, "A")   # the data's frame is the base's; the registration takes what it absorbs
    got = (back.forward(Qn, "tool_marker")[:, :3, 3] + back.self_weight(Qn, "tool_marker")[:, :3]) @ R.T + t
    assert np.max(np.linalg.norm(got - truth, axis=1)) < 3 * SIGMA
    mem = calibrated_model(cal)   # the model in memory is the file's
    assert mem.tools == back.tools == ("tool_marker", "tool")
    np.testing.assert_allclose(mem.forward(Qn, "tool_marker"), back.forward(Qn, "tool_marker"), atol=1e-9)
    nominal = m.forward(Qn, "tool")[:, :3, 3] + m.self_weight(Qn, "tool")[:, :3]
    assert np.mean(np.linalg.norm(nominal - truth, axis=1)) > 50 * SIGMA   # the hidden effects: about a mm
    # the hidden compliance, total: three times the file's, as the re-read stiffness says
    k = back.joint_springs["q2"].stiffness
    s = cal.std["q2.compliance"]
    assert abs(1 / k - 3 / 2.0e8) < 4 * s + 0.01 * 3 / 2.0e8   # within 4 sd (and the file's rounding)
    # q3 as the file states it: its correction, if fitted, within 4 sd of 0
    assert abs(1 / back.joint_springs["q3"].stiffness - 1e-8) < 4 * cal.std.get("q3.compliance", 0.0) + 1e-12


CRAIG = """name: PUMA 560 (Craig's modified DH)
dh:
  convention: modified
  joints:
    - {name: q1, alpha: 0, a: 0, d: 0, mass: 0, com: [0, 0, 0]}
    - {name: q2, alpha: -pi/2, a: 0, d: 0, mass: 17.4, com: [68, 6, -16]}
    - {name: q3, alpha: 0, a: 431.8, d: 149.09, mass: 4.8, com: [0, -70, 14]}
    - {name: q4, alpha: -pi/2, a: 20.3, d: 433.07, mass: 0.82, com: [0, 0, -19]}
    - {name: q5, alpha: pi/2, a: 0, d: 0, mass: 0.34, com: [0, 0, 0]}
    - {name: q6, alpha: -pi/2, a: 0, d: 0, mass: 0.09, com: [0, 0, 32]}
  tool: {xyz: [0, 0, 100]}
joints: {q2: {stiffness: 2.0e+8}, q3: {stiffness: 1.0e+8}}
"""
#: a calibration's geometry: offsets and origin errors (mm, rad) on most joints
GEOMETRY = {"q2.offset": 2e-3, "q2.dx": 0.3, "q2.ez": 4e-4, "q3.offset": -1.5e-3, "q3.dy": -0.2, "q3.ex": 3e-4,
            "q4.dz": 0.5, "q4.ey": -5e-4, "q5.offset": 1e-3, "q6.dx": 0.1, "tool.px": 5.0, "tool.pz": 40.0}


@pytest.mark.parametrize("source", ["standard", "modified"])
def test_a_written_dh_table_has_the_calibrated_kinematics(puma_tool, tmp_path, source):
    """The table written back, read again, moves its marker as the calibration's measurement model does
    (vjm.calibration.serial.chain_frames: the source tree with the origin errors and offsets), both conventions."""
    from vjm.calibration.result import Calibration
    from vjm.calibration.serial import chain_frames

    if source == "modified":
        (tmp_path / "craig.yaml").write_text(CRAIG, encoding="utf-8")
        m = _load(str(tmp_path / "craig.yaml"))
    else:
        m = puma_tool
    p0 = np.array([5.0, -3.0, 20.0])
    cal = Calibration(m, "tool", dict(GEOMETRY), {}, {}, p0)
    (tmp_path / "calibrated.yaml").write_text(calibrated_files(cal)["calibrated.yaml"], encoding="utf-8")
    back = _load(str(tmp_path / "calibrated.yaml"))
    assert yaml.safe_load((tmp_path / "calibrated.yaml").read_text())["dh"]["convention"] == source
    Q = design(m, "random:50", np.random.default_rng(7))
    T = chain_frames(m, Q, "tool", GEOMETRY)
    marker = p0 + np.array([GEOMETRY["tool.px"], 0.0, GEOMETRY["tool.pz"]])
    want = np.einsum("nij,j->ni", T[:, :3, :3], marker) + T[:, :3, 3]
    np.testing.assert_allclose(back.forward(Q, "tool_marker")[:, :3, 3], want, atol=1e-6)
    assert np.max(np.linalg.norm(m.forward(Q, "tool")[:, :3, 3] - want, axis=1)) > 10.0   # the test has teeth
    # each link's centre of mass where the calibrated chain carries it (the source's com in its corrected link frame)
    rows = yaml.safe_load((tmp_path / "calibrated.yaml").read_text())["dh"]["joints"]
    source = m.raw["dh"]["joints"]
    for i, (r, r0) in enumerate(zip(rows, source)):
        L = chain_frames(m, Q, f"link{i + 1}", GEOMETRY)
        want = np.einsum("nij,j->ni", L[:, :3, :3], np.array(r0["com"], dtype=float)) + L[:, :3, 3]
        B = back.forward(Q, f"link{i + 1}")
        np.testing.assert_allclose(np.einsum("nij,j->ni", B[:, :3, :3], np.array(r["com"])) + B[:, :3, 3], want,
                                   atol=1e-6)
