"""``vjm calibrate``: files in their own format (``;``, decimal commas, m and deg) made by pinocchio's truth
(tests/truth_serial.py), calibrated, held out on another set-up, written back as one set."""
import json
import os
import warnings

import numpy as np
import pytest

truth = pytest.importorskip("truth_serial")

import vjm  # noqa: E402
from linkfea.files.outputs import read_manifest  # noqa: E402
from vjm.calibration.serial import rotation_matrix  # noqa: E402
from vjm.cli import main  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
# the model pinocchio's truth simulates: the URDF, rigid (the calibration corrects the model it is given)
UR10 = os.path.join(ROOT, "tests", "ur10_rigid.yaml")
URDF = os.path.join(ROOT, "data", "robots", "ur10", "ur10.urdf")
SIGMA = 0.01
HIDDEN = truth.Hidden(
    offsets={"shoulder_lift_joint": 2e-3, "elbow_joint": -1.5e-3, "wrist_1_joint": 1e-3},
    origins={"elbow_joint": (0.4, 0.0, -0.3, 5e-4, 0.0, 0.0)},
    compliance={"shoulder_lift_joint": 4e-6, "elbow_joint": 8e-6},
    R=rotation_matrix([0.3, -0.2, 2.0]), t=np.array([2000.0, -1500.0, 300.0]), marker=np.array([10.0, -20.0, 110.0]),
    sigma=SIGMA)
#: points (mm, base frame) for the marker to reach, around the UR10's home
TARGETS = np.array([[900.0, 150.0, 330.0], [1000.0, -50.0, 400.0], [750.0, 450.0, 250.0]])
COLUMNS = """separator: ";"
decimal: ","
columns:
{joints}
  tool0.x: [X, m]
  tool0.y: [Y, m]
  tool0.z: [Z, m]
"""


@pytest.fixture(scope="module")
def names():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return vjm.load_model(UR10).q_names


def _write(path, names, hidden, n, seed):
    q = truth.ur10_postures(n, seed)
    p = truth.measure(URDF, "tool0", names, q, hidden, np.random.default_rng(seed + 100))
    head = ";".join([f"J{i}" for i in range(6)] + ["X", "Y", "Z"])
    rows = [";".join(f"{v:.12f}".replace(".", ",") for v in np.r_[np.degrees(a), b / 1000.0]) for a, b in zip(q, p)]
    path.write_text(head + "\n" + "\n".join(rows) + "\n")


@pytest.fixture(scope="module")
def files(tmp_path_factory, names):
    d = tmp_path_factory.mktemp("cal")
    (d / "map.yaml").write_text(COLUMNS.format(joints="\n".join(f"  {n}: [J{i}, deg]" for i, n in enumerate(names))))
    _write(d / "fit.csv", names, HIDDEN, 250, 1)
    other = truth.Hidden(**{**HIDDEN.__dict__, "R": rotation_matrix([-0.1, 0.4, -1.0]),
                            "t": np.array([-500.0, 2500.0, -100.0])})
    _write(d / "other.csv", names, other, 80, 2)
    (d / "targets.csv").write_text("x,y,z\n" + "\n".join(",".join(map(str, p)) for p in TARGETS) + "\n")
    return d


@pytest.fixture(scope="module")
def run(files):
    out = files / "out"
    code = main(["calibrate", UR10, str(files / "fit.csv"), "--columns", str(files / "map.yaml"),
                 "--validate", str(files / "other.csv"), "--register", "20", "--targets", str(files / "targets.csv"),
                 "--out", str(out)])
    return code, out


def test_calibrate_writes_the_set(run):
    code, out = run
    assert code == 0
    assert {"report.json", "summary.txt", "calibrated.urdf", "calibrated.yaml"} <= set(os.listdir(out))
    assert "vjm calibrate" in read_manifest(out)["sets"]
    # the calibrated URDF loads in pinocchio with the marker as a frame
    model = truth.pin.buildModelFromUrdf(str(out / "calibrated.urdf"))
    assert model.existFrame("tool0_marker")
    text = (out / "calibrated.yaml").read_text()
    assert "calibrated.urdf" in text and "stiffness" in text


def test_report_names_effects_in_order_with_gaps(run):
    _, out = run
    rep = json.loads((out / "report.json").read_text())
    named = [e["effect"] for e in rep["effects"]]
    assert set(named) == {"geometry", "compliance"}   # the payload is not hidden: not named
    buys = [e["buys_mm"] for e in rep["effects"]]
    assert buys == sorted(buys, reverse=True) and buys[-1] > 0
    for e in rep["effects"]:
        assert e["after_mm"]["mean"] < e["before_mm"]["mean"]
        assert set(e["after_mm"]) == {"mean", "std", "max", "p95"}
    # after all the effects, the fitted rows are at the noise (|3-D normal| of sigma 0.01 mm: mean 0.016)
    assert min(e["after_mm"]["mean"] for e in rep["effects"]) < 3 * SIGMA
    # held out on another instrument set-up registered on 20 of its poses: at the noise too
    (v,) = rep["held_out"]["validate"]
    assert v["rows"] == 60 and v["errors_mm"]["mean"] < 3 * SIGMA
    assert "shoulder_pan_joint.compliance" in [r["parameter"] for r in rep["not_observable"]]
    assert any(r["parameter"] == "shoulder_pan_joint.offset" for r in rep["not_identifiable"])
    reg = rep["registration"]
    assert np.linalg.norm(np.array(reg["marker"]["offset_mm"]) - HIDDEN.marker) < 2.0
    frame = reg["instrument_frames"]["fit.csv"]   # a file without a group column is one set-up
    assert all(s is not None and s > 0 for s in frame["std"].values())
    assert "registration only" in (out / "summary.txt").read_text()


def test_commands_written_back_reach_the_targets_on_the_truth(run, names):
    """commands.csv, computed on the calibrated model: the truth's arm (its geometry errors and its sag, seen in
    the base frame) puts the marker on the targets to within the calibration's accuracy, where the nominal
    model's plain IK misses by a millimetre and more."""
    import csv

    _, out = run
    assert "commands.csv" in read_manifest(out)["sets"]["vjm calibrate"]["files"]
    lines = (out / "commands.csv").read_text().splitlines()
    assert lines[0].startswith("# commands by vjm compensate") and "tool0_marker" in lines[0]
    rows = list(csv.DictReader(lines[1:]))
    assert [r["converged"] for r in rows] == ["1"] * len(TARGETS)
    q = np.array([[float(r[n]) for n in names] for r in rows])
    base = truth.Hidden(**{**HIDDEN.__dict__, "R": np.eye(3), "t": np.zeros(3), "sigma": 0.0})
    landed = truth.measure(URDF, "tool0", names, q, base)
    assert np.max(np.linalg.norm(landed - TARGETS, axis=1)) < 10 * SIGMA
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        nominal = vjm.load_model(UR10)
    plain = []
    for p in TARGETS:   # the nominal model's rigid IK of the marker point, orientation as at home
        T0 = nominal.forward(np.array(nominal.home))
        T = T0.copy()
        T[:3, 3] = p - T0[:3, :3] @ HIDDEN.marker
        plain.append(nominal.inverse(T, np.array(nominal.home)).q[0])
    missed = np.linalg.norm(truth.measure(URDF, "tool0", names, np.array(plain), base) - TARGETS, axis=1)
    assert np.all(missed > 0.5)


def test_a_second_run_replaces_its_own_set_but_never_a_users_file(run, files, capsys):
    _, out = run
    args = ["calibrate", UR10, str(files / "other.csv"), "--columns", str(files / "map.yaml"), "--folds", "0",
            "--effects", "geometry"]
    assert main(args + ["--out", str(out)]) == 0
    assert json.loads((out / "report.json").read_text())["rows"] == 80
    mine = files / "mine"
    mine.mkdir()
    (mine / "summary.txt").write_text("my notes")
    capsys.readouterr()
    assert main(args + ["--out", str(mine), "--force"]) == 2
    err = capsys.readouterr().err
    assert err.count("error:") == 1 and "summary.txt" in err
    assert (mine / "summary.txt").read_text() == "my notes" and os.listdir(mine) == ["summary.txt"]


def test_outlying_rows_are_set_aside_and_listed(files, names, capsys):
    """Rows of another reflector (150 mm away on the flange) in the file: listed in the report, not fitted."""
    text = (files / "fit.csv").read_text().splitlines()
    other = files / "other_marker.csv"
    _write(other, names, truth.Hidden(**{**HIDDEN.__dict__, "marker": HIDDEN.marker + [150.0, 0.0, 0.0]}), 250, 1)
    swapped = [3, 50, 77, 120, 200, 240]
    alt = other.read_text().splitlines()
    (files / "mixed.csv").write_text("\n".join(alt[i] if i - 1 in swapped else t for i, t in enumerate(text)) + "\n")
    out = files / "out_mixed"
    assert main(["calibrate", UR10, str(files / "mixed.csv"), "--columns", str(files / "map.yaml"), "--folds", "0",
                 "--out", str(out)]) == 0
    rep = json.loads((out / "report.json").read_text())
    assert [r["row"] for r in rep["set_aside"]] == swapped
    assert all(r["error_mm"] > 50 for r in rep["set_aside"])
    assert {e["effect"] for e in rep["effects"]} == {"geometry", "compliance"}
    assert "Set aside as outliers (not fitted): 6 rows" in capsys.readouterr().out

