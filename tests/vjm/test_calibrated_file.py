"""calibrated.yaml is complete: everything the source model file states (home, tools, gravity, joint and link
springs, added masses, payload), the total stiffnesses (the source's compliance plus the fitted correction) in
place of the nominal ones, rounded at their standard deviations; the joints the fit did not identify keep their
nominal stiffness, marked "not identified".  Loaded back, it is the source model with the total stiffnesses
substituted (built here with the model's own ``replace``), its K has full rank, and ``vjm compensate`` finds its
seed in the carried ``home:``."""
import os
import re
import warnings

import numpy as np
import pytest
import yaml

import vjm
from vjm.calibration.engine import Calibration
from vjm.calibration.write import rounded, write_calibrated
from vjm.cli import main
from vjm.robot.model import JointSpring

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
UR10 = os.path.join(ROOT, "data", "robots", "ur10", "ur10.yaml")
URDF = os.path.join(ROOT, "data", "robots", "ur10", "ur10.urdf")
Q = np.array([[0.0, -1.2, 1.5, -1.9, -1.57, 0.0], [0.4, -0.7, 0.9, 0.3, 1.1, -0.6],
              [-1.3, -2.1, 2.2, -0.4, 0.2, 2.5], [2.0, -0.2, -1.4, 1.9, -2.3, 0.8]])
#: the total compliances (rad/(N mm)) and their standard deviations; wrist_1's was removed as not observable
FITTED = {"shoulder_lift_joint": (7.9766e-9, 1.63e-10), "elbow_joint": (1.0487e-8, 3.1e-10)}
#: the source's compliances (1 / its stiffnesses): the calibration's values are the corrections to them
NOMINAL = {"shoulder_lift_joint": 1 / 1.5e8, "elbow_joint": 1 / 8.0e7}
WHY = "not observable: its gravity torque hardly varies"
EXTRA = ("masses:\n  forearm_link: {mass: 2.5, com: [0, 30, 200]}\n"
         "payload: {frame: tool0, mass: 3.0, com: [0, 0, 50]}\n")


def _load(path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return vjm.load_model(str(path))


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """The UR10 with its link springs, an added mass and a payload; a calibration of two compliances only
    (no geometry, the marker on tool0's origin), written back."""
    d = tmp_path_factory.mktemp("calfile")
    src_path = d / "ur10_full.yaml"
    src_path.write_text(open(UR10).read().replace("urdf: ur10.urdf", f"urdf: {URDF}") + EXTRA)
    src = _load(src_path)
    values = {f"{j}.compliance": c - NOMINAL[j] for j, (c, _) in FITTED.items()}   # the elbow's < 0
    std = {f"{j}.compliance": s for j, (_, s) in FITTED.items()}
    cal = Calibration(src, "tool0", values, std, {}, np.zeros(3), removed=(("wrist_1_joint.compliance", WHY),))
    write_calibrated(cal, URDF, str(d / "calibrated.urdf"), str(d / "calibrated.yaml"))
    return src_path, src, d / "calibrated.yaml"


def _substituted(src, stiffness):
    """The source model with the stiffnesses ``stiffness`` {joint: N mm/rad} in place of the nominal ones, its link
    springs kept (the calibration deflects them as the source states them)."""
    return src.replace(joint_springs={**src.joint_springs, **{j: JointSpring(stiffness=k) for j, k in stiffness.items()}})


def test_reloads_to_the_source_with_the_fitted_compliances(written):
    _, src, out = written
    back = _load(out)
    # the file's stiffnesses are the fitted 1/c up to the rounding: <= half a tenth of the std (2 digits of it)
    k = {j: yaml.safe_load(out.read_text())["joints"][j]["stiffness"] for j in FITTED}
    for j, (c, s) in FITTED.items():
        assert k[j] == pytest.approx(1.0 / c, rel=0.05 * s / c)
    ref = _substituted(src, k)
    for tool in ("tool0_marker", "tool0"):
        for q in Q:
            rb, rr = back.stiffness(q, tool), ref.stiffness(q, "tool0")
            np.testing.assert_allclose(rb.C, rr.C, rtol=1e-9, atol=1e-12 * np.abs(rr.C).max())
            assert rb.rank == 6
        # the same weight (URDF bodies, the added mass, the payload) under the same gravity, the same sag
        np.testing.assert_allclose(back.self_weight(Q, tool), ref.self_weight(Q, "tool0"), rtol=1e-9, atol=1e-12)
    # the substitution matters: the nominal model is another one
    assert not np.allclose(src.stiffness(Q[0]).C, ref.stiffness(Q[0]).C, rtol=1e-3, atol=0)


def test_the_source_file_entries_are_carried(written):
    src_path, src, out = written
    given, d = yaml.safe_load(src_path.read_text()), yaml.safe_load(out.read_text())
    for key in ("home", "masses", "payload", "gravity", "links"):
        assert d[key] == given[key], key
    assert d["tools"] == ["tool0_marker"] + given["tools"]
    back = _load(out)
    assert back.home == src.home and set(back.links) == set(src.links) == {"upper_arm", "forearm"}
    assert back.payload.mass == 3.0 and back.payload.frame == "tool0"
    assert sum(b.mass for b in back.tree.bodies) == pytest.approx(sum(b.mass for b in src.tree.bodies), rel=1e-12)


def test_joints_not_identified_keep_their_nominal_stiffness(written):
    src_path, src, out = written
    back, lines = _load(out), out.read_text().splitlines()
    nominal = yaml.safe_load(src_path.read_text())["joints"]
    for j in src.q_names:
        line = next(x for x in lines if x.strip().startswith(f"{j}:"))
        if j in FITTED:
            assert "fitted" in line and "not identified" not in line
            continue
        assert back.joint_springs[j].stiffness == src.joint_springs[j].stiffness == nominal[j]["stiffness"]
        assert "not identified" in line
        assert (WHY in line) == (j == "wrist_1_joint")   # why, from the calibration's removed parameters


def _last_digit(text: str) -> float:
    """The place value of the last digit of a number's text (``1.254e+08`` -> 1e5, ``2.35`` -> 0.01)."""
    m = re.fullmatch(r"-?\d+(?:\.(\d*))?(?:e([-+]\d+))?", text)
    assert m, text
    return 10.0 ** (int(m.group(2) or 0) - len(m.group(1) or ""))


def test_fitted_stiffnesses_are_rounded_at_their_standard_deviation(written):
    _, _, out = written
    lines = out.read_text().splitlines()
    for j, (c, s) in FITTED.items():
        line = next(x for x in lines if x.strip().startswith(f"{j}:"))
        text = re.search(r"stiffness: ([^,}\s]+)", line).group(1)
        k, sk = 1.0 / c, s / c ** 2   # the stiffness and its standard deviation (first order)
        unit = _last_digit(text)
        assert abs(float(text) - k) <= 0.5 * unit * (1 + 1e-12)
        assert sk / 100 < unit < sk            # two significant digits of the std: finer than it, no finer
        assert f"+- {sk:.2g}" in line and f"+- {s:.2g}" in line   # the std beside the value, and the compliance's


@pytest.mark.parametrize("seed", range(3))
def test_rounding_keeps_the_value_within_half_its_last_digit(seed):
    rng = np.random.default_rng(seed)
    for _ in range(200):
        v = rng.choice([-1, 1]) * 10.0 ** rng.uniform(-12, 10)
        s = abs(v) * 10.0 ** rng.uniform(-6, -0.5)
        r = rounded(v, s)
        unit = _last_digit(r.text)
        assert float(r) == float(r.text) and yaml.safe_load(r.text) == float(r)   # YAML reads it as that float
        assert abs(float(r) - v) <= 0.5 * unit * (1 + 1e-9) and s / 100 < unit < s


def test_vjm_stiffness_has_full_rank_and_compensate_needs_no_seed(tmp_path, capsys):
    """``vjm calibrate`` on poses of a UR10 that sags (pinocchio's truth), then its calibrated.yaml: K of rank
    6 at the working pose, and ``vjm compensate`` seeded at the carried ``home:``."""
    from vjm.calibration.serial import rotation_matrix

    truth = pytest.importorskip("truth_serial")
    names = _load(UR10).q_names
    rng = np.random.default_rng(3)
    q = rng.uniform(-np.pi, np.pi, (150, 6))
    q[:, 1] = rng.uniform(-np.pi, 0.0, len(q))
    hidden = truth.Hidden(offsets={"elbow_joint": 1e-3}, compliance={"shoulder_lift_joint": 4e-6, "elbow_joint": 8e-6},
                          R=rotation_matrix([0.1, -0.2, 0.5]), t=np.array([1500.0, -800.0, 200.0]),
                          marker=np.array([5.0, 0.0, 80.0]), sigma=0.01)
    p = truth.measure(URDF, "tool0", names, q, hidden, np.random.default_rng(4))
    (tmp_path / "poses.csv").write_text(",".join(list(names) + ["tool0.x", "tool0.y", "tool0.z"]) + "\n" + "".join(
        ",".join(f"{v:.12g}" for v in np.r_[a, b]) + "\n" for a, b in zip(q, p)))
    (tmp_path / "targets.csv").write_text("x,y,z\n900,150,330\n1000,-50,400\n")
    out = tmp_path / "out"
    assert main(["calibrate", UR10, str(tmp_path / "poses.csv"), "--folds", "0", "--out", str(out)]) == 0
    text = (out / "calibrated.yaml").read_text()
    assert "home:" in text and "\nlinks:" in text   # the link springs carried: the fit deflects them
    capsys.readouterr()
    assert main(["stiffness", str(out / "calibrated.yaml"), "--q", "0,-1.2,1.5,-1.9,-1.57,0"]) == 0
    assert "rank(K) = 6" in capsys.readouterr().out
    assert main(["compensate", str(out / "calibrated.yaml"), str(tmp_path / "targets.csv"),
                 "--out", str(tmp_path / "c.csv")]) == 0
    assert (tmp_path / "c.csv").is_file()
