"""``vjm diagnose`` on absolute poses made by pinocchio's truth (tests/truth_serial.py, no vjm code): a two-arm
torso measured at a marker on each hand (two points per row, no sigma columns, a file in its own format read
through a column map), an unknown instrument frame and unknown marker offsets.  A hidden joint compliance
is named, alone, recovered, and holds on another set-up (--validate); clean data name nothing (k-fold); the calibrated URDF written beside the report
carries both markers and, loaded in pinocchio, reproduces the calibration's own positions to 1e-9 m."""
import json

import numpy as np
import pytest

truth = pytest.importorskip("truth_serial")

from vjm.calibration.serial import rotation_matrix  # noqa: E402
from vjm.cli import main  # noqa: E402
from vjm.modelio.urdf import read_urdf  # noqa: E402
from vjm.robot.model import RobotModel  # noqa: E402

SIGMA = 0.01   # mm
HANDS = ("l_tool", "r_tool")
REGISTRATION = dict(R=rotation_matrix([0.2, -0.4, 1.0]), t=np.array([1500.0, -800.0, 200.0]),
                    marker={"l_tool": np.array([20.0, 5.0, -10.0]), "r_tool": np.array([15.0, -8.0, 12.0])},
                    sigma=SIGMA)
#: points (mm, base frame) for the left hand's marker to reach
TARGETS = np.array([[400.0, 260.0, 1000.0], [300.0, 255.0, 500.0], [500.0, 150.0, 900.0]])
COMPLIANCE = {"l1": 3e-5}   # rad/(N m): the left shoulder sags under its arm's weight


_link, _joint = truth.urdf_link, truth.urdf_joint


def _arm(p, y):
    return [_joint(f"{p}1", "chest", f"{p}_upper", f"0 {y} 0.3", "0 1 0"), _link(f"{p}_upper", 3.0, "0.2 0 0"),
            _joint(f"{p}2", f"{p}_upper", f"{p}_fore", "0.4 0 0", "0 1 0"), _link(f"{p}_fore", 2.0, "0.15 0 0.02"),
            f'<joint name="{p}_tool_joint" type="fixed"><parent link="{p}_fore"/><child link="{p}_tool"/>'
            f'<origin xyz="0.3 0 0" rpy="0 0 0"/></joint>', f'<link name="{p}_tool"/>']


@pytest.fixture(scope="module")
def torso(tmp_path_factory):
    """A torso (a yaw) with two two-joint arms; its robot file; the column map of files in their own format."""
    d = tmp_path_factory.mktemp("torso")
    parts = ['<robot name="torso">', _link("base", 20.0, "0 0 0.1"), _joint("yaw", "base", "chest", "0 0 0.5", "0 0 1"),
             _link("chest", 10.0, "0 0 0.2"), *_arm("l", 0.25), *_arm("r", -0.25), "</robot>"]
    (d / "torso.urdf").write_text("\n".join(parts))
    (d / "torso.yaml").write_text("urdf: torso.urdf\ntools: [l_tool, r_tool]\nhome: [0.1, -0.6, 1.2, -0.6, 1.2]\n")
    model = RobotModel(read_urdf(d / "torso.urdf", tools=list(HANDS)))
    cols = [f"  {n}: [Q{i}, deg]" for i, n in enumerate(model.q_names)]
    cols += [f"  {h}.{c}: [{h.upper()}_{c.upper()}, m]" for h in HANDS for c in "xyz"]
    (d / "map.yaml").write_text('separator: ";"\ndecimal: ","\ncolumns:\n' + "\n".join(cols) + "\n")
    return d, model


def _write(torso, name, hidden, n, seed):
    d, model = torso
    rng = np.random.default_rng(seed)
    q = rng.uniform(-2.5, 2.5, (n, model.nq))
    pts = truth.measure(str(d / "torso.urdf"), HANDS, model.q_names, q, hidden, rng)
    head = [f"Q{i}" for i in range(model.nq)] + [f"{h.upper()}_{c.upper()}" for h in HANDS for c in "xyz"]
    rows = [";".join(f"{v:.12f}".replace(".", ",") for v in np.r_[np.degrees(q[k]), pts[HANDS[0]][k] / 1000,
                                                                   pts[HANDS[1]][k] / 1000]) for k in range(n)]
    (d / name).write_text(";".join(head) + "\n" + "\n".join(rows) + "\n")
    return q


def _diagnose(torso, name, out, *more):
    d, _ = torso
    code = main(["diagnose", str(d / "torso.yaml"), str(d / name), "--columns", str(d / "map.yaml"),
                 "--out", str(d / out), *more])
    return code, json.loads((d / out / "report.json").read_text())


def test_a_hidden_joint_compliance_is_named_alone_and_recovered(torso):
    _write(torso, "sag.csv", truth.Hidden(**REGISTRATION, compliance=COMPLIANCE), 60, 1)
    moved = {**REGISTRATION, "R": rotation_matrix([-0.3, 0.1, 2.5]), "t": np.array([-700.0, 1900.0, -50.0])}
    _write(torso, "other.csv", truth.Hidden(**moved, compliance=COMPLIANCE), 40, 4)   # another set-up
    (torso[0] / "targets.csv").write_text("x,y,z\n" + "\n".join(",".join(map(str, p)) for p in TARGETS) + "\n")
    code, rep = _diagnose(torso, "sag.csv", "sag", "--validate", str(torso[0] / "other.csv"), "--register", "15",
                          "--targets", str(torso[0] / "targets.csv"))
    assert code == 0
    assert rep["kind"] == "absolute_poses" and rep["frames"] == list(HANDS)
    assert rep["named_effects"] == ["compliance"] and rep["verdict"] == "explained"
    p = rep["parameters"]["l1.compliance"]   # rad/(N mm)
    assert abs(p["value"] * 1000 - COMPLIANCE["l1"]) < 4 * p["std"] * 1000 and p["std"] * 1000 < 0.2 * COMPLIANCE["l1"]
    e = rep["effects"][0]   # the gap before and after, in mm: from the sag's size down to the noise's
    assert e["before_mm"]["mean"] > 5 * e["after_mm"]["mean"] and e["after_mm"]["mean"] < 3 * SIGMA
    held, = rep["held_out"]["validate"]   # the other set-up registered on 15 poses, the robot frozen
    assert held["rows"] == 25 and held["errors_mm"]["mean"] < 3 * SIGMA
    frame, = rep["registration"]["instrument_frames"].values()   # the nuisance, apart, with stds (set-up sag.csv)
    assert sorted(frame["std"]) == ["rx", "ry", "rz", "tx", "ty", "tz"] and all(0 < v < 0.1 for v in frame["std"].values())
    assert [m["frame"] for m in rep["registration"]["markers"]] == list(HANDS)
    for m in rep["registration"]["markers"]:
        assert np.linalg.norm(np.array(m["offset_mm"]) - REGISTRATION["marker"][m["frame"]]) < 0.1
        assert all(0 < s < 0.1 for s in m["std_mm"])
    assert "yaw.compliance" in [r["parameter"] for r in rep["not_observable"]]   # a vertical axis: no torque
    # commands.csv: the left hand's marker, commanded on the calibrated model, lands on the targets in the truth
    lines = (torso[0] / "sag" / "commands.csv").read_text().splitlines()
    assert "tool l_tool_marker" in lines[0]
    rows = [dict(zip(lines[1].split(","), r.split(","))) for r in lines[2:]]
    assert [r["converged"] for r in rows] == ["1"] * len(TARGETS)
    q = np.array([[float(r[n]) for n in torso[1].q_names] for r in rows])
    base = truth.Hidden(**{**REGISTRATION, "R": np.eye(3), "t": np.zeros(3), "sigma": 0.0}, compliance=COMPLIANCE)
    landed = truth.measure(str(torso[0] / "torso.urdf"), HANDS, torso[1].q_names, q, base)["l_tool"]
    assert np.max(np.linalg.norm(landed - TARGETS, axis=1)) < 3 * SIGMA
    assert all(float(r["sag_mm"]) > 3 * SIGMA for r in rows)   # what the plain command would miss by


def test_clean_data_name_nothing(torso):
    _write(torso, "clean.csv", truth.Hidden(**REGISTRATION), 60, 2)
    code, rep = _diagnose(torso, "clean.csv", "clean")
    assert code == 0
    assert rep["named_effects"] == [] and rep["verdict"] == "no_discrepancy"
    assert rep["held_out"]["folds"] == 5 and rep["stages"][0]["cv_rms_mm"] < 3 * SIGMA   # k-fold without --validate


def test_the_calibrated_urdf_carries_both_markers(torso):
    """The URDF written beside the report (Python API: diagnose, then save), loaded in pinocchio at the
    configurations the fitted compliances deflect, puts each hand's marker where the calibration puts it
    (base frame) to 1e-9 m."""
    from vjm.calibration.engine import instrument_frame, predict_points
    from vjm.discrepancy.workflow import diagnose

    d, model = torso
    _write(torso, "urdf.csv", truth.Hidden(**REGISTRATION, compliance=COMPLIANCE, offsets={"r1": 2e-3}), 60, 3)
    dg = diagnose(str(d / "torso.yaml"), str(d / "urdf.csv"), columns=str(d / "map.yaml"), folds=2)
    assert sorted(dg.named) == ["compliance", "geometry"]
    dg.save(d / "urdf")
    cal = dg.calibration
    upd = dg.updated_model   # the calibrated robot in memory: the files written, loaded back
    assert upd.kind == "serial" and {f"{h}_marker" for h in HANDS} <= {f.name for f in upd.tree.frames}
    pm = truth.pin.buildModelFromUrdf(str(d / "urdf" / "calibrated.urdf"))
    pd = pm.createData()
    idx = [pm.idx_qs[pm.getJointId(n)] for n in model.q_names]
    c = np.array([cal.values.get(f"{j}.compliance", 0.0) for j in model.q_names])
    from vjm.calibration.poses import read_column_map, read_poses
    data = read_poses(d / "urdf.csv", read_column_map(d / "map.yaml"), model.q_names).subset(np.arange(20))
    data = data.with_group("urdf.csv")
    R, t = instrument_frame(cal, "urdf.csv")
    pred = predict_points(cal, data).reshape(len(HANDS), data.n, 3)   # frame after frame
    qd = data.q - c * model.gravity_torques(data.q)
    for h, p in zip(HANDS, pred):
        fid = pm.getFrameId(f"{h}_marker")
        got = np.empty((data.n, 3))
        for k in range(data.n):
            qq = np.zeros(pm.nq)
            qq[idx] = qd[k]
            truth.pin.framesForwardKinematics(pm, pd, qq)
            got[k] = pd.oMf[fid].translation * 1000.0
        assert np.max(np.abs(got - (p - t) @ R)) < 1e-6   # mm: 1e-9 m


def test_vjm_calibrate_measures_both_points(torso):
    """``vjm calibrate`` (same engine) fits every point of the data by default: both markers in the report,
    the URDF and the robot file; the payload, weighed at one marker, leaves the default effects."""
    import yaml

    d, _ = torso
    _write(torso, "two.csv", truth.Hidden(**REGISTRATION), 40, 5)
    out = d / "cal"
    assert main(["calibrate", str(d / "torso.yaml"), str(d / "two.csv"), "--columns", str(d / "map.yaml"),
                 "--folds", "0", "--out", str(out)]) == 0
    rep = json.loads((out / "report.json").read_text())
    # every effect that applies but the payload (weighed at one marker) and thermal (no temperature column)
    assert rep["frames"] == list(HANDS) and "payload" not in rep["effects_tried"] and "thermal" not in \
        rep["effects_tried"] and {"geometry", "compliance", "lateral", "coupling"} <= set(rep["effects_tried"])
    assert [m["frame"] for m in rep["registration"]["markers"]] == list(HANDS)
    urdf = (out / "calibrated.urdf").read_text()
    assert all(f'<link name="{h}_marker"' in urdf for h in HANDS)
    assert yaml.safe_load((out / "calibrated.yaml").read_text())["tools"] == [f"{h}_marker" for h in HANDS] + list(HANDS)
