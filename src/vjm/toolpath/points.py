"""A toolpath: programmed TCP poses along a path, read from a CSV of points or from G-code.

A :class:`Toolpath` holds the sampled poses (n, 3) or (n, 6) in mm and rad
(world axes), the source line of every point (for messages and for writing
the compensated program), whether a point is a written end point of the
source, whether it is a cutting (feed) move, and the per-point wrench of a
CSV if it gives one.  CSV columns: ``x,y,z[,rx,ry,rz][,Fx,Fy,Fz,Mx,My,Mz]``
(header required; ``#`` lines are comments); a row's line number is its
line in the file.
"""
from __future__ import annotations

import csv
import io
import os
from dataclasses import dataclass

import numpy as np

from ..errors import VjmError
from . import gcode as gc

POSE = ("x", "y", "z")
ROT = ("rx", "ry", "rz")
WRENCH = ("Fx", "Fy", "Fz", "Mx", "My", "Mz")


@dataclass(frozen=True, eq=False)
class Toolpath:
    """Programmed TCP poses along a path.

    Attributes
    ----------
    poses : (n, 3) points or (n, 6) x, y, z, rx, ry, rz (rotation vector), mm and rad
    lines : (n,) source line number of each point (1-based, as an editor shows it)
    vertex : (n,) bool, the point is one the source writes (a CSV row, a move's end point)
    cutting : (n,) bool, the point is on a feed move (G1/G2/G3; every CSV row)
    wrench : (n, 6) per-point wrench at the TCP from the CSV (N, N mm), or None
    source : file name, for messages
    kind : "csv" or "gcode"
    program : the parsed G-code (:class:`vjm.toolpath.gcode.Program`) or None
    line_index : (n,) index of each point's line in ``program.lines`` (G-code) or its CSV row index
    """

    poses: np.ndarray
    lines: np.ndarray
    vertex: np.ndarray
    cutting: np.ndarray
    wrench: np.ndarray | None
    source: str
    kind: str
    program: gc.Program | None = None
    line_index: np.ndarray | None = None
    header: tuple = ()

    @property
    def n(self) -> int:
        return int(self.poses.shape[0])

    @property
    def has_orientation(self) -> bool:
        return self.poses.shape[1] == 6

    @property
    def points(self) -> np.ndarray:
        return self.poses[:, :3]

    def arc_length(self) -> np.ndarray:
        """(n,) cumulative length along the points, mm."""
        d = np.linalg.norm(np.diff(self.points, axis=0), axis=1)
        return np.concatenate([[0.0], np.cumsum(d)])

    def directions(self) -> np.ndarray:
        """(n, 3) unit feed direction at every point: the chord to the next point (the last keeps its
        predecessor's); zero where the path stands still."""
        d = np.diff(self.points, axis=0)
        d = np.vstack([d, d[-1:]]) if len(d) else np.zeros((1, 3))
        # a point that ends a move takes the incoming direction (the chord it ends)
        inc = np.vstack([d[:1], d[:-1]])
        d = np.where(self.vertex[:, None] & (np.arange(self.n) > 0)[:, None], inc, d)
        nrm = np.linalg.norm(d, axis=1, keepdims=True)
        return np.divide(d, nrm, out=np.zeros_like(d), where=nrm > 0)

    def where(self, i: int) -> str:
        """``"<file> line N"`` of point ``i``."""
        return f"{self.source} line {int(self.lines[i])}"


#: CSV rows formatted per piece when writing (the text of a long file is never held whole)
CSV_ROWS = 65536


def read_csv_text(text: str, source: str = "<csv>") -> Toolpath:
    """A toolpath from CSV text (see the module docstring)."""
    return read_csv_lines(io.StringIO(text), source, text.count("\n") + text.count("\r") + 1)


def _csv_header(rows, source: str):
    """(header line number, column names, the columns read) of the first row that is not a comment."""
    first = next(((k, r) for k, r in rows if r and not r[0].lstrip().startswith("#") and any(c.strip() for c in r)),
                 None)
    if first is None:
        raise VjmError(f"{source}: no header line (x,y,z[,rx,ry,rz][,Fx..Mz])")
    k, r = first
    head = [h.strip() for h in r]
    known = set(POSE + ROT + WRENCH)
    unknown = [h for h in head if h not in known]
    if unknown:
        raise VjmError(f"{source}: line {k}: unknown columns {unknown}; known: x,y,z[,rx,ry,rz][,Fx..Mz]")
    if len(set(head)) != len(head):
        raise VjmError(f"{source}: line {k}: a column appears twice")
    for group, name in ((POSE, "x,y,z"), (ROT, "rx,ry,rz"), (WRENCH, "Fx,Fy,Fz,Mx,My,Mz")):
        got = [c for c in group if c in head]
        if (group is POSE and len(got) != 3) or (0 < len(got) < len(group)):
            raise VjmError(f"{source}: line {k}: columns {name} come all together "
                           f"({'required' if group is POSE else 'or not at all'})")
    cols = list(POSE) + (list(ROT) if "rx" in head else []) + (list(WRENCH) if "Fx" in head else [])
    return head, cols


def read_csv_lines(lines, source: str = "<csv>", max_rows: int | None = None) -> Toolpath:
    """A toolpath from CSV lines (a text file or any iterable of lines), parsed as they come: only the
    numbers are kept, in arrays sized by ``max_rows`` (at least the number of lines; default: the
    lines are counted first, so ``lines`` must then be a list or a seekable file)."""
    if max_rows is None:
        if isinstance(lines, list):
            max_rows = len(lines)
        else:
            max_rows = sum(1 for _ in lines)
            lines.seek(0)
    rows = ((k + 1, r) for k, r in enumerate(csv.reader(lines)))
    head, cols = _csv_header(rows, source)
    idx = [head.index(c) for c in cols]
    A = np.empty((max_rows, len(cols)))
    numbers = np.empty(max_rows, np.int64)
    n, nh = 0, len(head)
    for k, r in rows:
        if len(r) == nh:  # a data row, parsed at once; anything else is looked at below
            try:
                A[n] = [float(r[i]) for i in idx]
                numbers[n] = k
                n += 1
                continue
            except ValueError:
                pass
        if not r or r[0].lstrip().startswith("#") or not any(c.strip() for c in r):
            continue
        if len(r) != nh:
            raise VjmError(f"{source}: line {k}: {len(r)} fields, the header has {nh}")
        raise VjmError(f"{source}: line {k}: a value is not a number: {','.join(r)!r}")
    if n == 0:
        raise VjmError(f"{source}: no data rows after the header")
    A = A[:n]
    bad = ~np.all(np.isfinite(A), axis=1)
    if bad.any():
        raise VjmError(f"{source}: line {numbers[np.argmax(bad)]}: values must be finite numbers")
    npose = 6 if "rx" in head else 3
    return Toolpath(A[:, :npose], numbers[:n], np.ones(n, bool), np.ones(n, bool),
                    A[:, npose:] if "Fx" in head else None, source, "csv", None, np.arange(n), tuple(cols))


def from_gcode(prog: gc.Program, source: str = "<G-code>", chord_tol: float = 1e-3, step: float = 1.0) -> Toolpath:
    """A toolpath sampled from a parsed program (see :func:`vjm.toolpath.gcode.sample`); refused before the
    sampling if its points cannot fit in memory (:func:`path_plan`)."""
    path_plan(gc.sample_count(prog, chord_tol, step))
    pts, li, kind, vertex = gc.sample(prog, chord_tol, step)
    numbers = np.array([prog.lines[i].number for i in li])
    return Toolpath(pts, numbers, vertex, kind != 0, None, source, "gcode", prog, li)


PATH_BYTES = 1e3
"""Memory per toolpath point of ``vjm path`` (nonlinear deflection and compensation, the 3-PUU): the
equilibria run in passes of ``vjm.toolpath.passes.CHUNK`` points, so what grows with the path is its
arrays and results; measured 587 MB peak for a one-million-point CSV (776 MB before the spring bases
were shared between points), and about 320 MB in the forked worker process."""
PATH_SECONDS = 1e-4
"""Seconds per toolpath point of ``vjm path`` on one core (nonlinear deflection and compensation of the
3-PUU with FEA links, the compiled equilibria: ~80 us CPU per point, docs/benchmarks.md)."""
ROBOT_PATH_SECONDS = 1.2e-3
"""Seconds per toolpath point of ``vjm path`` on a serial robot (IK, equilibrium under the weight and the
process wrench, compensation: 1.2 ms a point measured on the UR10, 388,000 points)."""


def path_plan(n: float, seconds_per_point: float | None = None):
    """The :class:`vjm.maps.grid.Plan` of ``vjm path`` over ``n`` points (``seconds_per_point``: default
    :data:`PATH_SECONDS`, a robot's is :data:`ROBOT_PATH_SECONDS`); VjmError if they cannot fit in memory."""
    from ..maps.grid import plan

    return plan("vjm path", n, PATH_BYTES, PATH_SECONDS if seconds_per_point is None else seconds_per_point,
                unit="toolpath points",
                hint="use a larger --step (straight moves) or --chord-tol (arcs)")


GCODE_SUFFIXES = (".nc", ".gcode", ".ngc", ".tap", ".cnc", ".g", ".gc", ".ncc", ".mpf", ".txt")


def read(path, chord_tol: float = 1e-3, step: float = 1.0, passed: str = gc.DEFAULT_PASS) -> Toolpath:
    """Read a toolpath file: ``.csv`` as CSV, the usual G-code suffixes as G-code."""
    from ..resources import data_file

    path = os.fspath(data_file(path, suffixes=(".nc", ".csv")))  # the bundled data/toolpaths/ by name too
    name = os.path.basename(path)
    if not os.path.isfile(path):
        raise VjmError(f"toolpath file not found: {path}")
    suffix = os.path.splitext(name)[1].lower()
    try:
        if suffix == ".csv":  # read as it is parsed; spreadsheets write a byte order mark (utf-8-sig drops it)
            with open(path, encoding="utf-8-sig", newline="") as fh:
                return read_csv_lines(fh, name)
        if suffix in GCODE_SUFFIXES:  # parsed line by line: only the lines' tokens are kept
            with open(path, encoding="utf-8", newline="") as fh:
                prog = gc.parse_lines(fh, passed, name)
    except (OSError, UnicodeDecodeError) as exc:
        raise VjmError(f"cannot read toolpath {path}: {exc}") from None
    if suffix in GCODE_SUFFIXES:
        return from_gcode(prog, name, chord_tol, step)
    raise VjmError(f"toolpath {name}: unknown format {suffix or '(no suffix)'}; use .csv or a G-code suffix "
                   f"({', '.join(GCODE_SUFFIXES)})")


def csv_text(tp: Toolpath, poses: np.ndarray) -> str:
    """The CSV of ``tp`` with its poses replaced (same columns; wrench columns kept)."""
    buf = io.StringIO()
    write_csv(buf, tp, poses)
    return buf.getvalue()


def write_csv(fh, tp: Toolpath, poses: np.ndarray, rows: int | None = None) -> None:
    """Write :func:`csv_text` to the text file ``fh``, ``rows`` (default ``CSV_ROWS``) at a time
    (bounded memory on long paths)."""
    rows = rows or CSV_ROWS
    csv.writer(fh, lineterminator="\n").writerow(tp.header)
    fmt = ["%.6f"] * 3 + ["%.9f"] * (poses.shape[1] - 3) + (["%.12g"] * 6 if tp.wrench is not None else [])
    for a in range(0, tp.n, rows):
        b = min(a + rows, tp.n)
        block = poses[a:b] if tp.wrench is None else np.hstack([poses[a:b], tp.wrench[a:b]])
        fh.write(format_rows(fmt, block))


def format_rows(fmt: list, block: np.ndarray) -> str:
    """CSV lines of the rows of ``block``, column j formatted by ``fmt[j]`` (``%`` formats: the same text
    as the f-string formats of the same spec, made by one formatting of the whole block)."""
    return ((",".join(fmt) + "\n") * len(block)) % tuple(np.asarray(block, dtype=float).ravel().tolist())
