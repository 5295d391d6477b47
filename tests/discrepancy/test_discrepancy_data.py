"""Reading measurement CSVs: every bad input names its row and column."""
import numpy as np
import pytest

from vjm.discrepancy.data import Deflections, StiffnessObs, read_csv, write_deflections
from vjm.errors import VjmError

HDR = "x,y,z,Fx,Fy,Fz,Mx,My,Mz,dx,dy,dz,rx,ry,rz"


def _write(tmp_path, text, name="m.csv"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_round_trip_with_blank_rotations(tmp_path):
    P = np.array([[0.0, 1.0, 2.0], [3.0, 4.0, 5.0]])
    W = np.array([[100.0, 0, 0, 0, 0, 0], [0, -50.0, 0, 0, 0, 1000.0]])
    T = np.array([[1e-3, 2e-5, 0.0, np.nan, np.nan, np.nan], [0.0, -4e-3, 1e-6, 1e-7, np.nan, 2e-6]])
    d = Deflections(P, W, T, np.full(2, 1e-3), None)
    path = tmp_path / "d.csv"
    write_deflections(path, d, "comment line")
    back = read_csv(path)
    assert isinstance(back, Deflections)
    np.testing.assert_array_equal(back.P, P)
    np.testing.assert_array_equal(back.W, W)
    np.testing.assert_array_equal(np.isnan(back.T), np.isnan(T))
    np.testing.assert_array_equal(back.T[~np.isnan(T)], T[~np.isnan(T)])
    assert back.sigma_r is None and np.all(back.sigma_t == 1e-3)
    assert list(back.rows) == [3, 4]  # comment line is row 1, header row 2


def test_missing_column_named(tmp_path):
    p = _write(tmp_path, "x,y,z,Fx,Fy,Fz,Mx,My,Mz,dx,dy,rx,ry,rz\n0,0,0,1,0,0,0,0,0,0,0,,,\n")
    with pytest.raises(VjmError, match=r"row 1, column 'dz'.*missing column"):
        read_csv(p)


def test_malformed_row_named(tmp_path):
    p = _write(tmp_path, HDR + "\n0,0,0,1,0,0,0,0,0,1e-3,0,0,,,\n0,0,0,1,0,0\n")
    with pytest.raises(VjmError, match=r"row 3.*malformed"):
        read_csv(p)


def test_nan_in_required_column_named(tmp_path):
    p = _write(tmp_path, HDR + "\n0,0,0,1,0,0,0,0,0,1e-3,0,0,,,\n5,nan,0,1,0,0,0,0,0,1e-3,0,0,,,\n")
    with pytest.raises(VjmError, match=r"row 3, column 'y'"):
        read_csv(p)


def test_text_in_number_column_named(tmp_path):
    p = _write(tmp_path, HDR + "\n0,0,0,1,0,abc,0,0,0,1e-3,0,0,,,\n")
    with pytest.raises(VjmError, match=r"row 2, column 'Fz': 'abc' is not a number"):
        read_csv(p)


def test_all_loads_zero(tmp_path):
    p = _write(tmp_path, HDR + "\n0,0,0,0,0,0,0,0,0,1e-3,0,0,,,\n1,0,0,0,0,0,0,0,0,1e-3,0,0,,,\n")
    with pytest.raises(VjmError, match=r"row 2, column 'Fx'.*all applied loads are zero"):
        read_csv(p)


def test_row_without_any_measurement(tmp_path):
    p = _write(tmp_path, HDR + "\n0,0,0,1,0,0,0,0,0,,,,,,\n")
    with pytest.raises(VjmError, match=r"row 2, column 'dx'"):
        read_csv(p)


def test_stiffness_observations(tmp_path):
    p = _write(tmp_path, "architecture,x,y,z,quantity,value\n3-PUU,0,0,0,k_tran,2.78e-4\n3-PUU,0,0,0,k_rot,20.9e-7\n")
    d = read_csv(p)
    assert isinstance(d, StiffnessObs)
    assert list(d.quantity) == [0, 1] and d.extra["architecture"] == ["3-PUU", "3-PUU"]
    bad = _write(tmp_path, "x,y,z,quantity,value\n0,0,0,k_foo,1\n", "b.csv")
    with pytest.raises(VjmError, match=r"row 2, column 'quantity'"):
        read_csv(bad)
