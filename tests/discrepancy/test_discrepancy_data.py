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


# ---------------------------------------------------------------- files from instruments and spreadsheets
PLAIN = HDR + ",sigma_t\n0,0,0,100,0,0,0,0,0,0.0281,-1.5e-4,0,,,,0.001\n10,-20,5,0,-50,0,0,0,1000,0,-0.0142,2e-5,,,,0.001\n"


@pytest.mark.parametrize("variant", [
    "\ufeff" + PLAIN,                                                    # UTF-8 byte-order mark (Excel's CSV UTF-8)
    PLAIN.replace(",", ";"),                                             # ; separators, decimal points
    PLAIN.replace(",", ";").replace(".", ","),                           # ; separators, decimal commas
    PLAIN.replace(",", "\t").replace(".", ","),                          # tab separators, decimal commas
    PLAIN.split("\n", 1)[0].upper().replace("SIGMA_T", "Sigma_T") + "\n" + PLAIN.split("\n", 1)[1],  # upper case
    " " + PLAIN.split("\n", 1)[0].replace(",", " , ") + " \n" + PLAIN.split("\n", 1)[1].replace(",", ", "),
])
def test_spreadsheet_dialects_read_as_the_plain_file(tmp_path, variant):
    ref = read_csv(_write(tmp_path, PLAIN, "plain.csv"))
    got = read_csv(_write(tmp_path, variant))
    for a in ("P", "W", "T", "sigma_t"):
        np.testing.assert_array_equal(getattr(got, a), getattr(ref, a))
    assert got.T[0, 0] == 0.0281 and got.T[1, 2] == 2e-5


def test_unknown_columns_refused_unless_meta(tmp_path):
    """A misspelt sigma would silently switch to sigmas estimated from the residuals: refused, naming the
    closest known name; a meta_ column is carried along as text."""
    with pytest.raises(VjmError, match=r"column 'sigmat': unknown column \(did you mean 'sigma_t'\?\)"):
        read_csv(_write(tmp_path, PLAIN.replace("sigma_t", "sigmat")))
    with pytest.raises(VjmError, match=r"column 'temperature': unknown column.*name it meta_temperature"):
        read_csv(_write(tmp_path, PLAIN.replace("sigma_t", "temperature")))
    d = read_csv(_write(tmp_path, PLAIN.replace("sigma_t", "META_temperature")))
    assert d.sigma_t is None and d.meta == {"meta_temperature": ["0.001", "0.001"]}


def test_exact_duplicates_refused_genuine_repeats_kept(tmp_path):
    row = "0,0,0,100,0,0,0,0,0,0.0281,0,0,,,"
    with pytest.raises(VjmError, match=r"row 4: repeats row 2 exactly"):
        read_csv(_write(tmp_path, "\n".join([HDR, row, row.replace("100", "50"), row]) + "\n"))
    # same posture and load, another reading: a genuine repeat, kept
    d = read_csv(_write(tmp_path, "\n".join([HDR, row, row.replace("0.0281", "0.0279")]) + "\n"))
    assert d.n == 2 and d.T[0, 0] != d.T[1, 0]
    # repeats that read the same are told apart by a meta_ column
    d = read_csv(_write(tmp_path, "\n".join([HDR + ",meta_run", row + ",1", row + ",2"]) + "\n"))
    assert d.n == 2 and d.meta["meta_run"] == ["1", "2"]


def test_encodings_named(tmp_path):
    p = tmp_path / "u16.csv"
    p.write_bytes(PLAIN.encode("utf-16"))
    with pytest.raises(VjmError, match="UTF-16"):
        read_csv(p)
    p.write_bytes(("# mesure à 20 °C\n" + PLAIN).encode("latin-1"))
    with pytest.raises(VjmError, match=r"row 1: byte 0xe0 is not UTF-8"):
        read_csv(p)


def test_a_diagnosis_beyond_the_memory_is_refused_before_it_starts(tmp_path, monkeypatch):
    """120,000 rows (a 27 MB file of ``vjm simulate``) passed 12 GB in 45 s: the estimate from the row count
    and the candidates (210 kB per row with all 25, measured) refuses it on a 16 GB machine at once; a smaller
    file is refused the same way when the memory is smaller, before any stage runs."""
    from vjm.discrepancy import workflow
    from vjm.maps import grid

    monkeypatch.setattr(grid, "available_memory", lambda: 20e9)  # 16 GB usable (80%)
    with pytest.raises(VjmError, match=r"vjm diagnose would need about 25.2 GB of memory for 1.2e\+05 rows"):
        workflow.diagnose_plan(120_000)
    assert workflow.diagnose_plan(120_000, 2).memory == pytest.approx(2 / 25 * 120_000 * 2.1e5)

    def never(*a, **k):
        raise AssertionError("a stage ran")

    monkeypatch.setattr(workflow, "run_stages", never)
    monkeypatch.setattr(grid, "available_memory", lambda: 1e5)  # 3 rows need 630 kB
    import vjm
    model = vjm.load_model("puu")
    C = model.stiffness([0.0, 0.0, 0.0]).C
    rows = ["x,y,z,Fx,Fy,Fz,Mx,My,Mz,dx,dy,dz,rx,ry,rz"]
    for k in range(3):
        w = np.zeros(6)
        w[k] = 100.0
        t = C @ w
        rows.append("0,0,0," + ",".join(f"{v:g}" for v in w) + "," + ",".join(f"{v:.6g}" for v in t[:3]) + ",,,")
    (tmp_path / "m.csv").write_text("\n".join(rows) + "\n")
    with pytest.raises(VjmError, match="vjm diagnose would need about"):
        workflow.diagnose(model, tmp_path / "m.csv")
