"""Measurement files: reading, validation and writing.

Two kinds of CSV are accepted (header row required, comma separated):

* **deflections** -- columns ``x,y,z,Fx,Fy,Fz,Mx,My,Mz,dx,dy,dz,rx,ry,rz``
  and optional ``sigma_t,sigma_r`` (units: mm, N, N mm, rad).  ``x,y,z`` is the commanded end-effector
  position (mm), ``F``/``M`` the applied wrench at that point (N, N mm),
  ``dx,dy,dz`` the measured displacement (mm) from the nominal rigid unloaded
  position, ``rx,ry,rz`` the measured small rotation (rad).  Rotations (and
  individual translations) may be left blank where they were not measured.
  ``sigma_t``/``sigma_r`` are the standard deviations of one translation /
  rotation component; when absent they are estimated from the residuals.
  Optional ``ox,oy,oz`` (all three or none): the commanded platform orientation
  of a 6-dof platform, a rotation vector in rad (world axes, the convention of
  ``vjm stiffness --at x,y,z,rx,ry,rz`` and ``vjm map --orientation``); blank
  is not allowed.  A machine whose platform only translates refuses them.
  Per-component standard deviations ``sigma_dx,sigma_dy,sigma_dz`` (all three,
  instead of ``sigma_t``) and ``sigma_rx,sigma_ry,sigma_rz`` (instead of
  ``sigma_r``) may be given instead (e.g. a tracker noisier along one axis);
  blank where the component is not measured.
* **stiffness observations** -- columns ``x,y,z,quantity,value`` with
  ``quantity`` one of ``k_tran`` (mm/N) or ``k_rot`` (rad/(N mm)), and optional
  ``sigma_rel`` (relative standard deviation of ``value``).  The text columns
  ``architecture`` (rows for other machines are left out) and ``point`` (a label)
  are kept.

Files as instruments and spreadsheets write them are read as they are: a UTF-8
byte-order mark, ``;`` or tab separators (then ``,`` may be the decimal mark),
header names in any case and with surrounding spaces.  A file that is not
UTF-8 text is refused with that reason.

Every column must mean something: an unknown column (a misspelt ``sigma_t``,
an extra ``temperature``) is refused, naming the closest known name, unless its
name starts with ``meta_`` (metadata carried along as text, never used in the
fit; e.g. ``meta_operator``, ``meta_temperature``).

Exact duplicate rows are refused: a row pasted twice would count as two
independent measurements and shrink every uncertainty by sqrt(2).  Genuine
repeated measurements (same posture and load, different values) are kept and
used as such (pure error); two repeats that happen to read exactly the same are
told apart by a ``meta_`` column (e.g. ``meta_run``).

Every error names the file row (1-based, header is row 1) and column.
"""
from __future__ import annotations

import csv
import io
import math
import os
import re
from dataclasses import dataclass, field

import numpy as np

from linkfea.files.atomic import read_user_file, write_text
from linkfea.mechanics.compliance import TWIST, WRENCH
from linkfea.runtime.checks import did_you_mean

from ..errors import VjmError
from ..resources import data_file

POS = ("x", "y", "z")
#: the commanded platform orientation of a 6-dof platform: a rotation vector, rad (world axes)
ORIENT = ("ox", "oy", "oz")
SIGMA = ("sigma_t", "sigma_r")
#: per-component standard deviations, in twist order (mm, rad)
SIGMA6 = tuple(f"sigma_{c}" for c in TWIST)
STIFF = ("x", "y", "z", "quantity", "value")
QUANTITIES = ("k_tran", "k_rot")


@dataclass(frozen=True)
class Deflections:
    """Measured deflections under applied wrenches.

    Attributes
    ----------
    P : (n, 3) commanded positions, mm; (n, 6) positions and orientations (``ox,oy,oz``: a
        rotation vector, rad) when the file gives the platform's orientation.
    W : (n, 6) applied wrenches, N and N mm.
    T : (n, 6) measured twists, mm and rad; NaN where not measured.
    sigma_t, sigma_r : (n,) standard deviations, or None when absent from the file.
    sigma : (n, 6) per-component standard deviations (columns ``sigma_dx..sigma_rz``), NaN where the
        file states none for that component; None without such columns.
    rows : (n,) 1-based row numbers in the source file (header = row 1).
    source : file name, for messages.
    """

    P: np.ndarray
    W: np.ndarray
    T: np.ndarray
    sigma_t: np.ndarray | None = None
    sigma_r: np.ndarray | None = None
    rows: np.ndarray | None = None
    source: str = "<memory>"
    #: ``meta_`` columns of the file, name -> list of str (carried along, not used)
    meta: dict = field(default_factory=dict)
    sigma: np.ndarray | None = None

    @property
    def n(self) -> int:
        return self.P.shape[0]

    def stated_sigmas(self) -> np.ndarray:
        """(n, 6) standard deviation the file states for each component (``sigma_t``/``sigma_r`` or
        ``sigma_dx..sigma_rz``), NaN where it states none."""
        out = np.full((self.n, 6), np.nan)
        if self.sigma_t is not None:
            out[:, :3] = self.sigma_t[:, None]
        if self.sigma_r is not None:
            out[:, 3:] = self.sigma_r[:, None]
        if self.sigma is not None:
            out = np.where(np.isfinite(self.sigma), self.sigma, out)
        return out

    @property
    def mask(self) -> np.ndarray:
        """(n, 6) bool: which twist components were measured."""
        return np.isfinite(self.T)

    @property
    def has_orientation(self) -> bool:
        """The rows give the platform's orientation (columns ``ox,oy,oz``)."""
        return self.P.shape[1] == 6


@dataclass(frozen=True)
class StiffnessObs:
    """Per-posture stiffness observations (e.g. the seed's Table 1).

    Attributes
    ----------
    P : (n, 3) positions, mm.
    quantity : (n,) int, 0 for ``k_tran`` (mm/N), 1 for ``k_rot`` (rad/(N mm)).
    value : (n,) observed values (> 0).
    sigma_rel : (n,) relative standard deviations or None.
    extra : other text columns, name -> list of str.
    """

    P: np.ndarray
    quantity: np.ndarray
    value: np.ndarray
    sigma_rel: np.ndarray | None = None
    rows: np.ndarray | None = None
    source: str = "<memory>"
    extra: dict = field(default_factory=dict)

    @property
    def n(self) -> int:
        return self.P.shape[0]


def _err(source, row, col, msg):
    where = f"{os.path.basename(str(source))}: row {row}"
    if col is not None:
        where += f", column '{col}'"
    return VjmError(f"{where}: {msg}")


def _float(text, source, row, col, required):
    t = (text or "").strip()
    if t == "":
        if required:
            raise _err(source, row, col, "value is missing (required column)")
        return math.nan
    try:
        v = float(t)
    except ValueError:
        raise _err(source, row, col, f"'{t}' is not a number") from None
    if required and not math.isfinite(v):
        raise _err(source, row, col, f"value is {t} (required column must be a finite number)")
    if not required and math.isinf(v):
        raise _err(source, row, col, f"value is {t} (must be finite or blank)")
    return v


def _read_text(path) -> str:
    raw = read_user_file(path, "measurement file", error=VjmError)  # a regular file of bounded size only
    name = os.path.basename(str(path))
    if raw.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise VjmError(f"{name}: the file is UTF-16 text; save it as UTF-8 (CSV UTF-8 in a spreadsheet)")
    try:
        return raw.decode("utf-8-sig")  # a byte-order mark (spreadsheets write one) is not part of the header
    except UnicodeDecodeError as exc:
        line = raw[:exc.start].count(b"\n") + 1
        raise VjmError(f"{name}: row {line}: byte 0x{raw[exc.start]:02x} is not UTF-8 text; save the file as "
                       f"UTF-8 (CSV UTF-8 in a spreadsheet)") from None


def _delimiter(text: str) -> str:
    """The separator of the header line: ',' unless ';' or a tab splits it into more fields."""
    for line in text.splitlines():
        if line.strip() and not line.lstrip().startswith("#"):
            counts = {d: line.count(d) for d in (",", ";", "\t")}
            return max(counts, key=lambda d: (counts[d], d == ","))
    return ","


def _read_table(path):
    """Rows ``(row number, fields)`` of a CSV (comments and blank lines skipped), and its separator."""
    path = data_file(path)
    text = _read_text(path)
    delim = _delimiter(text)
    # keep row numbers aligned with the file: comment lines starting with '#' are skipped
    rows = []
    reader = csv.reader(io.StringIO(text), delimiter=delim)
    for i, rec in enumerate(reader, start=1):
        if not rec or all(not c.strip() for c in rec):
            continue
        if rec[0].lstrip().startswith("#"):
            continue
        rows.append((i, [c.strip() for c in rec]))
    if not rows:
        raise VjmError(f"{os.path.basename(str(path))}: file is empty (expected a header row)")
    return rows, delim


#: a number written with a decimal comma (1,5 or -2,5e-3), in a ';' or tab separated file
_DECIMAL_COMMA = re.compile(r"^([+-]?\d*),(\d+(?:[eE][+-]?\d+)?)$")
#: every column name a measurement file may hold (matched whatever its case), and the metadata prefix
KNOWN = POS + ORIENT + WRENCH + TWIST + SIGMA + SIGMA6 + ("quantity", "value", "sigma_rel", "architecture", "point")
META = "meta_"


def _header(path, hdr_row, header):
    """Header names in their canonical case (``FX`` -> ``Fx``); ``meta_`` columns kept as written."""
    canon = {k.lower(): k for k in KNOWN}
    out = []
    for h in header:
        low = h.lower()
        if low.startswith(META) or low.startswith(QUANTITIES):
            out.append(META + h[len(META):] if low.startswith(META) else low)
        else:
            out.append(canon.get(low, h))
    return out


def _check_columns(path, hdr_row, header, known):
    """Refuse a column that is neither known for this kind of file nor declared metadata (``meta_``)."""
    unknown = [h for h in header if h not in known and not h.startswith(META)]
    if unknown:
        h = unknown[0]
        near = did_you_mean(h, known)
        raise _err(path, hdr_row, h, f"unknown column{near}; known columns: {', '.join(known)}"
                                     + ("" if near else f"; to carry it along unused, name it {META}{h}"))


def read_csv(path) -> Deflections | StiffnessObs:
    """Read a measurement CSV of either kind (see module docstring).

    Raises
    ------
    VjmError
        Naming the row and column of the first problem found.
    """
    rows, delim = _read_table(path)
    hdr_row, header = rows[0]
    header = _header(path, hdr_row, header)
    if len(set(header)) != len(header):
        dup = [h for h in header if header.count(h) > 1][0]
        raise _err(path, hdr_row, dup, "duplicate column name")
    body = rows[1:]
    if delim != ",":  # a ';' or tab separated file may use ',' as its decimal mark
        body = [(r, [_DECIMAL_COMMA.sub(r"\1.\2", c) for c in rec]) for r, rec in body]
    if "quantity" in header:
        _check_columns(path, hdr_row, header, STIFF + ("sigma_rel", "architecture", "point"))
        return _parse_stiffness(path, header, hdr_row, body)
    wide = [h for h in header if h.startswith(QUANTITIES)]
    if wide and not any(c in header for c in WRENCH):
        _check_columns(path, hdr_row, header, POS + tuple(wide) + ("architecture", "point"))
        return _parse_stiffness_wide(path, header, hdr_row, body, wide)
    missing = [c for c in POS + WRENCH + TWIST if c not in header]
    if missing and any(re.match(r"^.+\.[xyz]$", h) for h in header):
        raise _err(path, hdr_row, next(h for h in header if re.match(r"^.+\.[xyz]$", h)),
                   "absolute poses (columns <frame>.x,.y,.z), not deflections: vjm diagnose reads them as such "
                   "(vjm.calibration.poses.read_poses), a robot's joint values or a parallel machine's actuator values "
                   "with the platform's point")
    if missing:
        raise _err(path, hdr_row, missing[0],
                   f"missing column(s) {', '.join(missing)}; expected "
                   f"{','.join(POS + WRENCH + TWIST)} [+ ox,oy,oz] [+ sigma_t,sigma_r or sigma_dx..sigma_rz] "
                   f"or {','.join(STIFF)}" + _dialect_hint(header))
    _check_columns(path, hdr_row, header, POS + ORIENT + WRENCH + TWIST + SIGMA + SIGMA6)
    _check_sigma_columns(path, hdr_row, header)
    orient = _orientation_columns(path, hdr_row, header)
    if not body:
        raise _err(path, hdr_row + 1, None, "no data rows")
    col = {h: i for i, h in enumerate(header)}
    n = len(body)
    pos = POS + orient
    P = np.empty((n, len(pos)))
    W = np.empty((n, 6))
    T = np.empty((n, 6))
    has_sig = {s: s in col for s in SIGMA}
    sig = {s: np.empty(n) for s in SIGMA if has_sig[s]}
    rownums = np.empty(n, dtype=int)
    for k, (r, rec) in enumerate(body):
        if len(rec) != len(header):
            raise _err(path, r, None, f"has {len(rec)} fields, header has {len(header)} (malformed CSV"
                                      f"{'; a decimal comma needs ; as the separator' if delim == ',' else ''})")
        rownums[k] = r
        for j, c in enumerate(pos):
            P[k, j] = _float(rec[col[c]], path, r, c, True)
        for j, c in enumerate(WRENCH):
            W[k, j] = _float(rec[col[c]], path, r, c, True)
        for j, c in enumerate(TWIST):
            T[k, j] = _float(rec[col[c]], path, r, c, False)
        for s in sig:
            v = _float(rec[col[s]], path, r, s, True)
            if v <= 0:
                raise _err(path, r, s, f"standard deviation must be > 0, got {v}")
            sig[s][k] = v
    # a row with nothing measured carries no information: say so rather than silently dropping it
    empty = ~np.isfinite(T).any(axis=1)
    if empty.any():
        raise _err(path, int(rownums[np.argmax(empty)]), "dx", "no measured twist component in this row")
    zero = ~(np.abs(W) > 0).any(axis=1)
    if zero.all():
        raise _err(path, int(rownums[0]), "Fx",
                   "all applied loads are zero in every row: deflections carry no stiffness information")
    meta = {h: [rec[col[h]] for _, rec in body] for h in header if h.startswith(META)}
    sig6 = _per_component_sigmas(path, body, col, T, rownums)
    _refuse_duplicates(path, rownums, [P, W, T] + list(sig.values()) + ([] if sig6 is None else [sig6]), meta)
    return Deflections(P, W, T, sig.get("sigma_t"), sig.get("sigma_r"), rownums, str(path), meta, sig6)


def _check_sigma_columns(path, hdr_row, header) -> None:
    """One way of stating each group's sigmas: ``sigma_t`` or all of ``sigma_dx,sigma_dy,sigma_dz``
    (``sigma_r`` or all of ``sigma_rx..sigma_rz``), never both, never some of the three."""
    for one, three in (("sigma_t", SIGMA6[:3]), ("sigma_r", SIGMA6[3:])):
        given = [c for c in three if c in header]
        if given and one in header:
            raise _err(path, hdr_row, given[0], f"{one} and {given[0]} both given: state the sigmas of "
                                                f"these components one way ({one}, or {', '.join(three)})")
        if given and len(given) < 3:
            missing = [c for c in three if c not in header]
            raise _err(path, hdr_row, given[0], f"{', '.join(given)} without {', '.join(missing)}: give all three "
                                                f"({', '.join(three)}) or {one}")


def _per_component_sigmas(path, body, col, T, rownums) -> np.ndarray | None:
    """(n, 6) ``sigma_dx..sigma_rz`` (NaN where not stated), or None without such columns; a measured
    component needs its sigma, a sigma must be > 0."""
    if not any(c in col for c in SIGMA6):
        return None
    out = np.full(T.shape, np.nan)
    for j, c in enumerate(SIGMA6):
        if c not in col:
            continue
        for k, (r, rec) in enumerate(body):
            v = _float(rec[col[c]], path, r, c, False)
            if np.isnan(v) and np.isfinite(T[k, j]):
                raise _err(path, r, c, f"value is missing: {TWIST[j]} is measured in this row, so its standard "
                                       "deviation is needed")
            if v <= 0:
                raise _err(path, r, c, f"standard deviation must be > 0, got {v}")
            out[k, j] = v
    return out


def _orientation_columns(path, hdr_row, header) -> tuple:
    """``ORIENT`` when the header gives the platform's orientation, () without; a partial set is refused."""
    given = [c for c in ORIENT if c in header]
    if given and len(given) < len(ORIENT):
        missing = [c for c in ORIENT if c not in header]
        raise _err(path, hdr_row, missing[0], f"missing column(s) {', '.join(missing)}: the platform orientation "
                                              f"is a rotation vector {','.join(ORIENT)} (rad), all three or none")
    return ORIENT if given else ()


def _dialect_hint(header) -> str:
    """Why no expected column was found, when the header itself shows it (a lone field holding separators)."""
    if len(header) == 1 and any(d in header[0] for d in ";\t|"):
        return f" (the header is one field, {header[0][:40]!r}: separate columns with , or ;)"
    return ""


def _refuse_duplicates(path, rows, arrays, meta) -> None:
    """Exact duplicate rows (every column equal, blanks included) are an error naming both rows."""
    A = np.hstack([np.asarray(a, float).reshape(len(rows), -1) for a in arrays])
    A = np.where(np.isnan(A), np.inf, A)  # blank == blank
    keys = {}
    for k in range(len(rows)):
        key = (A[k].tobytes(), tuple(v[k] for v in meta.values()))
        if key in keys:
            raise _err(path, int(rows[k]), None,
                       f"repeats row {int(rows[keys[key]])} exactly (every column equal): a row pasted twice would "
                       f"count as two measurements and shrink the uncertainties; delete it, or, for genuine repeated "
                       f"measurements that read the same, tell them apart in a {META} column (e.g. {META}run)")
        keys[key] = k


def _parse_stiffness(path, header, hdr_row, body):
    missing = [c for c in STIFF if c not in header]
    if missing:
        raise _err(path, hdr_row, missing[0], f"missing column(s) {', '.join(missing)}; expected {','.join(STIFF)}")
    if not body:
        raise _err(path, hdr_row + 1, None, "no data rows")
    col = {h: i for i, h in enumerate(header)}
    n = len(body)
    P = np.empty((n, 3))
    q = np.empty(n, dtype=int)
    v = np.empty(n)
    srel = np.empty(n) if "sigma_rel" in col else None
    extra = {h: [] for h in header if h not in STIFF and h != "sigma_rel"}
    rownums = np.empty(n, dtype=int)
    for k, (r, rec) in enumerate(body):
        if len(rec) != len(header):
            raise _err(path, r, None, f"has {len(rec)} fields, header has {len(header)} (malformed CSV)")
        rownums[k] = r
        for j, c in enumerate(POS):
            P[k, j] = _float(rec[col[c]], path, r, c, True)
        name = rec[col["quantity"]]
        if name not in QUANTITIES:
            raise _err(path, r, "quantity", f"'{name}' is not one of {', '.join(QUANTITIES)}")
        q[k] = QUANTITIES.index(name)
        v[k] = _float(rec[col["value"]], path, r, "value", True)
        if v[k] <= 0:
            raise _err(path, r, "value", f"a compliance must be > 0, got {v[k]}")
        if srel is not None:
            srel[k] = _float(rec[col["sigma_rel"]], path, r, "sigma_rel", True)
            if srel[k] <= 0:
                raise _err(path, r, "sigma_rel", f"must be > 0, got {srel[k]}")
        for h in extra:
            extra[h].append(rec[col[h]])
    return StiffnessObs(P, q, v, srel, rownums, str(path), extra)


def _parse_stiffness_wide(path, header, hdr_row, body, wide):
    """Wide stiffness table: one row per posture, columns ``k_tran*`` / ``k_rot*`` (e.g. the
    seed's Table 1 file ``k_tran_mm_per_N, k_rot_rad_per_Nmm``); turned into long form."""
    missing = [c for c in POS if c not in header]
    if missing:
        raise _err(path, hdr_row, missing[0], f"missing column(s) {', '.join(missing)}")
    if not body:
        raise _err(path, hdr_row + 1, None, "no data rows")
    col = {h: i for i, h in enumerate(header)}
    qcols = [(h, 0 if h.startswith("k_tran") else 1) for h in wide]
    P, q, v, rows = [], [], [], []
    extra = {h: [] for h in header if h not in POS and h not in wide}
    for r, rec in body:
        if len(rec) != len(header):
            raise _err(path, r, None, f"has {len(rec)} fields, header has {len(header)} (malformed CSV)")
        p = [_float(rec[col[c]], path, r, c, True) for c in POS]
        for h, qi in qcols:
            val = _float(rec[col[h]], path, r, h, False)
            if not math.isfinite(val):
                continue
            if val <= 0:
                raise _err(path, r, h, f"a compliance must be > 0, got {val}")
            P.append(p)
            q.append(qi)
            v.append(val)
            rows.append(r)
            for e in extra:
                extra[e].append(rec[col[e]])
    if not v:
        raise _err(path, hdr_row + 1, wide[0], "no stiffness value in the file")
    return StiffnessObs(np.array(P), np.array(q, int), np.array(v), None, np.array(rows), str(path), extra)


def write_deflections(path, data: Deflections, header_comment: str | None = None) -> None:
    """Write deflection measurements in the CSV format read by :func:`read_csv`."""
    buf = io.StringIO()
    if header_comment:
        for line in header_comment.splitlines():
            buf.write(f"# {line}\n")
    cols = list(POS + (ORIENT if data.has_orientation else ()) + WRENCH + TWIST)
    if data.sigma_t is not None:
        cols.append("sigma_t")
    if data.sigma_r is not None:
        cols.append("sigma_r")
    groups = [] if data.sigma is None else [g for g in (slice(0, 3), slice(3, 6)) if np.isfinite(data.sigma[:, g]).any()]
    for g in groups:
        cols += list(SIGMA6[g])
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(cols)

    def fmt(v):
        return "" if not np.isfinite(v) else repr(float(v))

    for k in range(data.n):
        rec = [fmt(v) for v in data.P[k]] + [fmt(v) for v in data.W[k]] + [fmt(v) for v in data.T[k]]
        if data.sigma_t is not None:
            rec.append(fmt(data.sigma_t[k]))
        if data.sigma_r is not None:
            rec.append(fmt(data.sigma_r[k]))
        for g in groups:
            rec += [fmt(v) for v in data.sigma[k, g]]
        w.writerow(rec)
    write_text(path, buf.getvalue())


def write_design(path, rows, header_comment: str | None = None) -> None:
    """Write (posture, load) rows ``x,y,z,Fx,Fy,Fz,Mx,My,Mz`` (no measured values): the measurement plan
    ``vjm diagnose --suggest`` proposes, read back by ``vjm simulate --poses FILE --loads FILE``.
    Rows of 12 values (a 6-dof platform) are ``x,y,z,ox,oy,oz,Fx..Mz``."""
    buf = io.StringIO()
    if header_comment:
        for line in header_comment.splitlines():
            buf.write(f"# {line}\n")
    w = csv.writer(buf, lineterminator="\n")
    rows = np.asarray(rows, float)
    w.writerow(list(POS + (ORIENT if rows.ndim == 2 and rows.shape[1] == 12 else ()) + WRENCH))
    for r in rows:
        w.writerow([repr(float(v) + 0.0) for v in r])  # + 0.0: no "-0.0" in the file
    write_text(path, buf.getvalue())
