"""Silent wrong answers (units and ranges) and tracebacks or noise where one line is promised: absolute poses in
degrees or metres refused against the robot, a seed, a target or a model in the wrong units refused, the URDF
parser's own stderr lines captured into one, the masses it drops caught, the default tool frame one a joint
moves, the joint-limit warning said once, and the CSV headers vjm writes quoted and defused.  The command-line
refusals themselves are rows of the bad-input table (tests/bad_inputs.py, issues 40.3 and 40.4)."""
import math
from pathlib import Path

import numpy as np
import pytest
from bad_inputs import CAL_FILES, CASES, X_FILES, Case, _joint, _urdf, run, write_files

import vjm
from vjm.calibration import report as cr
from vjm.errors import VjmError, VjmWarning
from vjm.modelio.read import load_model
from vjm.robot.model import JointSpring, Payload

ROOT = Path(__file__).resolve().parents[1]
UR10 = ROOT / "data" / "robots" / "ur10" / "ur10.yaml"
IPA = ROOT / "data" / "realdata" / "ur10_ipa"
TORSO = ROOT / "tests" / "vjm" / "robots" / "torso_two_arms.urdf"


# --------------------------------------------------------------------------- absolute poses against the robot
def _ipa_rows(tmp_path, joints=1.0, points=1.0, rows=150) -> Path:
    """The first ``rows`` rows of the IPA series A as they are, the joint columns times ``joints`` and the measured
    positions times ``points`` (the file's own decimal commas kept)."""
    lines = (IPA / "Series_A" / "measurements_grid.csv").read_text(encoding="utf-8").splitlines()[:rows + 1]
    head = lines[0].split(";")
    jcols = [head.index(n) for n in ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
                                     "wrist_2_joint", "wrist_3_joint")]
    pcols = [head.index(f"measurement_{c}") for c in "xyz"]
    out = [lines[0]]
    for ln in lines[1:]:
        cells = ln.split(";")
        for cols, f in ((jcols, joints), (pcols, points)):
            for c in cols:
                cells[c] = repr(float(cells[c].replace(",", ".")) * f).replace(".", ",")
        out.append(";".join(cells))
    p = tmp_path / "a.csv"
    p.write_text("\n".join(out) + "\n", encoding="utf-8")
    return p


def _inputs(path):
    return cr.inputs(UR10, path, IPA / "columns.yaml", [], cr.Options(), False)


def test_the_ipa_data_pass_and_their_degrees_or_metres_are_refused(tmp_path):
    """The real UR10 data: as measured they pass, the measured points spreading as the model's tool0 does at the
    same joint values (an independent size: the RMS distance from the centroid, which no registration changes);
    the same rows with the joints in degrees, or the points in metres, are refused naming the unit."""
    from vjm.calibration.poses import spread

    m, d, _, _ = _inputs(_ipa_rows(tmp_path))
    ratio = spread(d.points["tool0"]) / spread(m.forward(d.q_for(m.q_names), "tool0")[:, :3, 3])
    assert 0.9 < ratio < 1.1
    with pytest.raises(VjmError, match="degrees where radians are meant"):
        _inputs(_ipa_rows(tmp_path, joints=180 / math.pi))
    with pytest.raises(VjmError, match=r"a factor 0\.00[01].*points in metres"):
        _inputs(_ipa_rows(tmp_path, points=1e-3))


def test_the_joint_limit_warning_is_said_once(tmp_path):
    """19 of the 40 poses beyond j1's limit: one warning for the run, not one per fold and stage."""
    res = run(Case("40.4", "vjm calibrate r.yaml p.csv --out o --folds 7 --effects geometry,compliance", "", CAL_FILES),
              tmp_path)
    assert res.status == 0, res.stderr
    limits = [ln for ln in res.stderr.splitlines() if "limits" in ln]
    assert len(limits) == 1 and "19 of 40 rows outside the joint limits" in limits[0], res.stderr


# --------------------------------------------------------------------------- the URDF parser's own lines
def _urdf_cases():
    return [c for c in CASES if c.issue in ("40.3", "40.4") and c.command.startswith("vjm stiffness r.yaml")
            and "r.urdf" in c.files and c.files["r.urdf"] != X_FILES["r.urdf"]]


@pytest.mark.parametrize("case", _urdf_cases(), ids=lambda c: c.note)
def test_a_malformed_urdf_gets_one_line_and_nothing_from_the_parser(case, tmp_path, capfd):
    """Checked at the file descriptor (the parser writes to fd 2 from C++, which sys.stderr does not see)."""
    from vjm.cli import main

    write_files(case, tmp_path)
    with pytest.MonkeyPatch.context() as mp:
        mp.chdir(tmp_path)
        status = main(case.argv[1:])
    err = capfd.readouterr().err
    assert status == 2
    assert err.count("\n") == 1 and err.startswith("error: ") and case.expect in err, err
    assert ".cpp" not in err


def test_a_urdf_in_utf16_gets_one_line(tmp_path, capfd):
    from vjm.cli import main

    text = X_FILES["r.urdf"].replace('<?xml version="1.0"?>', '<?xml version="1.0" encoding="UTF-16"?>')
    (tmp_path / "r.urdf").write_bytes(text.encode("utf-16"))
    (tmp_path / "r.yaml").write_text("urdf: r.urdf\n", encoding="utf-8")
    assert main(["stiffness", str(tmp_path / "r.yaml"), "--q", "0,0"]) == 2
    err = capfd.readouterr().err
    assert err.count("\n") == 1 and "a URDF in UTF-16" in err, err


def test_the_parsers_stderr_is_captured_into_the_error_line(tmp_path, monkeypatch, capfd):
    """What vjm's own XML pass would refuse, handed to the parser anyway: its C++ lines (``Error: ... at line 124
    in .../joint.cpp``) become one error line without the source location, and nothing reaches fd 2."""
    from vjm.modelio import urdf

    monkeypatch.setattr(urdf, "check_xml", lambda raw, path: {})
    p = tmp_path / "r.urdf"
    p.write_text(X_FILES["r.urdf"].replace('lower="-2"', 'lower="nan"', 1), encoding="utf-8")
    with pytest.raises(VjmError) as e:
        urdf.read_urdf(p)
    assert "joint [j1]: lower value (nan) is not a valid float" in str(e.value)
    assert ".cpp" not in str(e.value) and "\n" not in str(e.value)
    assert capfd.readouterr().err == ""


def test_a_mass_the_parser_drops_is_caught(tmp_path, monkeypatch):
    """A mass the parser cannot read it drops, with the link's inertial (a NaN in the UR10's made its sag 0.551 mm
    instead of 0.783): the masses it gives back must add up to the file's.  vjm's own pass, which refuses the NaN
    first, stands aside here and states the 2 kg of each link."""
    from vjm.modelio import urdf

    text = X_FILES["r.urdf"].replace('<mass value="2"/>', '<mass value="nan"/>', 1)
    declared = {"l1": 2.0, "l2": 2.0}
    monkeypatch.setattr(urdf, "check_xml", lambda raw, path: declared)
    p = tmp_path / "r.urdf"
    p.write_text(text, encoding="utf-8")
    with pytest.warns(VjmWarning, match="the URDF parser says"):
        with pytest.raises(VjmError, match="the URDF parser gave the links 2 kg in all, the file's inertials 4 kg"):
            urdf.read_urdf(p)


# --------------------------------------------------------------------------- the default tool frame
def test_a_ros_industrial_urdf_without_tools_takes_tool0(tmp_path):
    """The UR10's own URDF (leaves base, ee_link, tool0; base fixed to the root): tool0 is chosen and said, and its
    stiffness has full rank (the base frame's would be K = 0, rank 0)."""
    (tmp_path / "r.yaml").write_text(f"urdf: {ROOT / 'data/robots/ur10/ur10.urdf'}\njoints: {{" + ", ".join(
        f"{n}: {{stiffness: 1.0e+8}}" for n in ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint",
                                                 "wrist_1_joint", "wrist_2_joint", "wrist_3_joint")) + "}\n")
    with pytest.warns(VjmWarning, match="tool frame 'tool0' chosen"):
        m = load_model(tmp_path / "r.yaml")
    assert m.tools[0] == "tool0" and "base" not in m.tools
    assert m.stiffness([0, -1.2, 1.5, -1.87, -1.57, 0]).rank == 6
    with pytest.raises(VjmError, match="'base' is fixed to the robot's base: no joint moves it"):
        m.stiffness([0, -1.2, 1.5, -1.87, -1.57, 0], "base")


def test_without_tool0_the_deepest_moving_leaf_is_the_tool(tmp_path):
    from vjm.modelio.urdf import read_urdf

    with pytest.warns(VjmWarning, match="tool frame 'r_fa' chosen \\(5 joints from the root"):
        t = read_urdf(TORSO)
    depth = {}
    for name in t.tools:
        j, n = t.frame(name).joint, 0
        while j >= 0:
            n, j = n + 1, t.joints[j].parent
        depth[name] = n
    assert depth[t.tools[0]] == max(depth.values()) == 5


def test_a_urdf_whose_only_leaf_is_fixed_to_the_root_is_refused(tmp_path):
    from vjm.modelio.urdf import read_urdf

    p = tmp_path / "r.urdf"
    p.write_text(_urdf(_joint("j1", "base", "l1") + _joint("f", "base", "l2", "fixed")))
    assert read_urdf(p).tools == ("l1",)  # l2 is fixed to the root: no tool, and no choice to say
    p.write_text(_urdf(_joint("f1", "base", "l1", "fixed") + _joint("f2", "base", "l2", "fixed")))
    with pytest.raises(VjmError, match="no link without a child is moved by a joint"):
        read_urdf(p)


# --------------------------------------------------------------------------- the Python API
@pytest.fixture(scope="module")
def ur10():
    return vjm.load_model(UR10)


HOME = [0, -1.2, 1.5, -1.8707963267948966, -1.5707963267948966, 0]


def test_the_api_refuses_what_it_used_to_crash_or_accept(ur10):
    with pytest.raises(VjmError, match="payload must be a vjm.robot.model.Payload"):
        ur10.compensate([[884, 164, 436]], HOME, payload=-5)
    with pytest.raises(VjmError, match=r"payload.mass must be a number in \[0, 100000\] kg"):
        ur10.compensate([[884, 164, 436]], HOME, payload=Payload("tool0", 1e300))
    with pytest.raises(VjmError, match="poses must be tool frames .* got shape \\(2, 3\\)"):
        ur10.inverse(np.array([[884, 164, 436], [800, 100, 400]]), HOME)
    with pytest.raises(VjmError, match="the wrench must be finite"):
        ur10.deflection(HOME, [np.nan, 0, 0, 0, 0, 0])
    with pytest.raises(VjmError, match="magnitude 1e\\+300 m/s\\^2"):
        ur10.replace(gravity=(0, 0, 1e300))
    with pytest.raises(VjmError, match="mm/s\\^2\\?"):
        ur10.replace(gravity=(0, 0, -9806.65))
    with pytest.raises(VjmError, match="seed: shoulder_lift_joint = 68.75 is beyond 2 pi"):
        ur10.inverse(ur10.forward(HOME), np.degrees(HOME))
    with pytest.raises(VjmError, match="orientation: a rotation vector of 180 rad"):
        ur10.cartesian_map([[884, 164, 436]], HOME, orientation=[180, 0, 0])
    # what is plausible stays accepted: no gravity, a gravity of 9.81, an orientation of half a turn
    assert ur10.replace(gravity=(0, 0, 0)).gravity == (0, 0, 0)
    ur10.replace(gravity=(0, 0, -9.81))
    assert ur10.cartesian_map([[884, 164, 436]], HOME, orientation=[math.pi, 0, 0])[0].q.shape == (1, 6)


def test_a_stiffness_below_one_is_refused_not_printed_as_nan(ur10):
    soft = ur10.replace(joint_springs={**ur10.joint_springs, "elbow_joint": JointSpring(1e-300)}, raw=None)
    with pytest.raises(VjmError, match="joints.elbow_joint.stiffness: stiffness 1e-300 .* at least 1"):
        soft.stiffness(HOME)
    ok = ur10.replace(joint_springs={**ur10.joint_springs, "elbow_joint": JointSpring(1.0)}, raw=None)
    assert np.all(np.isfinite(ok.stiffness(HOME).K))


def test_a_continuous_joint_beyond_a_turn_warns_only(tmp_path):
    """A continuous joint may turn more than once: its seed beyond 2 pi warns, a limited joint's is refused."""
    from vjm.modelio.urdf import read_urdf
    from vjm.robot.model import RobotModel

    text = _urdf(_joint("j1", "base", "l1", "continuous") + _joint("j2", "l1", "l2")).replace(
        '<origin xyz="0 0 0.3"/>', '<origin xyz="0.3 0 0.1"/>')
    p = tmp_path / "c.urdf"
    p.write_text(text)
    m = RobotModel(read_urdf(p))
    with pytest.warns(VjmWarning, match="j1 = 7 is beyond 2 pi .* a continuous joint may turn more"):
        m.check_seed([7.0, 0.0])
    with pytest.raises(VjmError, match="j2 = 7 is beyond 2 pi"):
        m.check_seed([0.0, 7.0])


# --------------------------------------------------------------------------- CSV headers vjm writes
def test_names_in_csv_headers_are_quoted_defused_and_read_back(tmp_path):
    """A joint named like a formula and a frame with a quote and a comma: sim.csv holds them in one cell each, the
    formula behind a ``'``, and vjm's pose reader gives the names back as the model has them."""
    from vjm.calibration.poses import read_poses
    from vjm.modelio.csvtext import header

    assert header(["=cmd|calc!A0", "+1", "-x", "@SUM(A1)", 'a"b,c', "j2"]) == \
        '\'=cmd|calc!A0,\'+1,\'-x,\'@SUM(A1),"a""b,c",j2'
    tool = 'to"o,l'
    text = (X_FILES["r.urdf"].replace('name="j1"', 'name="=cmd|calc!A0"').replace('name="l2"', 'name="to&quot;o,l"')
            .replace('link="l2"', 'link="to&quot;o,l"'))
    (tmp_path / "r.urdf").write_text(text)
    (tmp_path / "r.yaml").write_text("urdf: r.urdf\n")
    m = load_model(tmp_path / "r.yaml")
    assert m.q_names == ("=cmd|calc!A0", "j2") and tool in m.tools
    res = run(Case("40.4", "vjm simulate r.yaml --out s.csv --poses random:12", ""), tmp_path)
    assert res.status == 0, res.stderr
    first = (tmp_path / "s.csv").read_text().splitlines()[1]
    assert first.startswith("'=cmd|calc!A0,j2,") and '"to""o,l.x"' in first
    d = read_poses(tmp_path / "s.csv", joints=m.q_names)
    assert d.joints == m.q_names and list(d.points) == [tool] and d.n == 12


def test_a_formula_named_joint_reaches_map_csv_defused_and_readable(tmp_path):
    """`vjm map` end to end on the two-joint arm whose joints are named ``=cmd|calc!A0`` and ``-j"2,x``: map.csv's
    header holds each name in one cell behind a ``'``, the csv module reads it back, and the joint values stand
    under their joint (the arm's point at (300 + 300 cos q1, 300 sin q1, 200) mm: q1 = atan2(y, x - 300))."""
    import csv

    from vjm.cli import main

    (tmp_path / "r.urdf").write_text(X_FILES["r.urdf"].replace('name="j1"', 'name="=cmd|calc!A0"')
                                     .replace('name="j2"', 'name="-j&quot;2,x"'))
    (tmp_path / "r.yaml").write_text("urdf: r.urdf\nhome: [0.1, 0.2]\n"
                                     "joints: {'=cmd|calc!A0': {stiffness: 1.0e+8}, '-j\"2,x': {stiffness: 5.0e+7}}\n")
    out = tmp_path / "m"
    assert main(["map", str(tmp_path / "r.yaml"), "--grid", "2", "--box", "300:600,0:300,100:300", "--slice", "z=200",
                 "--out", str(out)]) == 0
    text = (out / "map.csv").read_text(encoding="utf-8")
    assert text.splitlines()[0] == ("x_mm,y_mm,z_mm,status,'=cmd|calc!A0,\"'-j\"\"2,x\",k_tran_mm_per_N,"
                                    "k_rot_rad_per_Nmm")
    head, *rows = list(csv.reader(text.splitlines()))
    assert head[4:6] == ["'=cmd|calc!A0", "'-j\"2,x"] and not any(h.startswith(("=", "+", "-", "@")) for h in head)
    assert len(rows) == 4 and all(len(r) == len(head) for r in rows)
    ok = [r for r in rows if r[3] == "ok"]
    assert len(ok) == 2
    for r in ok:
        x, y = float(r[0]), float(r[1])
        assert float(r[4]) == pytest.approx(math.atan2(y, x - 300.0), abs=1e-6)


def test_folds_beyond_50_or_the_data_are_refused_before_any_fit(tmp_path):
    """``--folds`` of the deflection diagnosis: 1e6 folds is one error line and exit 2 from the command itself, at
    once (it used to run a leave-one-posture-out cross-validation and report 1000000 folds); through the Python
    API, more folds than the data's postures are refused, as many are taken."""
    import subprocess
    import sys

    from bad_inputs import GOOD

    (tmp_path / "m.csv").write_text(GOOD)
    p = subprocess.run([sys.executable, "-m", "vjm.cli", "diagnose", str(ROOT / "data" / "orthoglide" / "puu.yaml"),
                        "m.csv", "--out", "rep", "--folds", "1000000"], cwd=tmp_path, capture_output=True, text=True,
                       timeout=300)
    assert p.returncode == 2, p.stderr
    assert p.stderr.strip() == "error: --folds must be a whole number in [2, 50], got 1000000", p.stderr
    assert not (tmp_path / "rep").exists()
    table1 = ROOT / "data" / "seed_table1.csv"   # 3 postures
    with pytest.raises(VjmError, match=r"--folds 4: the data hold 3 postures, .* at most 3 folds"):
        vjm.diagnose(ROOT / "data" / "orthoglide" / "puu.yaml", table1, folds=4)
    assert vjm.diagnose(ROOT / "data" / "orthoglide" / "puu.yaml", table1, folds=3).report["cv_folds"] == 3
