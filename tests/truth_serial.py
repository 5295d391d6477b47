"""Independent truth for absolute-pose calibration of serial arms: pinocchio, no vjm code.

A serial arm read by pinocchio from its URDF carries hidden effects:
- joint offsets (added to the commanded joint values);
- URDF-origin errors (each joint's placement times a small rigid motion);
- a payload (a point mass at the marker);
- joint compliance under self-weight and backlash: the link angles ``theta`` solve
  ``theta = q + offset - c g(theta) - b sign(g(theta))`` with pinocchio's generalized gravity ``g`` of the
  *perturbed* arm (fixed point, to 1e-14 rad; the clearance taken up on the side gravity pushes to);
- a base tilt: the gravity turned about the base's x and y axes;
- joint couplings: a joint turning by k times another's commanded value (what the data call a joint is a
  combination of two);
- an unknown instrument frame (R, t) and a marker offset on the measured frame;
- noise (iid, mm).
It returns what a laser tracker would log: the commanded q (rad) and the marker's position in the
instrument frame (mm).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

GRAVITY = (0.0, 0.0, -9.80665)


@dataclass(frozen=True)
class Hidden:
    """The hidden truth: offsets {joint: rad}, origin errors {joint: (dx, dy, dz mm, rx, ry, rz rad)},
    compliances {joint: rad/(N m)}, instrument frame (R, t mm), marker (mm in the frame), noise sigma (mm)."""

    offsets: dict = field(default_factory=dict)
    origins: dict = field(default_factory=dict)
    compliance: dict = field(default_factory=dict)
    R: np.ndarray = field(default_factory=lambda: np.eye(3))
    t: np.ndarray = field(default_factory=lambda: np.zeros(3))
    marker: np.ndarray = field(default_factory=lambda: np.zeros(3))
    sigma: float = 0.0
    payload: float = 0.0   # kg, a point mass at the marker
    backlash: dict = field(default_factory=dict)   # {joint: rad}, half the clearance
    tilt: tuple = (0.0, 0.0)   # rad: the base turned about its x and y axes against gravity
    coupling: dict = field(default_factory=dict)   # {(a, b): k}: joint a turns by k times b's commanded value


def _rotation(w) -> np.ndarray:
    return pin.exp3(np.asarray(w, dtype=float))


def perturbed_model(urdf: str, hidden: Hidden):
    """pinocchio's model of the URDF with the hidden origin errors (placement @ (rotation, translation))."""
    m = pin.buildModelFromUrdf(urdf)
    m.gravity.linear = _rotation([hidden.tilt[0], hidden.tilt[1], 0.0]) @ np.array(GRAVITY)
    for name, e in hidden.origins.items():
        jid = m.getJointId(name)
        e = np.asarray(e, dtype=float)
        m.jointPlacements[jid] = m.jointPlacements[jid] * pin.SE3(_rotation(e[3:]), e[:3] / 1000.0)
    return m


def _add_payload(m, frame: str, hidden: Hidden) -> None:
    """A point mass at the marker, on the body carrying ``frame``."""
    if hidden.payload <= 0:
        return
    f = m.frames[m.getFrameId(frame)]
    com = f.placement.rotation @ (hidden.marker / 1000.0) + f.placement.translation
    m.appendBodyToJoint(f.parentJoint, pin.Inertia(hidden.payload, com, np.zeros((3, 3))), pin.SE3.Identity())


def measure(urdf: str, frame: str, names, q: np.ndarray, hidden: Hidden, rng=None) -> np.ndarray:
    """Marker positions (n, 3) mm in the instrument frame at commanded configurations q (n, len(names)),
    ``names`` the joints' order in q (revolute joints, rad)."""
    m = perturbed_model(urdf, hidden)
    _add_payload(m, frame, hidden)
    d = m.createData()
    fid = m.getFrameId(frame)
    idx = [m.idx_qs[m.getJointId(nm)] for nm in names]
    off = np.zeros(m.nq)
    c = np.zeros(m.nq)
    for nm, v in hidden.offsets.items():
        off[m.idx_qs[m.getJointId(nm)]] = v
    for nm, v in hidden.compliance.items():
        c[m.idx_qs[m.getJointId(nm)]] = v
    b = np.zeros(m.nq)
    for nm, v in hidden.backlash.items():
        b[m.idx_qs[m.getJointId(nm)]] = v
    out = np.empty((len(q), 3))
    for k, row in enumerate(q):
        qc = np.zeros(m.nq)
        qc[idx] = row
        for (a, bb), kc in hidden.coupling.items():
            qc[m.idx_qs[m.getJointId(a)]] += kc * row[list(names).index(bb)]
        theta = qc + off
        for _ in range(100):
            g = pin.computeGeneralizedGravity(m, d, theta)
            new = qc + off - c * g - b * np.sign(g)
            done = np.max(np.abs(new - theta)) < 1e-14
            theta = new
            if done:
                break
        pin.framesForwardKinematics(m, d, theta)
        M = d.oMf[fid]
        p = (M.rotation @ (hidden.marker / 1000.0) + M.translation) * 1000.0
        out[k] = hidden.R @ p + hidden.t
    if hidden.sigma > 0:
        rng = rng or np.random.default_rng(0)
        out = out + rng.normal(scale=hidden.sigma, size=out.shape)
    return out


def gravity_torques(urdf: str, names, q: np.ndarray) -> np.ndarray:
    """pinocchio's generalized gravity (n, len(names)) N m of the nominal arm."""
    m = pin.buildModelFromUrdf(urdf)
    m.gravity.linear = np.array(GRAVITY)
    d = m.createData()
    idx = [m.idx_qs[m.getJointId(nm)] for nm in names]
    out = np.empty((len(q), len(names)))
    for k, row in enumerate(q):
        qc = np.zeros(m.nq)
        qc[idx] = row
        out[k] = pin.computeGeneralizedGravity(m, d, qc)[idx]
    return out
