"""Absolute-pose data sets: one row per configuration, read from a file as it is through a column map.

A calibration file holds, per row, the joint values and the positions (and perhaps orientations) of
points on the robot measured by an instrument (laser tracker, camera) in its own frame.  vjm's names:

- a column per joint, named by the model's joint name (rad; mm for a prismatic joint);
- ``<frame>.x``, ``<frame>.y``, ``<frame>.z``: a measured point (mm, instrument frame), ``<frame>`` a
  frame or link of the model (several points per row are allowed);
- optional: ``<frame>.rx/.ry/.rz`` (rotation vector, rad), ``<frame>.sigma`` (one position sigma, mm)
  or ``<frame>.sigma_x/_y/_z``, ``group`` (a registration group: an instrument set-up), ``meta_*``.

Real files use their own names, units, separators and decimal marks.  A **column map** (a small YAML)
says how to read one without editing it::

    separator: ";"                # default ","
    decimal: ","                  # default "."
    rotation: euler_XYZ           # how <frame>.rx/ry/rz are given: rotvec (default), or scipy Euler axes
    columns:                      # vjm name: [the file's column, its unit]  (units: m mm rad deg, or none)
      shoulder_pan_joint: [shoulder_pan_joint, rad]
      tool0.x: [measurement_x, mm]
      tool0.rx: [measurement_rx, deg]
      meta_temperature: measurement_temperature
    if_present:                   # the same, for columns some files of the family lack
      tool0.sigma_x: [measurement_std_x, mm]

A file read without a map must already use vjm's names (``,`` separated, mm and rad).
"""
from __future__ import annotations

import contextlib
import csv
import io
import re
from dataclasses import dataclass, field, replace

import numpy as np

from ..errors import VjmError

#: unit name -> (quantity, factor to vjm's unit)
UNITS = {"mm": ("length", 1.0), "m": ("length", 1000.0), "rad": ("angle", 1.0), "deg": ("angle", np.pi / 180),
         "": ("any", 1.0)}
_POINT = re.compile(r"^(?P<frame>.+)\.(?P<c>x|y|z|rx|ry|rz|sigma|sigma_x|sigma_y|sigma_z)$")
#: a measured point farther than this from the instrument (mm) is in other units or corrupt: 1 km
POINT_MAX_MM = 1e6
#: a position sigma below this (mm) no instrument gives: a nanometre
SIGMA_MIN_MM = 1e-6
#: fewer distinct configurations than this calibrate nothing (an instrument frame alone has 6 parameters)
MIN_DISTINCT = 3


@dataclass(frozen=True)
class ColumnMap:
    """How a file's columns become vjm's names: {vjm name: (column, unit)} (see the module docstring)."""

    columns: dict
    optional: dict = field(default_factory=dict)
    separator: str = ","
    decimal: str = "."
    rotation: str = "rotvec"
    source: str = "column map"


@dataclass(frozen=True, eq=False)
class AbsolutePoses:
    """Absolute measurements: joint values ``q`` (n, len(joints)) and per measured frame its points
    (n, 3) mm in the instrument frame, optional rotation vectors (n, 3) rad and position sigmas (n, 3) mm;
    ``group`` (n,) the registration group of each row; ``meta`` {name: (n,) values}."""

    joints: tuple
    q: np.ndarray
    points: dict
    rotations: dict = field(default_factory=dict)
    sigmas: dict = field(default_factory=dict)
    group: np.ndarray | None = None
    meta: dict = field(default_factory=dict)
    source: str = ""
    units: dict = field(default_factory=dict)  # vjm name -> the unit the column map gave ("" unsaid)

    @property
    def n(self) -> int:
        return len(self.q)

    @property
    def groups(self) -> np.ndarray:
        return np.full(self.n, "", dtype=object) if self.group is None else self.group

    def q_for(self, names) -> np.ndarray:
        """Joint values (n, len(names)) in the order of ``names`` (a model's ``q_names``)."""
        missing = [m for m in names if m not in self.joints]
        if missing:
            raise VjmError(f"{self.source}: no column for joint(s) {', '.join(missing)}; the data's joints: "
                           f"{', '.join(self.joints) or 'none'}")
        return self.q[:, [self.joints.index(m) for m in names]]

    def subset(self, rows) -> AbsolutePoses:
        """The rows ``rows`` (indices or a boolean mask)."""
        r = np.asarray(rows)
        pick = (lambda d: {k: v[r] for k, v in d.items()})  # noqa: E731
        return replace(self, q=self.q[r], points=pick(self.points), rotations=pick(self.rotations),
                       sigmas=pick(self.sigmas), group=None if self.group is None else self.group[r],
                       meta=pick(self.meta))

    def with_group(self, name: str) -> AbsolutePoses:
        """The same rows, all in registration group ``name``."""
        return replace(self, group=np.full(self.n, str(name), dtype=object))


def _entry(key: str, v, where: str) -> tuple[str, str]:
    if isinstance(v, str):
        return v, ""
    if isinstance(v, (list, tuple)) and len(v) in (1, 2) and all(isinstance(x, str) for x in v):
        return v[0], (v[1] if len(v) == 2 else "")
    raise VjmError(f"{where}: columns.{key}: give the file's column name, or [column, unit]; got {v!r}")


def _entries(d, key: str, where: str) -> dict:
    if d is None:
        return {}
    if not isinstance(d, dict):
        raise VjmError(f"{where}: {key}: must be a mapping of vjm name -> [column, unit]")
    out = {}
    for k, v in d.items():
        col, unit = _entry(str(k), v, where)
        if unit not in UNITS:
            raise VjmError(f"{where}: {key}.{k}: unknown unit {unit!r}; units: {', '.join(u for u in UNITS if u)}")
        out[str(k)] = (col, unit)
    return out


def column_map_from_dict(d, where: str = "column map") -> ColumnMap:
    """A :class:`ColumnMap` from the YAML's mapping (VjmError naming the key on a bad one)."""
    if not isinstance(d, dict):
        raise VjmError(f"{where}: a column map is a mapping with 'columns:'")
    unknown = set(d) - {"separator", "decimal", "rotation", "columns", "if_present"}
    if unknown:
        raise VjmError(f"{where}: unknown key(s) {', '.join(sorted(map(str, unknown)))}; keys: separator, decimal, "
                       f"rotation, columns, if_present")
    sep, dec = str(d.get("separator", ",")), str(d.get("decimal", "."))
    if len(sep) != 1 or dec not in (".", ","):
        raise VjmError(f"{where}: separator must be one character and decimal '.' or ','; got {sep!r}, {dec!r}")
    if sep == dec:
        raise VjmError(f"{where}: the separator and the decimal mark are both {sep!r}")
    rot = str(d.get("rotation", "rotvec"))
    axes = rot[6:].upper()
    if rot != "rotvec" and (not re.fullmatch(r"euler_([xyz]{3}|[XYZ]{3})", rot) or axes[0] == axes[1]
                            or axes[1] == axes[2]):
        raise VjmError(f"{where}: rotation must be rotvec or euler_<axes>, three axes with no two consecutive ones "
                       f"the same (e.g. euler_XYZ intrinsic, euler_xyz extrinsic, euler_ZYZ); got {rot!r}")
    cols = _entries(d.get("columns"), "columns", where)
    if not cols:
        raise VjmError(f"{where}: columns: is empty")
    return ColumnMap(cols, _entries(d.get("if_present"), "if_present", where), sep, dec, rot, where)


def read_column_map(path) -> ColumnMap:
    """Read a column map YAML file."""
    from linkfea.files.atomic import read_user_file

    from ..modelio.yamldata import read_yaml

    read_user_file(path, "column map", error=VjmError)  # a regular file of bounded size only (not a pipe)
    return column_map_from_dict(read_yaml(path, "column map"), str(path))


def _number(text: str, dec: str, where: str) -> float:
    t = text.strip()
    if dec == ",":
        t = t.replace(",", ".")
    try:
        return float(t)
    except ValueError:
        raise VjmError(f"{where}: {text!r} is not a number") from None


def _numbers_or_text(text: np.ndarray, dec: str, factor: float) -> np.ndarray:
    """A meta column as numbers (in vjm's units) if every entry is one, else as it is written."""
    try:
        return np.array([_number(t, dec, "") for t in text]) * factor
    except VjmError:
        return text


def _table(path, sep: str) -> tuple[list, list]:
    from linkfea.files.atomic import read_user_file

    raw = read_user_file(path, "absolute-pose file", error=VjmError)  # a regular file of bounded size only
    try:
        f = io.StringIO(raw.decode("utf-8-sig"), newline="")
        rows = [r for r in csv.reader(f, delimiter=sep) if any(c.strip() for c in r)]
        while rows and rows[0][0].startswith("#"):  # comment lines above the header (vjm simulate's mark)
            rows.pop(0)
    except OSError as e:
        raise VjmError(f"{path}: cannot read ({e.strerror})") from None
    except UnicodeDecodeError:
        raise VjmError(f"{path}: not a text file (UTF-8)") from None
    if len(rows) < 2:
        raise VjmError(f"{path}: no data rows under the header")
    header = [undefused(c.strip()) for c in rows[0]]
    seen: dict = {}
    for i, h in enumerate(header):
        if h and h in seen:
            raise VjmError(f"{path}: column {h!r} appears twice in the header (columns {seen[h] + 1} and {i + 1}); "
                           f"which one holds the data is not said: rename or remove one")
        seen[h] = i
    return header, rows[1:]


def _identity_map(header: list) -> ColumnMap:
    cols = {h: (h, "") for h in header}
    return ColumnMap(cols, source="vjm's own column names")


def _unit_check(name: str, unit: str, where: str) -> None:
    m = _POINT.match(name)
    want = None
    if m:
        want = "angle" if m["c"] in ("rx", "ry", "rz") else "length"
    if want and UNITS[unit][0] not in (want, "any"):
        raise VjmError(f"{where}: {name}: unit {unit!r} is not a {want}")


def _values(header, rows, cmap: ColumnMap, path) -> dict:
    """{vjm name: (n,) values converted to vjm's units (meta and group kept as text where not numbers)}."""
    out = {}
    width = len(header)
    for i, r in enumerate(rows):
        if len(r) != width:
            raise VjmError(f"{path}: row {i + 2} has {len(r)} fields, the header {width} (separator "
                           f"{cmap.separator!r})")
    for optional, d in ((False, cmap.columns), (True, cmap.optional)):
        for name, (col, unit) in d.items():
            if col not in header:
                if optional:
                    continue
                raise VjmError(f"{path}: no column {col!r} (for {name}); its columns: {', '.join(header)}")
            _unit_check(name, unit, cmap.source)
            j = header.index(col)
            f = UNITS[unit][1]
            if name == "group" or name.startswith("meta_"):
                text = np.array([r[j].strip() for r in rows], dtype=object)
                out[name] = _numbers_or_text(text, cmap.decimal, f) if name != "group" else text
                continue
            out[name] = np.array([_number(r[j], cmap.decimal, f"{path}: row {i + 2}, column {col!r}")
                                  for i, r in enumerate(rows)]) * f
    return out


def _rotvecs(vals: dict, frame: str, cmap: ColumnMap, path) -> np.ndarray | None:
    keys = [f"{frame}.r{c}" for c in "xyz"]
    have = [k in vals for k in keys]
    if not any(have):
        return None
    if not all(have):
        raise VjmError(f"{path}: {frame}: give all of .rx .ry .rz or none")
    a = np.column_stack([vals[k] for k in keys])
    if cmap.rotation == "rotvec":
        return a
    from scipy.spatial.transform import Rotation

    return Rotation.from_euler(cmap.rotation[6:], a).as_rotvec()


def _sigmas(vals: dict, frame: str, path) -> np.ndarray | None:
    keys = [f"{frame}.sigma_{c}" for c in "xyz"]
    if f"{frame}.sigma" in vals:
        s = np.repeat(vals[f"{frame}.sigma"][:, None], 3, axis=1)
    elif any(k in vals for k in keys):
        if not all(k in vals for k in keys):
            raise VjmError(f"{path}: {frame}: give all of .sigma_x .sigma_y .sigma_z, or .sigma")
        s = np.column_stack([vals[k] for k in keys])
    else:
        return None
    if not np.all(s >= SIGMA_MIN_MM):
        low = float(np.min(s))
        raise VjmError(f"{path}: {frame}: sigmas must be at least {SIGMA_MIN_MM:g} mm (a nanometre; no instrument "
                       f"measures a robot better), got {low:.3g}")
    return s


def read_poses(path, cmap: ColumnMap | None = None, joints=None, group: str | None = None) -> AbsolutePoses:
    """Read an absolute-pose file (with a column map, or in vjm's own names).

    ``joints``: the model's joint names (their columns are required; default: every column that is no
    point, sigma, group or meta column).  ``group``: one registration group for every row (overrides a
    ``group`` column)."""
    header, rows = _table(path, cmap.separator if cmap else ",")
    cmap = cmap or _identity_map(header)
    vals = _values(header, rows, cmap, path)
    frames = sorted({m["frame"] for k in vals if (m := _POINT.match(k))})
    points = {}
    for fr in frames:
        keys = [f"{fr}.{c}" for c in "xyz"]
        if not all(k in vals for k in keys):
            raise VjmError(f"{path}: point {fr!r}: give all of {', '.join(keys)}")
        points[fr] = np.column_stack([vals[k] for k in keys])
    if not points:
        raise VjmError(f"{path}: no measured point (columns <frame>.x, <frame>.y, <frame>.z)")
    names = [k for k in vals if not _POINT.match(k) and k != "group" and not k.startswith("meta_")]
    if joints is not None:
        missing = [j for j in joints if j not in names]
        if missing:
            raise VjmError(f"{path}: no column for joint(s) {', '.join(missing)} (map them in the column map)")
        names = list(joints)
    q = np.column_stack([vals[k] for k in names]) if names else np.zeros((len(rows), 0))
    rots = {fr: r for fr in frames if (r := _rotvecs(vals, fr, cmap, path)) is not None}
    sig = {fr: s for fr in frames if (s := _sigmas(vals, fr, path)) is not None}
    g = vals.get("group")
    if group is not None:
        g = np.full(len(rows), str(group), dtype=object)
    meta = {k: v for k, v in vals.items() if k.startswith("meta_")}
    bad = ~np.all(np.isfinite(np.column_stack([q] + list(points.values()))), axis=1)
    if np.any(bad):
        raise VjmError(f"{path}: row {int(np.argmax(bad)) + 2}: joint values and points must be finite")
    _check_points(points, path)
    units = {k: cmap.columns.get(k, cmap.optional.get(k, ("", "")))[1] for k in vals}
    return AbsolutePoses(tuple(names), q, points, rots, sig, g, meta, str(path), units)


def _check_points(points: dict, path) -> None:
    """Points beyond :data:`POINT_MAX_MM` refused."""
    for fr, p in points.items():
        far = np.max(np.abs(p), axis=1)
        if np.any(far > POINT_MAX_MM):
            i = int(np.argmax(far > POINT_MAX_MM))
            raise VjmError(f"{path}: row {i + 2}: point {fr!r} is {far[i]:.3g} mm from the instrument, beyond "
                           f"{POINT_MAX_MM:g} mm (1 km): points are in mm (map the columns' unit in a column map)")


def undefused(name: str) -> str:
    """A header cell as vjm wrote it, its spreadsheet defusing undone: ``'=x`` -> ``=x`` (see
    :func:`vjm.modelio.csvtext.cell`)."""
    return name[1:] if len(name) > 1 and name[0] == "'" and name[1] in "=+-@" else name


#: the measured points' spread over the model's predicted spread, beyond which one of the two is in other units
SCALE_FACTOR = 10.0


def check_distinct(data: AbsolutePoses) -> None:
    """Refuse fitted data of fewer than :data:`MIN_DISTINCT` distinct configurations (one row copied 60 times
    calibrates nothing, yet fits every effect to nothing)."""
    distinct = len(np.unique(data.q, axis=0)) if data.q.shape[1] else len(
        np.unique(np.column_stack(list(data.points.values())), axis=0))
    if distinct < MIN_DISTINCT:
        raise VjmError(f"{data.source}: the data hold {distinct} distinct pose{'s' if distinct != 1 else ''} "
                       f"({data.n} rows); a calibration needs at least {MIN_DISTINCT} poses spread over the workspace")


def check_against(model, data: AbsolutePoses, frames) -> None:
    """Refuse data whose units the robot contradicts, before any fit (VjmError, one line; a case legitimate
    data could look like warns once instead): a rotational joint's column mapped in a length unit (or a
    prismatic one in an angle unit); a rotational joint's values beyond 2 pi, or any joint's beyond its
    limits by a factor (:func:`vjm.robot.model.unit_slip`: degrees or metres read as radians or millimetres); measured points whose
    spread is not that of the model's frames at the data's configurations within :data:`SCALE_FACTOR`
    (points in metres, or a model in other units)."""
    import warnings

    from ..errors import VjmWarning
    from ..robot.model import unit_slip

    names = tuple(model.q_names)
    kinds = {j.name: j.type for j in model.tree.joints}
    q = data.q_for(names)
    lo, hi = model.tree.limits
    for name in names:
        rot = kinds[name] != "prismatic"
        unit = data.units.get(name, "")
        if unit and UNITS[unit][0] != ("angle" if rot else "length"):
            raise VjmError(f"{data.source}: joint {name} is {kinds[name]} ({'rad' if rot else 'mm'}), but its column "
                           f"is mapped in {unit}: map it as [column, {'rad' if rot else 'mm'}] (or "
                           f"{'deg' if rot else 'm'})")
    slip = unit_slip(model.tree, q)
    if slip is not None:
        msg = f"{data.source}: joint {slip[1]} Give the column's unit in a column map ([column, deg], [column, m])"
        if slip[2]:
            raise VjmError(msg)
        warnings.warn(msg + " (a continuous joint may turn more: then ignore this)", VjmWarning, stacklevel=2)
    deg = _deg_hint(data, names, kinds, q)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for fr in frames:
            _check_scale(data.points[fr], model.forward(q, fr)[:, :3, 3], fr, data.source, deg)
    if deg:
        warnings.warn(f"{data.source}: {deg}", VjmWarning, stacklevel=2)


@contextlib.contextmanager
def quiet_limits():
    """The joint-limit warnings of a model's evaluations silenced (a fit evaluates the rows once per fold and
    stage: :func:`warn_limits` says it once instead)."""
    import warnings

    from ..errors import VjmWarning

    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", r".* is outside its limits ", VjmWarning)
        yield


def warn_limits(model, data: AbsolutePoses) -> None:
    """One warning for the rows outside the joint limits (the fit's many evaluations say nothing more)."""
    import warnings

    from ..errors import VjmWarning

    names = tuple(model.q_names)
    q = data.q_for(names)
    lo, hi = model.tree.limits
    out = (q < lo - 1e-12) | (q > hi + 1e-12)
    if np.any(out):
        i, j = np.argwhere(out)[0]
        warnings.warn(f"{data.source}: {int(out.any(axis=1).sum())} of {len(q)} rows outside the joint limits "
                      f"(row {i + 2}: {names[j]} = {q[i, j]:g}, limits [{lo[j]:g}, {hi[j]:g}])", VjmWarning,
                      stacklevel=3)


def _deg_hint(data: AbsolutePoses, names, kinds, q: np.ndarray) -> str:
    """Radians mapped as degrees: every rotational column mapped ``deg`` within 2 pi before the conversion."""
    deg = [j for j, n in enumerate(names) if kinds[n] != "prismatic" and data.units.get(n) == "deg"]
    if deg and float(np.max(np.abs(q[:, deg]))) * 180 / np.pi <= 2 * np.pi:
        return (f"the joint columns mapped in deg all lie within +-{2 * np.pi:.3g} before the conversion: radians "
                f"mapped as deg? (map them as [column, rad])")
    return ""


def spread(p: np.ndarray) -> float:
    """RMS distance (mm) of points (n, 3) from their centroid: a size that no rigid move of the frame changes."""
    return float(np.sqrt(np.mean(np.sum((p - p.mean(axis=0)) ** 2, axis=1))))


def _check_scale(measured: np.ndarray, predicted: np.ndarray, frame: str, source: str, deg: str) -> None:
    s_data, s_model = spread(measured), spread(predicted)
    if s_model < 1.0 or s_data == 0.0:  # a point the joints hardly move: no scale to compare
        return
    r = s_data / s_model
    if 1 / SCALE_FACTOR <= r <= SCALE_FACTOR:
        return
    if 1e-3 / 3 <= r <= 3e-3:
        hint = "points in metres (map their columns as [column, m]), or a model in millimetres"
    elif 1e3 / 3 <= r <= 3e3:
        hint = "points in microns, or a model in metres"
    else:
        hint = deg or "check the units of the points, of the joints and of the model"
    raise VjmError(f"{source}: the measured points of {frame} spread over {s_data:.3g} mm, the model's {frame} at "
                   f"the same joint values over {s_model:.3g} mm (a factor {r:.3g}): {hint}")
