"""Long toolpaths are read and written in pieces: the memory a CSV toolpath takes to read, and the memory
the compensated program and the table take to write, do not grow with the program beyond its arrays."""
import io
import tracemalloc

import numpy as np

from vjm.compensation import Compensation
from vjm.toolpath import points
from vjm.toolpath.result import PathResult


def _csv(path, n):
    rng = np.random.default_rng(0)
    A = np.column_stack([rng.uniform(-50, 50, (n, 3)), rng.uniform(-100, 100, (n, 6))])
    with open(path, "w", encoding="utf-8") as fh:
        fh.write("x,y,z,Fx,Fy,Fz,Mx,My,Mz\n# a comment\n")
        np.savetxt(fh, A, fmt="%.17g", delimiter=",")
    return A


def _peak(f):
    tracemalloc.start()
    try:
        out = f()
        return out, tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_reading_a_csv_toolpath_takes_its_arrays_and_a_bounded_rest(tmp_path):
    """Peak memory while reading, less the arrays returned: the same for 5k and 20k rows (the old
    reader held the text and a list of strings per row, ~0.6 kB per point)."""
    extra = {}
    for n in (5_000, 20_000):
        f = tmp_path / f"p{n}.csv"
        A = _csv(f, n)
        tp, peak = _peak(lambda f=f: points.read(f))
        np.testing.assert_array_equal(np.hstack([tp.poses, tp.wrench]), A)  # every value, exactly
        assert tp.lines[0] == 3 and tp.lines[-1] == n + 2  # line numbers of the file
        arrays = 8 * n * (9 + 1 + 1) + 2 * n  # values, line numbers, line index, flags
        extra[n] = peak - arrays
        assert peak < 1.3 * arrays + 2e6
    assert extra[20_000] < 1.5 * max(extra[5_000], 1e6)


def test_the_table_and_the_compensated_csv_are_written_in_pieces(tmp_path, monkeypatch):
    """Writing path.csv and the compensated CSV of 8k points takes about what 2k take (pieces of
    CSV_ROWS rows), and the pieces give the same text as one piece."""
    monkeypatch.setattr(points, "CSV_ROWS", 500)
    peaks = {}
    for n in (2_000, 8_000):
        f = tmp_path / f"p{n}.csv"
        _csv(f, n)
        tp = points.read(f)
        cmd = tp.poses + 1e-3
        res = PathResult(tp, tp.wrench, np.full((n, 6), 1e-3), "nonlinear",
                         compensation=Compensation(cmd, np.zeros(n), equilibria=1),
                         compensated=lambda fh, tp=tp, cmd=cmd: points.write_csv(fh, tp, cmd))

        def write(res=res, n=n):
            with open(tmp_path / f"out{n}.csv", "w", encoding="utf-8") as fh:
                res.write_compensated(fh)
            with open(tmp_path / f"table{n}.csv", "w", encoding="utf-8") as fh:
                res.write_table(fh, rows=500)

        peaks[n] = _peak(write)[1]
        back = points.read(tmp_path / f"out{n}.csv")
        np.testing.assert_allclose(back.poses, cmd, rtol=0, atol=5.1e-7)  # 6 decimals
        assert (tmp_path / f"out{n}.csv").read_text() == points.csv_text(tp, cmd)
        buf = io.StringIO()
        res.write_table(buf, rows=n)
        assert (tmp_path / f"table{n}.csv").read_text() == buf.getvalue()
    assert peaks[8_000] < 1.5 * peaks[2_000]


def test_the_table_in_pieces_is_the_table_in_one(tmp_path):
    """Arc length and errors computed piece by piece give the same text as in one piece."""
    f = tmp_path / "p.csv"
    _csv(f, 1000)
    tp = points.read(f)
    d = np.random.default_rng(2).normal(0, 1e-3, (tp.n, 6))
    res = PathResult(tp, tp.wrench, d, "nonlinear", after=d[::-1].copy())
    one, pieces = io.StringIO(), io.StringIO()
    res.write_table(one, rows=tp.n)
    res.write_table(pieces, rows=7)
    assert one.getvalue() == pieces.getvalue() == res.table()
    s = [float(r.split(",")[1]) for r in one.getvalue().splitlines()[1:]]
    np.testing.assert_allclose(s, tp.arc_length(), rtol=1e-5)
