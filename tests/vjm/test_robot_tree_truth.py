"""Two measured points per row on a tree robot (a marker on each hand of a two-arm torso), against
pinocchio's truth (tests/truth_serial.py): hidden joint offsets, an origin error, joint compliances under
self-weight and a wrist column holding a coupling of two joints written as an ordinary joint, no sigma
columns; then 5 % of the rows of a rigid arm with the markers swapped between the hands."""
import numpy as np
import pytest

truth = pytest.importorskip("truth_serial")

from vjm.calibration.engine import calibrate, position_errors  # noqa: E402
from vjm.calibration.poses import AbsolutePoses  # noqa: E402
from vjm.calibration.robust import calibrate_robust  # noqa: E402
from vjm.calibration.serial import rotation_matrix  # noqa: E402
from vjm.modelio.urdf import read_urdf  # noqa: E402
from vjm.robot.model import RobotModel  # noqa: E402

SIGMA = 0.01   # mm
HANDS = ("l_tool", "r_tool")


_link, _joint = truth.urdf_link, truth.urdf_joint


def _arm(side, y):
    p = side[0]
    return [_joint(f"{p}1", "chest", f"{p}_upper", f"0 {y} 0.3", "0 1 0"), _link(f"{p}_upper", 3.0, "0.2 0 0"),
            _joint(f"{p}2", f"{p}_upper", f"{p}_fore", "0.4 0 0", "0 1 0"), _link(f"{p}_fore", 2.0, "0.15 0 0.02"),
            _joint(f"{p}3", f"{p}_fore", f"{p}_hand", "0.3 0 0", "1 0 0"), _link(f"{p}_hand", 0.5, "0.05 0.02 0"),
            f'<joint name="{p}_tool_joint" type="fixed"><parent link="{p}_hand"/><child link="{p}_tool"/>'
            f'<origin xyz="0.1 0 0" rpy="0 0 0"/></joint>', f'<link name="{p}_tool"/>']


@pytest.fixture(scope="module")
def torso(tmp_path_factory):
    """A two-arm torso (revolute joints only): a yaw, then three joints per arm."""
    parts = ['<robot name="torso">', _link("base", 20.0, "0 0 0.1"), _joint("yaw", "base", "chest", "0 0 0.5", "0 0 1"),
             _link("chest", 10.0, "0 0 0.2"), *_arm("left", 0.25), *_arm("right", -0.25), "</robot>"]
    path = tmp_path_factory.mktemp("torso") / "torso.urdf"
    path.write_text("\n".join(parts))
    return str(path), RobotModel(read_urdf(path, tools=list(HANDS)))


HIDDEN = dict(offsets={"l1": 2e-3, "r2": -1.5e-3, "l2": 1e-3}, origins={"l2": (0.3, 0.0, -0.2, 0.0, 4e-4, 0.0)},
              compliance={"l1": 2e-5, "r1": 3e-5},   # rad/(N m)
              R=rotation_matrix([0.2, -0.4, 1.0]), t=np.array([1500.0, -800.0, 200.0]),
              marker={"l_tool": np.array([20.0, 5.0, -10.0]), "r_tool": np.array([15.0, -8.0, 12.0])}, sigma=SIGMA)


def _data(torso, hidden, n, seed):
    urdf, model = torso
    rng = np.random.default_rng(seed)
    q = rng.uniform(-2.5, 2.5, (n, model.nq))
    pts = truth.measure(urdf, HANDS, model.q_names, q, hidden, rng)
    return AbsolutePoses(tuple(model.q_names), q, pts, group=np.full(n, "A", dtype=object))


def test_two_hands_with_a_coupled_wrist_are_calibrated(torso):
    """The l3 column holds l3 + 0.03 l2 (a wrist's gear train written as an ordinary joint)."""
    k = 0.03
    data = _data(torso, truth.Hidden(**HIDDEN, coupling={("l3", "l2"): k}), 120, 1)
    assert not data.sigmas   # no sigma columns
    cal = calibrate(torso[1], data, HANDS, effects=("geometry", "compliance", "coupling"))
    assert [s.name for s in cal.stages if s.kept] == ["registration", "geometry", "compliance", "coupling"]
    name = "l3.coupling[l2]"
    assert abs(cal.values[name] - k) < 4 * cal.std[name] and cal.std[name] < 0.05 * k
    for j, c in HIDDEN["compliance"].items():
        x, s = cal.values[f"{j}.compliance"] * 1000, cal.std[f"{j}.compliance"] * 1000
        assert abs(x - c) < 4 * s and s < 0.2 * c
    for f in HANDS:   # each hand's marker offset found
        assert np.linalg.norm(cal.measured[HANDS.index(f)][1] + [cal.values.get(f"{f}.p{c}", 0.0) for c in "xyz"]
                              - HIDDEN["marker"][f]) < 0.1
    assert np.mean(position_errors(cal, data)) < 3 * SIGMA


def test_rows_with_the_hands_markers_swapped_are_set_aside(torso):
    rigid = truth.Hidden(**{**HIDDEN, "compliance": {}})
    data = _data(torso, rigid, 100, 2)
    swapped = np.arange(5, 100, 20)   # 5 rows of 100
    pts = {f: v.copy() for f, v in data.points.items()}
    pts["l_tool"][swapped], pts["r_tool"][swapped] = data.points["r_tool"][swapped], data.points["l_tool"][swapped]
    mixed = AbsolutePoses(data.joints, data.q, pts, group=data.group)
    cal = calibrate_robust(torso[1], mixed, HANDS, effects=("geometry",))
    assert sorted(cal.set_aside) == swapped.tolist()
    assert [s.name for s in cal.stages if s.kept] == ["registration", "geometry"]
    assert np.mean(position_errors(cal, data.subset(np.setdiff1d(np.arange(100), swapped)))) < 3 * SIGMA
    plain = calibrate(torso[1], mixed, HANDS, effects=("geometry",))   # the swapped rows pull a plain fit off
    assert np.mean(position_errors(plain, data.subset(np.setdiff1d(np.arange(100), swapped)))) > 10 * SIGMA
