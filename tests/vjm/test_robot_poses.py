"""Absolute-pose files read as they are through a column map: separators, decimal commas, units, Euler angles."""
import os

import numpy as np
import pytest

from vjm.calibration.poses import column_map_from_dict, read_column_map, read_poses
from vjm.calibration.serial import rotation_matrix
from vjm.errors import VjmError

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(__file__)))
IPA = os.path.join(ROOT, "data", "realdata", "ur10_ipa")
MAP = {"separator": ";", "decimal": ",", "rotation": "euler_XYZ",
       "columns": {"j1": ["A1", "deg"], "j2": ["A2", "rad"], "hand.x": ["X", "m"], "hand.y": ["Y", "m"],
                   "hand.z": ["Z", "mm"], "hand.rx": ["RX", "deg"], "hand.ry": ["RY", "deg"], "hand.rz": ["RZ", "deg"],
                   "group": "station", "meta_stamp": "Time"},
       "if_present": {"hand.sigma": ["S", "mm"]}}
TEXT = ("A1;A2;X;Y;Z;RX;RY;RZ;station;Time\n"
        "90;0,5;1,25;-0,001;300,5;30;45;0;s1;2,02011E+13\n"
        "-45,5;-1;0;2;1e3;0;0;90;s2;x\n")


def _write(tmp_path, text, name="poses.csv"):
    p = tmp_path / name
    p.write_text(text)
    return str(p)


def test_a_foreign_file_is_read_with_its_units_and_dialect(tmp_path):
    d = read_poses(_write(tmp_path, TEXT), column_map_from_dict(MAP), joints=["j1", "j2"])
    assert d.joints == ("j1", "j2") and d.n == 2
    assert np.allclose(d.q, [[np.pi / 2, 0.5], [-45.5 * np.pi / 180, -1.0]], rtol=0, atol=1e-15)
    assert np.allclose(d.points["hand"], [[1250.0, -1.0, 300.5], [0.0, 2000.0, 1000.0]], rtol=0, atol=1e-12)
    # intrinsic XYZ angles (a, b, 0) are the rotation Rx(a) Ry(b)
    R = rotation_matrix(d.rotations["hand"][0])
    a, b = np.radians(30), np.radians(45)
    assert np.allclose(R, rotation_matrix([a, 0, 0]) @ rotation_matrix([0, b, 0]), atol=1e-14)
    assert np.allclose(d.rotations["hand"][1], [0, 0, np.pi / 2], atol=1e-14)
    assert list(d.groups) == ["s1", "s2"] and d.sigmas == {}
    assert list(d.meta["meta_stamp"]) == ["2,02011E+13", "x"]   # text where not every entry is a number


def test_optional_sigmas_and_a_constant_group(tmp_path):
    text = TEXT.replace("station;Time", "station;Time;S").replace("+13\n", "+13;0,02\n").replace(";x\n", ";x;0,03\n")
    d = read_poses(_write(tmp_path, text), column_map_from_dict(MAP), group="G")
    assert np.allclose(d.sigmas["hand"], [[0.02] * 3, [0.03] * 3])
    assert list(d.groups) == ["G", "G"]
    sub = d.subset([1])
    assert sub.n == 1 and np.allclose(sub.points["hand"], [[0.0, 2000.0, 1000.0]])


def test_vjm_names_need_no_map(tmp_path):
    d = read_poses(_write(tmp_path, "a,b,tool0.x,tool0.y,tool0.z,tool0.sigma_x,tool0.sigma_y,tool0.sigma_z,meta_t\n"
                                    "0.1,0.2,1,2,3,0.1,0.2,0.3,7\n"))
    assert d.joints == ("a", "b") and np.allclose(d.sigmas["tool0"], [[0.1, 0.2, 0.3]])
    assert np.allclose(d.meta["meta_t"], [7.0])


@pytest.mark.parametrize("change, message", [
    (lambda m: {**m, "columns": {**m["columns"], "j1": ["NOPE", "deg"]}}, "no column 'NOPE'"),
    (lambda m: {**m, "columns": {**m["columns"], "hand.x": ["X", "deg"]}}, "is not a length"),
    (lambda m: {**m, "columns": {**m["columns"], "j1": ["A1", "inch"]}}, "unknown unit"),
    (lambda m: {**m, "separator": ","}, "separator and the decimal mark"),
    (lambda m: {**m, "rotation": "quaternion"}, "rotation must be"),
    (lambda m: {**m, "colums": {}}, "unknown key"),
])
def test_bad_maps_name_the_problem(tmp_path, change, message):
    with pytest.raises(VjmError, match=message):
        read_poses(_write(tmp_path, TEXT), column_map_from_dict(change(MAP)))


def test_bad_rows_name_the_row(tmp_path):
    with pytest.raises(VjmError, match=r"row 3, column 'X'"):
        read_poses(_write(tmp_path, TEXT.replace("-45,5;-1;0;", "-45,5;-1;zero;")), column_map_from_dict(MAP))
    with pytest.raises(VjmError, match="row 2 has 9 fields"):
        read_poses(_write(tmp_path, TEXT.replace(";s1;", ";")), column_map_from_dict(MAP))
    with pytest.raises(VjmError, match="no column for joint"):
        read_poses(_write(tmp_path, TEXT), column_map_from_dict(MAP), joints=["j1", "j7"])


def test_the_ipa_ur10_files_are_read_as_they_are():
    cmap = read_column_map(os.path.join(IPA, "columns.yaml"))
    a = read_poses(os.path.join(IPA, "Series_A", "measurements_grid.csv"), cmap, group="A")
    d = read_poses(os.path.join(IPA, "Series_D", "measurements_iso_cubes.csv"), cmap, group="D")
    assert (a.n, d.n) == (11911, 632)
    # the files' first rows, as written there
    assert np.allclose(a.points["tool0"][0], [2361.9831, -1368.5474, 119.39713], rtol=0, atol=1e-9)
    assert np.allclose(a.q[0], [-1.5708, -1.5708, 0.0, -1.5708, 0.0, 0.0], rtol=0, atol=1e-12)
    assert np.isclose(a.meta["meta_goal_x"][0], 365.141) and np.isclose(a.meta["meta_temperature"][0], 23.6800003051758)
    assert a.sigmas == {} and np.allclose(d.sigmas["tool0"][0], [0.00095905, 0.0022901, 0.0019936])
    assert d.meta["meta_timestamp"][0] == 2.02103e13   # the spreadsheet-mangled stamp, a number once read


def test_series_b_is_read_as_it_is():
    """Series B (two joint configurations per goal) through the same column map, first row as written."""
    b = read_poses(os.path.join(IPA, "Series_B", "measurements_joint_configurations.csv"),
                   read_column_map(os.path.join(IPA, "columns.yaml")), group="B")
    assert b.n == 1495
    assert np.allclose(b.points["tool0"][0], [383.76294, -3240.8734, 201.93157], rtol=0, atol=1e-9)
    assert np.allclose(b.q[1], [-0.908775, -0.052173, -1.92746, -1.16213, -2.05921, -0.000837151], rtol=0, atol=1e-12)
    assert np.allclose(b.sigmas["tool0"][1], [0.011904, 0.0080769, 0.0088318])
    assert np.isclose(b.meta["meta_goal_z"][1], 800.0)
