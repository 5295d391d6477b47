"""The strict G-code subset of ``vjm path``: round trip, arcs within their chord tolerance,
one-line errors naming the line, coordinates rewritten and nothing else."""
import numpy as np
import pytest

from vjm import VjmError
from vjm.toolpath import gcode as gc

POCKET = "data/toolpaths/pocket.nc"


def _text():
    with open(POCKET, encoding="utf-8", newline="") as fh:
        return fh.read()


def _same(a: gc.Program, b: gc.Program):
    assert [ln.text for ln in a.lines] == [ln.text for ln in b.lines]
    assert [ln.words for ln in a.lines] == [ln.words for ln in b.lines]
    assert [ln.gcodes for ln in a.lines] == [ln.gcodes for ln in b.lines]


@pytest.mark.parametrize("newline", ["\n", "\r\n"])
def test_round_trip_parse_write_parse_is_identical(newline):
    """parse -> write unchanged -> parse gives the same program, byte for byte (both line endings)."""
    text = _text().replace("\n", newline)
    p1 = gc.parse_text(text)
    out = gc.write_text_of(p1)
    assert out == text
    _same(p1, gc.parse_text(out))


def test_rewrite_with_unchanged_coordinates_keeps_every_word_and_comment():
    """Writing the program's own end points back changes only the numbers' decimals, nothing else:
    same words, codes, comments and line order; the sampled path is the same."""
    prog = gc.parse_text(_text())
    ends = {m.line: m.end for m in gc.moves(prog)}
    out = gc.rewrite(prog, ends)
    assert len(out.lines) == len(prog.lines)
    for a, b in zip(prog.lines, out.lines):
        assert a.gcodes == b.gcodes and set(a.words) == set(b.words)
        assert [t for t in a.tokens if t.startswith("(")] == [t for t in b.tokens if t.startswith("(")]
        for k, v in a.words.items():
            assert b.words[k] == pytest.approx(v, abs=1e-12)
    np.testing.assert_allclose(gc.sample(out)[0], gc.sample(prog)[0], atol=1e-12)


def test_rewrite_moves_only_coordinates():
    prog = gc.parse_text("G21 G90\nG1 X0 Y0 Z0 F500 (a)\nG1 X10 S100\n")
    out = gc.rewrite(prog, {1: np.array([0.001, 0.0, 0.0]), 2: np.array([10.0, 0.0005, 0.0])})
    text = gc.write_text_of(out)
    # numbers whose value is unchanged keep their text; a moved axis the line left out is added
    assert text == "G21 G90\nG1 X0.0010 Y0 Z0 F500 (a)\nG1 X10 Y0.0005 S100\n"


@pytest.mark.parametrize("tol", [1e-2, 1e-3, 1e-4])
@pytest.mark.parametrize("code,plane", [("G2", 17), ("G3", 17), ("G2", 18), ("G3", 19)])
def test_arcs_within_their_chord_tolerance(tol, code, plane):
    """Every chord of the sampled arc stays within ``tol`` of the true circle (sagitta of the chord
    midpoint, from the centre in closed form), and the samples lie on the circle."""
    u, v, w = gc.PLANE_AXES[plane]
    start = np.zeros(3)
    centre = np.zeros(3)
    centre[u] = 20.0
    end = np.zeros(3)
    end[u], end[v] = 20.0, 20.0 if code == "G3" else -20.0
    ijk = " ".join(f"{'IJK'[k]}{(centre - start)[k]:g}" for k in (u, v))
    xyz = " ".join(f"{'XYZ'[k]}{end[k]:g}" for k in range(3))
    prog = gc.parse_text(f"G21 G90 G{plane}\nG1 X0 Y0 Z0\n{code} {xyz} {ijk}\n")
    pts, line, _, _ = gc.sample(prog, chord_tol=tol)
    arc = pts[line == 2]
    arc = np.vstack([start, arc])
    r = np.linalg.norm((arc - centre)[:, [u, v]], axis=1)
    np.testing.assert_allclose(r, 20.0, atol=1e-9)
    mid = 0.5 * (arc[1:] + arc[:-1])
    sag = 20.0 - np.linalg.norm((mid - centre)[:, [u, v]], axis=1)
    assert sag.max() <= tol * (1 + 1e-9)
    assert sag.max() > 0.25 * tol  # not needlessly fine
    # a quarter circle: the sense of G2 / G3 as in the standard (counter-clockwise = G3 seen from +normal)
    cross = np.cross(arc[1] - centre, arc[2] - centre)[w]
    assert (cross > 0) == (code == "G3")


def test_full_circle_and_helix():
    prog = gc.parse_text("G90 G17\nG1 X10 Y0 Z0\nG2 X10 Y0 Z-2 I-10 J0\n")
    pts, line, _, _ = gc.sample(prog, chord_tol=1e-3)
    arc = pts[line == 2]
    assert np.linalg.norm(arc[:, :2], axis=1) == pytest.approx(10.0)
    assert arc[-1, 2] == -2.0 and np.all(np.diff(arc[:, 2]) < 0)
    assert len(arc) > 100  # the whole turn, not an empty arc


@pytest.mark.parametrize("text,line,words", [
    ("G1 X0 Y0 Z0\nG1 X1 Q5\n", 2, "unknown word 'Q5'"),
    ("G1 X0 Y0 Z0\nG2 X10 Y0 R5\n", 2, "R-format arcs"),
    ("G1 X0 Y0 Z0\n\nG1 X1 X2\n", 3, "appears twice"),
    ("G1 X0 Y0 Z0\nG1 X1.2.3\n", 2, "not a word"),
    ("G1 X0 Y0 Z0\nG41 X1\n", 2, "unsupported 'G41'"),
    ("G1 X0 Y0 Z0\nG0 G1 X1\n", 2, "two codes of one modal group"),
    ("G1 X0 Y0\n", 1, "first move must give X, Y and Z"),
    ("X0 Y0 Z0\n", 1, "before any motion code"),
    ("G1 X0 Y0 Z0\nG2 X10 Y0 I3 J0\n", 2, "not on the circle"),
    ("G1 X0 Y0 Z0\nG1 X1 (open\n", 2, "comment"),
    ("G1 X0 Y0 Z0\nG1 X1 F0\n", 2, "feed F must be > 0"),
    ("G1 X0 Y0 Z0\nG1 X1 I2\n", 2, "belong to arcs"),
])
def test_bad_gcode_is_one_line_naming_the_line(text, line, words):
    with pytest.raises(VjmError) as e:
        gc.sample(gc.parse_text(text))
    msg = str(e.value)
    assert "\n" not in msg and f"line {line}" in msg and words in msg


def test_pass_through_words_are_kept_and_others_refused():
    text = "G1 X0 Y0 Z0 M3 S1000 T1\nG1 X1 H2\n"
    with pytest.raises(VjmError, match="line 2: unknown word 'H2'"):
        gc.parse_text(text)
    prog = gc.parse_text(text, passed="MSTH")
    assert gc.write_text_of(prog) == text


def test_inches_and_incremental_moves_in_mm():
    prog = gc.parse_text("G20 G90\nG1 X1 Y0 Z0\nG91\nG1 X0.5 Y0.25\n")
    mv = gc.moves(prog)
    np.testing.assert_allclose(mv[-1].end, [1.5 * 25.4, 0.25 * 25.4, 0.0])
    # rewritten in the program's own units and mode: increments between the compensated points
    out = gc.rewrite(prog, {1: np.array([25.4, 0, 0]), 3: np.array([1.5 * 25.4 + 0.0254, 0.25 * 25.4, 0])})
    assert gc.moves(out)[-1].end == pytest.approx([1.5 * 25.4 + 0.0254, 0.25 * 25.4, 0.0])
    assert out.lines[3].words["X"] == pytest.approx(0.501)


def test_linearized_arcs_are_g1_chords_through_the_given_points():
    prog = gc.parse_text("G90 G17\nG1 X10 Y0 Z0 F100\nG3 X0 Y10 I-10 J0 (quarter)\nG1 X0 Y20\n")
    pts, line, _, _ = gc.sample(prog, chord_tol=1e-3)
    out = gc.linearize(prog, {2: pts[line == 2]})
    codes = [ln.gcodes for ln in out.lines]
    assert all(c == (1,) for c in codes[2:-1])
    assert "(quarter)" in out.lines[2].text and "F100" not in out.lines[2].text
    np.testing.assert_allclose(gc.sample(out)[0][-1], [0, 20, 0])
    p2 = np.vstack([m.end for m in gc.moves(out)])[1:-1]
    np.testing.assert_allclose(p2, pts[line == 2], atol=1e-5)


def test_round_trip_keeps_a_bom_and_mixed_line_endings():
    """A UTF-8 byte order mark and lines ending in LF, CRLF and CR (as files edited on two systems have):
    read, and written back byte for byte, unchanged and after a rewrite or a linearization, which keep
    every line's own ending."""
    lines = ["%", "G21 G90", "G1 X10 Y0 Z0 F100", "G3 X0 Y10 I-10 J0 (quarter)", "G1 X0 Y20", "%"]
    ends = ["\r\n", "\n", "\r\n", "\r", "\n", "\r\n"]
    text = gc.BOM + "".join(a + b for a, b in zip(lines, ends))
    prog = gc.parse_text(text)
    assert gc.write_text_of(prog) == text and prog.lines[1].gcodes == (21, 90)
    assert gc.write_text_of(gc.rewrite(prog, {m.line: m.end for m in gc.moves(prog)})) == text
    pts, line, _, _ = gc.sample(prog, chord_tol=1e-3)
    out = gc.write_text_of(gc.linearize(prog, {3: pts[line == 3]}))
    assert out.startswith(gc.BOM + "%\r\nG21 G90\nG1 X10 Y0 Z0 F100\r\nG1 ") and out.endswith("\rG1 X0 Y20\n%\r\n")
    k = len(pts[line == 3])
    assert out.count("\r\n") == 3 and out.count("\r") - 3 == k  # the arc's k chords end as the arc line did
    no_end = gc.parse_text("G1 X0 Y0 Z0\r\nG1 X1")  # no ending after the last line: none written
    assert gc.write_text_of(no_end) == "G1 X0 Y0 Z0\r\nG1 X1"


def test_a_program_is_written_in_pieces_byte_for_byte(monkeypatch):
    """write_program writes WRITE_LINES lines at a time (vjm path writes the compensated program so, never
    as one string): the pieces join to the text read, byte order mark, CRLF endings and a last line
    without an ending included."""
    monkeypatch.setattr(gc, "WRITE_LINES", 3)
    text = gc.BOM + _text().replace("\n", "\r\n")[:-2]
    prog = gc.parse_text(text)

    class Pieces(list):
        def write(self, s):
            self.append(s)

    out = Pieces()
    gc.write_program(out, prog)
    assert "".join(out) == text and gc.write_text_of(prog) == text
    assert len(out) == 1 + -(-len(prog.lines) // 3) and len(prog.lines) > 6
    assert all(p.count("\n") <= 3 for p in out)


def test_program_number_is_passed_through():
    """``O1000``, the program number most real programs start with, is kept verbatim, as ``%`` lines are."""
    text = "%\nO1000 (POCKET)\nG21 G90\nG1 X0 Y0 Z0 F500\nG1 X5\nM30\n%\n"
    prog = gc.parse_text(text)
    assert gc.write_text_of(prog) == text and prog.lines[1].words == {}
    assert [m.end.tolist() for m in gc.moves(prog)] == [[0, 0, 0], [5, 0, 0]]


def test_toolpath_files_with_a_byte_order_mark_are_read(tmp_path):
    """Files that start with a UTF-8 byte order mark (as editors and spreadsheets on Windows write them):
    G-code and CSV toolpaths read as without it."""
    from vjm.toolpath import points

    (tmp_path / "p.nc").write_bytes(b"\xef\xbb\xbfG21 G90\r\nG1 X0 Y0 Z0 F100\nG1 X2\r\n")
    (tmp_path / "p.csv").write_bytes(b"\xef\xbb\xbfx,y,z\n0,0,0\n2,0,0\n")
    for name in ("p.nc", "p.csv"):
        tp = points.read(str(tmp_path / name))
        np.testing.assert_allclose(tp.points[[0, -1], :3], [[0, 0, 0], [2, 0, 0]])


@pytest.mark.parametrize("chord_tol,step", [(1e-3, 1.0), (1e-2, 0.3), (0.5, 7.0)])
def test_the_sample_count_is_the_samples_made(chord_tol, step):
    """``sample_count`` (the estimate made before sampling) counts exactly the points ``sample`` makes, on the
    pocket's lines and arcs."""
    prog = gc.parse_text(_text())
    assert gc.sample_count(prog, chord_tol, step) == len(gc.sample(prog, chord_tol, step)[0])


@pytest.mark.parametrize("kw", [{"step": 1e-6}, {"chord_tol": 1e-14}, {"chord_tol": 1e-300}])
def test_a_sampling_beyond_the_memory_is_refused_before_it_starts(kw, monkeypatch):
    """``--step 1e-6`` grew to 24 GB before the kernel killed it: the count is made first and refused with the
    figures (the memory limit set to 64 GB, so that the answer does not depend on this machine)."""
    from vjm.maps import grid
    from vjm.toolpath.points import from_gcode

    monkeypatch.setattr(grid, "available_memory", lambda: 80e9)

    def never(*a, **k):
        raise AssertionError("sampled")

    monkeypatch.setattr(gc, "sample", never)
    with pytest.raises(VjmError, match=r"vjm path would need about .* more than the 64 GB this machine can give"):
        from_gcode(gc.parse_text(_text()), "pocket.nc", **kw)


@pytest.mark.parametrize("tail", ["%\r\n", "G1 X1", "G1 X1\r", ""])
def test_a_program_read_line_by_line_is_the_program_of_its_whole_text(tmp_path, tail):
    """vjm path parses a G-code file as it reads it (gc.parse_lines over the open file, never the whole
    text): the same lines, endings, byte order mark and last-line ending as parse_text of the text, so the
    program written back is the file byte for byte (LF, CRLF, CR, a form feed inside a line, no ending last)."""
    text = gc.BOM + "%\r\nG21 G90\nG1 X10 Y0 Z0 F100\r\nG3 X0 Y10 I-10 J0 (quarter)\rG1 X0 Y20\x0c\n" + tail
    f = tmp_path / "p.nc"
    f.write_bytes(text.encode("utf-8"))
    whole = gc.parse_text(text)
    with open(f, encoding="utf-8", newline="") as fh:
        read = gc.parse_lines(fh)
    assert [(ln.tokens, ln.ending) for ln in read.lines] == [(ln.tokens, ln.ending) for ln in whole.lines]
    assert (read.newline, read.trailing_newline, read.bom) == (whole.newline, whole.trailing_newline, whole.bom)
    assert gc.write_text_of(read) == text
