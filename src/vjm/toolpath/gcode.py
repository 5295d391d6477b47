"""A strict G-code subset: parse a program, sample its path, write it back with new coordinates.

Accepted: G0, G1, G2/G3 arcs with centre offsets I, J, K (incremental, the
usual G91.1 convention), G17/G18/G19 planes, G90/G91, G20/G21, F, N line
numbers, O program numbers, comments ``( ... )`` and ``; ...``, ``%`` lines, and
the words listed as passed through (default M, S, T), kept verbatim.  A UTF-8 byte
order mark and each line's own ending (LF, CRLF, mixed) are kept for the writer.  Anything else
(an unknown word, ``R`` arcs, a word twice on a line, a number that does not
parse) is refused with one line naming the line number.  Maintained PyPI
parsers (``gcodeparser`` and the like) are lenient and do not keep a line's
text, so they cannot write the same program back with only its coordinates
changed; this one keeps every line as a list of tokens and rewrites only
the numbers of X, Y, Z (and I, J, K of a kept arc).

>>> prog = parse_text("G21 G90\\nG1 X0 Y0 Z0 F600 (start)\\nG1 X10.5\\n")
>>> [ln.words.get("X") for ln in prog.lines]
[None, 0.0, 10.5]
>>> write_text_of(prog) == "G21 G90\\nG1 X0 Y0 Z0 F600 (start)\\nG1 X10.5\\n"
True
"""
from __future__ import annotations

import io
import math
import re
from dataclasses import dataclass, field

import numpy as np

from ..errors import VjmError

#: G codes understood (as numbers)
G_CODES = {0, 1, 2, 3, 17, 18, 19, 20, 21, 90, 91}
#: words with a number that the parser interprets
AXES = "XYZ"
CENTRE = "IJK"
KNOWN = set("GXYZIJKFN")
#: words passed through verbatim unless the caller lists others
DEFAULT_PASS = "MST"
#: words always passed through verbatim: the program number (``O1000``)
ALWAYS_PASS = "O"
BOM = "\ufeff"
#: mm per inch (G20)
INCH = 25.4

_TOKEN = re.compile(r"\s+|\([^()]*\)|;.*$|[A-Za-z][+-]?(?:\d+\.?\d*|\.\d+)|%|\S+")
_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)$")


@dataclass
class Line:
    """One program line: its tokens (text, kept exactly) and the parsed words.

    ``tokens`` is a list of strings whose concatenation is the line; ``word_at``
    maps a word letter to its token index, so that a writer can replace the number.
    ``ending`` is the line's own line ending as read (``""``: the program's).
    """

    number: int
    tokens: list
    words: dict = field(default_factory=dict)
    gcodes: tuple = ()
    word_at: dict = field(default_factory=dict)
    ending: str = ""

    @property
    def text(self) -> str:
        return "".join(self.tokens)


@dataclass
class Program:
    """A parsed program: its lines (with their original line ending) and the pass-through letters.

    ``newline`` is the ending of lines without their own (written ones), ``bom`` the byte order mark
    the text started with (kept, so that the text written back is the same)."""

    lines: list
    newline: str = "\n"
    trailing_newline: bool = True
    passed: str = DEFAULT_PASS
    bom: str = ""


def _fail(n: int, what: str):
    raise VjmError(f"G-code line {n}: {what}")


def parse_line(text: str, n: int, passed: str = DEFAULT_PASS) -> Line:
    """Tokens and words of one line; VjmError naming line ``n`` on anything outside the subset."""
    tokens = [m.group(0) for m in _TOKEN.finditer(text)]
    if "".join(tokens) != text:  # pragma: no cover - the pattern matches every character
        _fail(n, "cannot be read")
    ln = Line(n, tokens)
    gs = []
    for i, tok in enumerate(tokens):
        if tok.isspace() or (tok.startswith("(") and tok.endswith(")")) or tok.startswith(";") or tok == "%":
            continue
        if ")" in tok or "(" in tok:
            _fail(n, f"unbalanced comment near {tok!r}")
        letter = tok[0].upper()
        num = tok[1:]
        if not letter.isalpha() or not _NUMBER.match(num):
            _fail(n, f"{tok!r} is not a word (a letter and a number)")
        if letter in passed.upper() or letter in ALWAYS_PASS:
            continue
        if letter not in KNOWN:
            if letter == "R":
                _fail(n, "R-format arcs are not supported: give the centre with I, J, K")
            _fail(n, f"unknown word {tok!r} (supported: G0-G3, G17-G19, G20/G21, G90/G91, X Y Z I J K F N; "
                     f"passed through: {', '.join(passed) or 'none'})")
        value = float(num)
        if letter == "G":
            if value != int(value) or int(value) not in G_CODES:
                _fail(n, f"unsupported {tok!r} (supported: G0, G1, G2, G3, G17, G18, G19, G20, G21, G90, G91)")
            gs.append(int(value))
            continue
        if letter in ln.words:
            _fail(n, f"word {letter} appears twice")
        ln.words[letter] = value
        ln.word_at[letter] = i
    motion = [g for g in gs if g in (0, 1, 2, 3)]
    for group in ((0, 1, 2, 3), (17, 18, 19), (20, 21), (90, 91)):
        if sum(g in group for g in gs) > 1:
            _fail(n, f"two codes of one modal group: {', '.join(f'G{g}' for g in gs if g in group)}")
    if motion and motion[0] in (0, 1) and any(k in ln.words for k in CENTRE):
        _fail(n, f"I, J, K belong to arcs (G2/G3), not to G{motion[0]}")
    if "F" in ln.words and not ln.words["F"] > 0:
        _fail(n, f"feed F must be > 0, got {ln.words['F']:g}")
    ln.gcodes = tuple(gs)
    return ln


def parse_text(text: str, passed: str = DEFAULT_PASS, name: str = "<G-code>") -> Program:
    """Parse a whole program (see the module docstring)."""
    return parse_lines([text], passed, name)


def parse_lines(lines, passed: str = DEFAULT_PASS, name: str = "<G-code>") -> Program:
    """Parse a program from pieces of its text in order (a text file opened with ``newline=""``, read line by
    line, so that the text is never held whole; or ``[text]``): the same program as :func:`parse_text` of
    their concatenation.  Only the lines' tokens are kept."""
    out: list = []
    bom = ""
    last = ""
    for piece in lines:
        if not out and not last and piece.startswith(BOM) and not bom:
            bom, piece = BOM, piece[len(BOM):]
        for t in piece.splitlines(keepends=True):
            body = t.splitlines()[0] if t.splitlines() else ""
            ln = parse_line(body, len(out) + 1, passed)
            ln.ending = t[len(body):]
            out.append(ln)
            last = t
    newline = "\r\n" if any(ln.ending == "\r\n" for ln in out) else "\n"
    return Program(out, newline, last.endswith(("\n", "\r")), passed, bom)


#: program lines per write of :func:`write_program`
WRITE_LINES = 4096


def write_program(fh, prog: Program) -> None:
    """Write the program's text (:func:`write_text_of`) to the text file ``fh``, WRITE_LINES lines at a
    time (a long program's text is never held whole)."""
    n = len(prog.lines)
    fh.write(prog.bom)
    for a in range(0, n, WRITE_LINES):
        fh.write("".join(ln.text + (ln.ending or (prog.newline if k < n - 1 or prog.trailing_newline else ""))
                         for k, ln in enumerate(prog.lines[a:a + WRITE_LINES], start=a)))


def write_text_of(prog: Program) -> str:
    """The program's text: each line with its own line ending (the program's for a written one)."""
    buf = io.StringIO()
    write_program(buf, prog)
    return buf.getvalue()


# ------------------------------------------------------------------ sampling the path


@dataclass(frozen=True)
class Move:
    """One motion line in machine units (mm): start, end, and the arc's centre and sense if an arc."""

    line: int           # index into Program.lines
    kind: int           # 0, 1, 2, 3
    start: np.ndarray
    end: np.ndarray
    centre: np.ndarray | None
    plane: int          # 17, 18, 19
    scale: float        # mm per program unit (1 or 25.4)
    incremental: bool


#: the plane's (u, v, normal) axes: G3 is counter-clockwise in (u, v)
PLANE_AXES = {17: (0, 1, 2), 18: (2, 0, 1), 19: (1, 2, 0)}


def moves(prog: Program) -> list:
    """The motion lines of a program in mm, absolute; VjmError naming the line on a bad move."""
    pos = np.full(3, np.nan)
    mode, plane, scale, inc = None, 17, 1.0, False
    out = []
    for i, ln in enumerate(prog.lines):
        for g in ln.gcodes:
            if g in (17, 18, 19):
                plane = g
            elif g in (20, 21):
                scale = INCH if g == 20 else 1.0
            elif g in (90, 91):
                inc = g == 91
        m = [g for g in ln.gcodes if g in (0, 1, 2, 3)]
        if m:
            mode = m[0]
        has_axis = any(a in ln.words for a in AXES)
        if not has_axis:
            if m and m[0] in (2, 3):
                _fail(ln.number, "an arc needs an end point (X, Y or Z)")
            continue
        if mode is None:
            _fail(ln.number, "coordinates before any motion code (G0, G1, G2, G3)")
        end = pos.copy()
        for k, a in enumerate(AXES):
            if a in ln.words:
                v = ln.words[a] * scale
                end[k] = (pos[k] + v) if inc else v
        if np.any(np.isnan(end)):
            missing = ", ".join(a for k, a in enumerate(AXES) if np.isnan(end[k]))
            _fail(ln.number, f"the position of {missing} is not known yet: the first move must give X, Y and Z"
                  if not inc else f"incremental move before the position of {missing} is known")
        centre = None
        if mode in (2, 3):
            u, v, _ = PLANE_AXES[plane]
            off = np.zeros(3)
            for k, a in enumerate(CENTRE):
                if a in ln.words:
                    off[k] = ln.words[a] * scale
            if not any(CENTRE[k] in ln.words for k in (u, v)):
                _fail(ln.number, f"an arc in G{plane} needs its centre offset {CENTRE[u]} and/or {CENTRE[v]}")
            centre = pos + off
            r0 = np.hypot(*(pos - centre)[[u, v]])
            r1 = np.hypot(*(end - centre)[[u, v]])
            if r0 == 0:
                _fail(ln.number, "arc of zero radius")
            if abs(r1 - r0) > max(2e-3 * scale, 1e-3 * r0):
                _fail(ln.number, f"arc end is not on the circle: start radius {r0 / scale:.6g}, end radius "
                                 f"{r1 / scale:.6g} (program units)")
        out.append(Move(i, mode, pos.copy(), end, centre, plane, scale, inc))
        pos = end
    if not out:
        raise VjmError("G-code: no motion (no line with X, Y or Z)")
    return out


def _arc(mv: Move, chord_tol: float):
    """Start angle, signed sweep, start radius and number of chords of an arc within ``chord_tol``."""
    u, v, _ = PLANE_AXES[mv.plane]
    a0 = np.arctan2(*(mv.start - mv.centre)[[v, u]])
    a1 = np.arctan2(*(mv.end - mv.centre)[[v, u]])
    r = np.hypot(*(mv.start - mv.centre)[[u, v]])
    sweep = a1 - a0
    if mv.kind == 3:  # counter-clockwise
        sweep = sweep % (2 * np.pi)
        if sweep <= 1e-12:
            sweep = 2 * np.pi
    else:
        sweep = -((-sweep) % (2 * np.pi))
        if sweep >= -1e-12:
            sweep = -2 * np.pi
    x = chord_tol / r
    if x >= 2.0:
        step = np.pi
    elif x < 1e-8:
        # the same angle, 1 - cos(step / 2) = x, written so that a tiny x keeps its digits (arccos(1 - x)
        # is 0 below x ~ 1e-16, which counted such an arc's points as infinite)
        step = 4.0 * math.asin(math.sqrt(x / 2.0))
    else:
        step = 2.0 * np.arccos(1.0 - x)
    chords = abs(sweep) / step - 1e-12 if step > 0 else math.inf
    return a0, sweep, r, max(1.0, math.ceil(chords) if math.isfinite(chords) else math.inf)


def arc_points(mv: Move, chord_tol: float) -> np.ndarray:
    """Points (k, 3) along an arc after its start, the last being its end, within ``chord_tol`` (mm)
    of the true arc (sagitta of each chord); helices move the normal axis linearly."""
    u, v, w = PLANE_AXES[mv.plane]
    a0, sweep, r, chords = _arc(mv, chord_tol)
    k = int(chords)
    t = np.arange(1, k + 1) / k
    ang = a0 + sweep * t
    r1 = np.hypot(*(mv.end - mv.centre)[[u, v]])
    rr = r + (r1 - r) * t
    out = np.empty((k, 3))
    out[:, u] = mv.centre[u] + rr * np.cos(ang)
    out[:, v] = mv.centre[v] + rr * np.sin(ang)
    out[:, w] = mv.start[w] + (mv.end[w] - mv.start[w]) * t
    out[-1] = mv.end
    return out


def sample_count(prog: Program, chord_tol: float = 1e-3, step: float = 1.0) -> float:
    """The number of points :func:`sample` makes, counted without making them (a float: it may be huge)."""
    n = 0.0
    for m in moves(prog):
        if np.any(np.isnan(m.start)):
            n += 1.0
        elif m.kind in (2, 3):
            n += _arc(m, chord_tol)[3]
        else:
            n += max(1.0, math.ceil(float(np.linalg.norm(m.end - m.start)) / step))
    return n


def sample(prog: Program, chord_tol: float = 1e-3, step: float = 1.0):
    """Points (n, 3) mm along the program, with per point the index of its line (into ``prog.lines``),
    the motion code, and whether the point is a written end point (vs. an interior sample).

    Straight moves are sampled every ``step`` mm at most; arcs within ``chord_tol`` mm.
    """
    pts, line, kind, vertex = [], [], [], []
    for m in moves(prog):
        if np.any(np.isnan(m.start)):  # the first move: from an unknown position, its end point only
            p = m.end[None]
        elif m.kind in (2, 3):
            p = arc_points(m, chord_tol)
        else:
            k = max(1, int(np.ceil(np.linalg.norm(m.end - m.start) / step)))
            t = np.arange(1, k + 1)[:, None] / k
            p = m.start + t * (m.end - m.start)
            p[-1] = m.end
        pts.append(p)
        line += [m.line] * len(p)
        kind += [m.kind] * len(p)
        vertex += [False] * (len(p) - 1) + [True]
    return np.vstack(pts), np.array(line), np.array(kind), np.array(vertex)


# ------------------------------------------------------------------ writing new coordinates


def _fmt(value: float, like: str, unit_scale: float) -> str:
    """``value`` with at least as many decimals as the token ``like`` had (and enough for 0.1 um)."""
    num = like[1:]
    dec = len(num.split(".")[1]) if "." in num else 0
    need = 5 if unit_scale != 1.0 else 4
    s = f"{value:.{max(dec, need)}f}"
    if s.startswith("-") and float(s) == 0.0:
        s = s[1:]
    return s


def rewrite(prog: Program, new_end: dict, new_centre: dict | None = None) -> Program:
    """A copy of ``prog`` whose motion lines end at ``new_end[line index]`` (mm, absolute).

    Only the numbers of X, Y, Z (and of I, J, K where ``new_centre`` gives an arc's centre)
    change; every other token, the line order and the line endings stay.  An axis the line
    did not name keeps being omitted (its value must then be unchanged: the writer adds it
    after the line's last interpreted word, with a space, if compensation moved it).
    """
    mv = {m.line: m for m in moves(prog)}
    lines = []
    prev = None  # compensated position so far (mm)
    for i, ln in enumerate(prog.lines):
        m = mv.get(i)
        if m is None:
            lines.append(Line(ln.number, list(ln.tokens), dict(ln.words), ln.gcodes, dict(ln.word_at), ln.ending))
            continue
        tokens = list(ln.tokens)
        end = new_end[i]
        start_c = prev if prev is not None else end  # first move: no earlier written point
        extra = []
        for k, a in enumerate(AXES):
            val = (end[k] - start_c[k]) if m.incremental else end[k]
            val /= m.scale
            if a in ln.word_at:
                j = ln.word_at[a]
                if abs(val - ln.words[a]) >= 0.5 * 10.0 ** -(5 if m.scale != 1.0 else 4):
                    tokens[j] = tokens[j][0] + _fmt(val, tokens[j], m.scale)
            elif abs(end[k] - start_c[k]) / m.scale >= 0.5 * 10.0 ** -(5 if m.scale != 1.0 else 4):
                # the line left this axis where it was; compensation moved it: name it
                extra.append(f"{a}{_fmt(val, a + '0', m.scale)}")
        if new_centre is not None and i in new_centre and m.centre is not None:
            c = (new_centre[i] - start_c) / m.scale
            for k, a in enumerate(CENTRE):
                if a in ln.word_at and abs(c[k] - ln.words[a]) >= 0.5 * 10.0 ** -(5 if m.scale != 1.0 else 4):
                    j = ln.word_at[a]
                    tokens[j] = tokens[j][0] + _fmt(c[k], tokens[j], m.scale)
        if extra:  # after the line's last axis word (else its last interpreted word)
            at = max([j for a, j in ln.word_at.items() if a in AXES] or list(ln.word_at.values())) + 1
            tokens[at:at] = [" " + e for e in extra]
        text = "".join(tokens)
        lines.append(parse_line(text, ln.number, prog.passed))
        lines[-1].ending = ln.ending
        prev = end
    return Program(lines, prog.newline, prog.trailing_newline, prog.passed, prog.bom)


def linearize(prog: Program, arcs: dict) -> Program:
    """A copy of ``prog`` where every move line ``i`` in ``arcs`` becomes G1 moves through ``arcs[i]``
    ((k, 3) mm): arcs as chords, or feed moves split into pieces.

    The first generated line keeps the line's other words and comments.  Every arc is given (the
    callers linearize all or none), so no later line relies on a modal G2/G3.  Absolute coordinates only.
    """
    mv = {m.line: m for m in moves(prog)}
    out = []
    for i, ln in enumerate(prog.lines):
        if i not in arcs:
            out.append(ln)
            continue
        mvi = mv[i]
        if mvi.incremental:
            _fail(ln.number, "moves can be linearized or split in absolute mode (G90) only")
        drop = {j for a, j in ln.word_at.items() if a in AXES + CENTRE}
        keep = [t for j, t in enumerate(ln.tokens)
                if j not in drop and not re.fullmatch(r"[Gg]0*[0-3](\.0*)?", t)]
        pts = arcs[i] / mvi.scale
        for k, p in enumerate(pts):
            text = "G1 " + " ".join(f"{a}{v:.5f}" for a, v in zip(AXES, p))
            if k == 0:  # the arc line's other words and comments ride on its first segment
                text = (text + " " + "".join(keep).strip()).rstrip()
            out.append(parse_line(text, ln.number, prog.passed))
            out[-1].ending = ln.ending if k == len(pts) - 1 else (ln.ending or prog.newline)
    return Program(out, prog.newline, prog.trailing_newline, prog.passed, prog.bom)
