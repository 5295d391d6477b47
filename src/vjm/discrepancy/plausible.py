"""Checks of a data set against its model before any fit: reachable postures, units, workspace.

* **Units.**  The least-squares scale ``s`` of the nominal model's predictions
  that fits the measured deflections (or the median ratio of observed to
  predicted compliances) is what a calibration would have to absorb.  The
  effects of the library change a compliance by a few times at most (a link
  mode by up to 20 x in one direction, the calibration by 0.5-2 x); a scale
  beyond :data:`UNITS_FACTOR` either way is no physical effect but a unit (µm
  or m for mm, mrad or degrees for rad, kN for N).  The diagnosis is refused
  with that hint: no report and no updated model are written.
* **Workspace.**  A posture the kinematics reach but outside the model's
  workspace box is kept and reported as a warning: often a coordinate in the
  wrong frame or unit.
"""
from __future__ import annotations

import os

import numpy as np

from ..effects import modelops as mo
from ..effects.context import unique_postures
from ..errors import VjmError
from .data import StiffnessObs

#: a measured/predicted scale beyond this factor (or below its inverse) is taken for a units error
UNITS_FACTOR = 30.0


def check_orientation(model, data) -> None:
    """Orientation columns (``ox,oy,oz``) on a machine whose platform only translates: VjmError naming them."""
    if data.P.shape[1] == 6 and model.dof != 6:
        raise VjmError(f"{os.path.basename(str(data.source))}: column 'ox': the file gives platform orientations "
                       f"(ox,oy,oz) but the machine's platform only translates (3 dof); drop the columns ox,oy,oz")


def _pose_text(p) -> str:
    text = f"posture ({p[0]:g}, {p[1]:g}, {p[2]:g}) mm"
    return text + (f" at orientation ({p[3]:g}, {p[4]:g}, {p[5]:g}) rad" if len(p) == 6 else "")


def check_reachable(model, data):
    """Unique postures (positions, or positions and orientations), index; raises naming the first
    unreachable row (and orientation columns a 3-dof machine cannot take)."""
    check_orientation(model, data)
    U, idx = unique_postures(data.P)
    try:
        q = mo.actuator_coords(model, U)
    except VjmError:
        q = None
    if q is None or not np.all(np.isfinite(q)):
        for k in range(data.n):
            try:
                qq = mo.actuator_coords(model, data.P[k:k + 1])
                if not np.all(np.isfinite(qq)):
                    raise VjmError("no finite inverse kinematics")
            except VjmError as exc:
                row = int(data.rows[k]) if data.rows is not None else k + 2
                why = str(exc) if "unreachable" in str(exc) else (  # the kinematics' message names the pose
                    f"{_pose_text(data.P[k])} is unreachable: {exc}")
                cols = "x,y,z,ox,oy,oz" if data.P.shape[1] == 6 else "x,y,z"
                raise VjmError(f"{os.path.basename(data.source)}: row {row}, columns '{cols}': {why}") from None
        raise VjmError(f"{os.path.basename(data.source)}: a posture is unreachable")
    return U, idx, q


def _scale(T, T0):
    """Least-squares s in T ~ s T0 over the finite entries, and its standard error; None if T0 is ~0."""
    ok = np.isfinite(T) & np.isfinite(T0)
    t, t0 = T[ok], T0[ok]
    den = float(t0 @ t0)
    if t.size < 2 or den <= 0:
        return None
    s = float(t @ t0) / den
    r = t - s * t0
    se = float(np.sqrt(r @ r / max(t.size - 1, 1) / den))
    return s, se


def check_units(model, data, U, idx) -> None:
    """VjmError with a units hint when the data are a factor beyond :data:`UNITS_FACTOR` from the model."""
    name = os.path.basename(str(data.source))
    if isinstance(data, StiffnessObs):
        res = [model.stiffness(u) for u in U]
        pred = np.array([res[i].k_tran if q == 0 else res[i].k_rot for i, q in zip(idx, data.quantity)])
        ok = np.isfinite(pred) & (pred > 0)
        if not ok.any():
            return
        ratio = float(np.exp(np.median(np.log(data.value[ok] / pred[ok]))))
        if not (1 / UNITS_FACTOR <= ratio <= UNITS_FACTOR):
            raise VjmError(f"{name}: column 'value': the observed compliances are {ratio:.3g} x the model's "
                           f"(median), far beyond any physical effect: check the units (k_tran in mm/N, k_rot in "
                           f"rad/(N mm) expected); nothing was fitted or written")
        return
    C = mo.compliance_map(model, U)[idx]
    T0 = np.einsum("nij,nj->ni", C, data.W)
    for cols, what, units in ((slice(0, 3), "translations dx,dy,dz", "mm"),
                              (slice(3, 6), "rotations rx,ry,rz", "rad")):
        fit = _scale(data.T[:, cols], T0[:, cols])
        if fit is None:
            continue
        s, se = fit
        far = s > UNITS_FACTOR or (abs(s) + 3 * se < 1 / UNITS_FACTOR and abs(s) < 1 / UNITS_FACTOR)
        if far:
            raise VjmError(f"{name}: columns {what.split()[1]}: the measured {what.split()[0]} are {s:.3g} x the "
                           f"model's (least-squares scale), far beyond any physical effect: check the units "
                           f"({units} for {what.split()[0]}, N and N mm for the loads, mm for x,y,z expected); "
                           f"nothing was fitted or written")


def workspace_flags(model, data) -> list[str]:
    """Warnings for rows whose posture is reachable but outside the model's workspace box."""
    lo, hi = mo.workspace_box(model)
    pos = data.P[:, :3]
    out = np.any((pos < lo - 1e-9) | (pos > hi + 1e-9), axis=1)
    if not out.any():
        return []
    rows = (np.asarray(data.rows) if data.rows is not None else np.arange(data.n) + 2)[out]
    p = data.P[np.argmax(out)]
    more = f" and {len(rows) - 1} more" if len(rows) > 1 else ""
    return [f"{os.path.basename(str(data.source))}: row {int(rows[0])}{more}: posture ({p[0]:g}, {p[1]:g}, {p[2]:g}) "
            f"mm is outside the model's workspace box {np.round(lo, 3).tolist()}..{np.round(hi, 3).tolist()} mm, "
            f"though reachable: check the coordinates (mm, model frame)"]
