"""Independent truth for absolute-pose calibration of serial arms: pinocchio, no vjm code.

A serial arm read by pinocchio from its URDF carries hidden effects:
- joint offsets (added to the commanded joint values);
- URDF-origin errors (each joint's placement times a small rigid motion);
- a payload (a point mass at the marker);
- joint compliance under self-weight and backlash: the link angles ``theta`` solve
  ``theta = q + offset - c g(theta) - b sign(g(theta))`` with pinocchio's generalized gravity ``g`` of the
  *perturbed* arm (fixed point, to 1e-14 rad; the clearance taken up on the side gravity pushes to);
- compliance depending on the joint's value: the compliance ``c + c' q`` in the equilibrium above;
- lateral joint compliance: each joint's bearing tilted after its motion by ``-c_lat M_perp``, ``M_perp`` the
  part normal to the joint's axis of the moment pinocchio's RNEA passes through the joint (``data.f``);
- link bending: a long link (its placement's largest component at least half the path's longest) an
  Euler-Bernoulli cantilever along that component, loaded at its tip by the wrench RNEA passes to the next
  joint (moved to the tip), which the bent tip carries (tip rotation ``(L M_perp + L^2/2 e x F) / EI``,
  displacement ``(L^2/2 M_perp x e + L^3/3 (e x F) x e) / EI``);
- a length scale with temperature: every joint placement's and the measured frame's translation times
  ``1 + alpha (T - 20)``;
- a base tilt: the gravity turned about the base's x and y axes;
- joint couplings: a joint turning by k times another's commanded value (what the data call a joint is a
  combination of two);
- passive joints (a guide's carriage tilting, a link spring's six deflections): joints of the URDF that no
  command drives, deflected in the same fixed point by ``theta_p = -C(q) g_p(theta)``, ``g_p`` their
  generalized gravity and ``C`` a compliance (k, k) in SI units that may depend on the commanded row;
- prismatic joints commanded in mm (converted to pinocchio's m);
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
    varying: dict = field(default_factory=dict)    # {joint: rad/(N m) per rad}: compliance c + c' q
    lateral: dict = field(default_factory=dict)    # {joint: rad/(N m)}: its bearing's tilt under the normal moment
    bending: dict = field(default_factory=dict)    # {joint carrying the link: 1/EI in 1/(N m^2)}
    alpha: float = 0.0                             # 1/K: length scale with the rows' temperature
    #: {passive joint names (tuple): function of the commanded row {joint: value (rad, mm)} -> compliance (k, k)
    #: in m/N, rad/(N m) (and their cross terms)}: what no command drives, deflected under its gravity
    passive: dict = field(default_factory=dict)


def ur10_postures(n: int, seed: int) -> np.ndarray:
    """n random UR10 configurations (rad): every joint over a turn, the upper arm above the base plate (the
    shoulder lift in [-pi, 0]): large, varied gravity torques."""
    rng = np.random.default_rng(seed)
    q = rng.uniform(-np.pi, np.pi, (n, 6))
    q[:, 1] = rng.uniform(-np.pi, 0.0, n)
    return q


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


def measure(urdf: str, frame, names, q: np.ndarray, hidden: Hidden, rng=None, temperature=None):
    """Marker positions (n, 3) mm in the instrument frame at commanded configurations q (n, len(names)),
    ``names`` the joints' order in q (revolute joints, rad); ``temperature`` (n,) C for ``alpha``.

    Several measured frames (a marker on each hand): ``frame`` a tuple and ``hidden.marker`` a dict
    {frame: offset mm}; returns {frame: (n, 3)}."""
    if not isinstance(frame, str):
        out = {f: _measure(urdf, f, names, q, Hidden(**{**hidden.__dict__, "marker": np.asarray(hidden.marker[f]),
                                                         "sigma": 0.0}), temperature) for f in frame}
        rng = rng or np.random.default_rng(0)
        return {f: v + rng.normal(scale=hidden.sigma, size=v.shape) if hidden.sigma > 0 else v for f, v in out.items()}
    out1 = _measure(urdf, frame, names, q, hidden, temperature)
    if hidden.sigma > 0:
        rng = rng or np.random.default_rng(0)
        out1 = out1 + rng.normal(scale=hidden.sigma, size=out1.shape)
    return out1


def _measure(urdf: str, frame: str, names, q: np.ndarray, hidden: Hidden, temperature=None) -> np.ndarray:
    """The noiseless marker positions of one frame (see :func:`measure`)."""
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
    cv = np.zeros(m.nq)
    for nm, v in hidden.varying.items():
        cv[m.idx_qs[m.getJointId(nm)]] = v
    out = np.empty((len(q), 3))
    unit = np.array([1e-3 if m.joints[m.getJointId(nm)].shortname().startswith("JointModelP") else 1.0
                     for nm in names])   # a prismatic joint commanded in mm
    pidx = {g: [m.idx_qs[m.getJointId(nm)] for nm in g] for g in hidden.passive}
    for k, row in enumerate(q):
        qc = np.zeros(m.nq)
        qc[idx] = row * unit
        Cp = {g: np.asarray(f(dict(zip(names, row))), dtype=float) for g, f in hidden.passive.items()}
        for (a, bb), kc in hidden.coupling.items():
            qc[m.idx_qs[m.getJointId(a)]] += kc * row[list(names).index(bb)]
        theta = qc + off
        for _ in range(100):
            g = pin.computeGeneralizedGravity(m, d, theta)
            new = qc + off - (c + cv * qc) * g - b * np.sign(g)
            for grp, C in Cp.items():
                new[pidx[grp]] = -C @ g[pidx[grp]]
            done = np.max(np.abs(new - theta)) < 1e-14
            theta = new
            if done:
                break
        mk = m
        if hidden.lateral or hidden.bending or hidden.alpha:
            dT = 0.0 if temperature is None else float(temperature[k]) - 20.0
            mk = _flexed(m, d, theta, fid, hidden, dT)
        dk = mk.createData()
        pin.framesForwardKinematics(mk, dk, theta)
        M = dk.oMf[fid]
        p = (M.rotation @ (hidden.marker / 1000.0) + M.translation) * 1000.0
        out[k] = hidden.R @ p + hidden.t
    return out


def _flexed(m, d, theta, fid: int, hidden: Hidden, dT: float):
    """A copy of the model whose placements carry the lateral tilts, the bent links and the thermal scale
    at the link angles theta (the loads from pinocchio's RNEA at rest: ``data.f`` is the wrench the parent
    passes to each joint's subtree, in the joint's frame about its origin)."""
    pin.rnea(m, d, theta, np.zeros(m.nv), np.zeros(m.nv))
    mk = pin.Model(m)
    path = list(m.supports[m.frames[fid].parentJoint])[1:]
    s = 1.0 + hidden.alpha * dT
    for jid in path:
        mk.jointPlacements[jid] = pin.SE3(m.jointPlacements[jid].rotation, s * m.jointPlacements[jid].translation)
    fr = mk.frames[fid]
    fr.placement = pin.SE3(fr.placement.rotation, s * fr.placement.translation)
    mk.frames[fid] = fr
    top = max(np.max(np.abs(m.jointPlacements[b].translation)) for b in path[1:])
    for a, b in zip(path[:-1], path[1:]):
        ei = hidden.bending.get(m.names[a], 0.0)
        p = m.jointPlacements[b].translation
        k = int(np.argmax(np.abs(p)))
        if not ei or abs(p[k]) < 0.5 * top:
            continue
        e = np.zeros(3)
        e[k] = np.sign(p[k])
        L = abs(p[k])
        tip = e * L
        fa = d.liMi[b].act(d.f[b])                   # b's support wrench in a's frame, about a's origin
        Ft, Mt = -fa.linear, -(fa.angular - np.cross(tip, fa.linear))   # the loads on the beam, about the tip
        Mp = Mt - (Mt @ e) * e
        exF = np.cross(e, Ft)
        th = ei * (L * Mp + L**2 / 2 * exF)
        u = ei * (L**2 / 2 * np.cross(Mp, e) + L**3 / 3 * np.cross(exF, e))
        R = _rotation(th)
        mk.jointPlacements[b] = pin.SE3(R, u + tip - R @ tip) * mk.jointPlacements[b]
    for jid in path:
        c = hidden.lateral.get(m.names[jid], 0.0)
        if not c:
            continue
        ax = _axis(m, jid)
        Mj = d.f[jid].angular
        R = pin.SE3(_rotation(-c * (Mj - (Mj @ ax) * ax)), np.zeros(3))
        for child in range(1, m.njoints):
            if m.parents[child] == jid:
                mk.jointPlacements[child] = R * mk.jointPlacements[child]
        if m.frames[fid].parentJoint == jid:
            fr = mk.frames[fid]
            fr.placement = R * fr.placement
            mk.frames[fid] = fr
    return mk


def _axis(m, jid: int) -> np.ndarray:
    """A revolute joint's axis in its frame: the angular part of its motion subspace."""
    d = m.createData()
    q = pin.neutral(m)
    pin.computeJointJacobians(m, d, q)
    J = pin.getJointJacobian(m, d, jid, pin.LOCAL)
    return np.asarray(J[3:, m.idx_vs[jid]], dtype=float)


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


def urdf_link(name, mass, com):
    """A URDF link with a mass (kg) at its centre of mass ``com`` ("x y z", m) and a small inertia."""
    return (f'<link name="{name}"><inertial><mass value="{mass}"/><origin xyz="{com}"/>'
            f'<inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>')


def urdf_joint(name, parent, child, xyz, axis):
    """A revolute URDF joint at ``xyz`` (m) about ``axis``, limits of +-3.2 rad."""
    return (f'<joint name="{name}" type="revolute"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="{xyz}" rpy="0 0 0"/><axis xyz="{axis}"/>'
            f'<limit lower="-3.2" upper="3.2" effort="100" velocity="1"/></joint>')


def urdf_prismatic(name, parent, child, xyz, axis, lower, upper, rpy="0 0 0"):
    """A prismatic URDF joint at ``xyz`` (m) along ``axis``, travel [lower, upper] m."""
    return (f'<joint name="{name}" type="prismatic"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="{xyz}" rpy="{rpy}"/><axis xyz="{axis}"/>'
            f'<limit lower="{lower}" upper="{upper}" effort="1000" velocity="1"/></joint>')


def urdf_passive(name, parent, child, xyz="0 0 0", axis="1 0 0", kind="revolute", rpy="0 0 0"):
    """A passive URDF joint (a spring's deflection): wide limits, no command drives it."""
    return (f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="{xyz}" rpy="{rpy}"/><axis xyz="{axis}"/>'
            f'<limit lower="-1" upper="1" effort="1000" velocity="1"/></joint>')


def guide_robot_urdf(tilt: bool = False, stages: int = 1) -> str:
    """A four-joint arm on a vertical prismatic column (travel 0 to 0.8 m; with ``stages`` 2 a telescope whose
    second stage is a mimic of the first), the measured frame ``tool``.  ``tilt``: two passive revolute joints
    (about the carriage's x and y, ``tilt_x``/``tilt_y``, and per further stage ``tilt2_x``/``tilt2_y``) at the
    top of each stage, between it and what it carries: the truth of a guide tilting under its moment."""
    parts = ['<robot name="guide_robot">', '<link name="base_link"/>']
    parent = "base_link"
    for k in range(stages):
        tag = "" if k == 0 else str(k + 1)
        stage = f"stage{tag}"
        parts.append(urdf_link(stage, 0.001, "0 0 0"))
        joint = urdf_prismatic(f"column{tag}", parent, stage, "0 0 0.5" if k == 0 else "0 0 0.1", "0 0 1", 0.0, 0.8)
        if k > 0:
            joint = joint.replace("</joint>", '<mimic joint="column" multiplier="1" offset="0"/></joint>')
        parts.append(joint)
        parent = stage
        if tilt:
            parts += [urdf_link(f"{stage}_tx", 0.0, "0 0 0"), urdf_link(f"{stage}_ty", 0.0, "0 0 0"),
                      urdf_passive(f"tilt{tag}_x", parent, f"{stage}_tx", axis="1 0 0"),
                      urdf_passive(f"tilt{tag}_y", f"{stage}_tx", f"{stage}_ty", axis="0 1 0")]
            parent = f"{stage}_ty"
    parts += [urdf_link("carriage", 10.0, "0 0 0.1"), _fixed("carriage_fix", parent, "carriage"),
              urdf_link("turret", 8.0, "0 0 0.1"), urdf_joint("j1", "carriage", "turret", "0 0 0.3", "0 0 1"),
              urdf_link("upper", 6.0, "0.3 0 0"), urdf_joint("j2", "turret", "upper", "0 0 0.2", "0 1 0"),
              urdf_link("fore", 4.0, "0.25 0 0"), urdf_joint("j3", "upper", "fore", "0.6 0 0", "0 1 0"),
              urdf_link("hand", 1.0, "0 0 -0.05"), urdf_joint("j4", "fore", "hand", "0.5 0 0", "0 0 1"),
              '<link name="tool"/>', _fixed("tool_fix", "hand", "tool", "0 0 -0.1"), "</robot>"]
    return "\n".join(parts)


def _fixed(name, parent, child, xyz="0 0 0", rpy="0 0 0"):
    return (f'<joint name="{name}" type="fixed"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="{xyz}" rpy="{rpy}"/></joint>')


def with_link_spring(urdf_text: str, link: str, child_joint: str, xyz, rpy, prefix: str) -> str:
    """The URDF with six passive joints (``prefix``_tx, _ty, _tz, _rx, _ry, _rz: translations then rotations
    about the spring frame's axes) inserted on ``link`` at the spring frame (``xyz`` m, ``rpy``) before the
    joint ``child_joint``, whose origin is moved into the spring's deflected frame: the truth of a link spring
    (its deflections, at zero, the spring frame's local twist)."""
    import xml.etree.ElementTree as ET

    root = ET.fromstring(urdf_text)
    S = pin.SE3(pin.rpy.rpyToMatrix(*[float(a) for a in rpy]), np.array(xyz, dtype=float))
    cj = next(j for j in root.findall("joint") if j.get("name") == child_joint)
    o = cj.find("origin")
    O = pin.SE3(pin.rpy.rpyToMatrix(*[float(a) for a in o.get("rpy", "0 0 0").split()]),
                np.array([float(a) for a in o.get("xyz", "0 0 0").split()]))
    N = S.inverse() * O
    o.set("xyz", " ".join(repr(float(v)) for v in N.translation))
    o.set("rpy", " ".join(repr(float(v)) for v in pin.rpy.matrixToRpy(N.rotation)))
    parent = link
    for k, (kind, axis) in enumerate((("prismatic", "1 0 0"), ("prismatic", "0 1 0"), ("prismatic", "0 0 1"),
                                      ("revolute", "1 0 0"), ("revolute", "0 1 0"), ("revolute", "0 0 1"))):
        name = f"{prefix}_{'t' if k < 3 else 'r'}{'xyz'[k % 3]}"
        child = f"{prefix}_l{k}"
        root.append(ET.fromstring(f'<link name="{child}"/>'))
        root.append(ET.fromstring(urdf_passive(name, parent, child, " ".join(map(str, xyz)) if k == 0 else "0 0 0",
                                               axis, kind, " ".join(map(str, rpy)) if k == 0 else "0 0 0")))
        parent = child
    cj.find("parent").set("link", parent)
    return ET.tostring(root, encoding="unicode")


def si_compliance(C: np.ndarray) -> np.ndarray:
    """A 6x6 compliance in mm/N, rad/(N mm) by block (order Fx..Mz) in SI: m/N, rad/(N m)."""
    C = np.asarray(C, dtype=float)
    out = C.copy()
    out[:3, :3] = C[:3, :3] / 1000.0
    out[3:, 3:] = C[3:, 3:] * 1000.0
    return out


#: the column robot's joints as its data name them: the column's lift (mm), then the arm (rad)
COLUMN_JOINTS = ("lift", "yaw", "shoulder", "elbow", "wrist")
#: the column's travel (m)
COLUMN_TRAVEL = (0.0, 0.8)


def column_robot_urdf(hidden_tilt: bool = False) -> str:
    """A robot whose four-joint arm rides on a prismatic (telescopic) column: the lift along z (its travel
    :data:`COLUMN_TRAVEL` above the fixed guide's 0.8 m), a yaw at the column's top, a shoulder, an elbow and
    a wrist pitching about y.  ``hidden_tilt``: two revolute joints (about x, then y) at the fixed guide's top, where
    the moving stage leaves it: the stage's tilt in the guide (the whole moving column and the arm turn about
    it), set by :func:`column_robot_poses` (not joints of the robot's own model)."""
    parts = ['<robot name="column">', urdf_link("base", 50.0, "0 0 0.2")]
    if hidden_tilt:
        parts += [urdf_joint("tilt_x", "base", "tilt_mid", "0 0 0.8", "1 0 0"), urdf_link("tilt_mid", 0.0, "0 0 0"),
                  urdf_joint("tilt_y", "tilt_mid", "guide", "0 0 0", "0 1 0"), urdf_link("guide", 0.0, "0 0 0"),
                  urdf_prismatic("lift", "guide", "carriage", "0 0 0", "0 0 1", *COLUMN_TRAVEL)]
    else:
        parts += [urdf_prismatic("lift", "base", "carriage", "0 0 0.8", "0 0 1", *COLUMN_TRAVEL)]
    parts += [urdf_link("carriage", 6.0, "0 0 0.1"),
              urdf_joint("yaw", "carriage", "turret", "0 0 0.2", "0 0 1"), urdf_link("turret", 4.0, "0 0 0.05"),
              urdf_joint("shoulder", "turret", "upper", "0 0 0.1", "0 1 0"), urdf_link("upper", 9.0, "0.3 0 0.05"),
              urdf_joint("elbow", "upper", "fore", "0.6 0 0.1", "0 1 0"), urdf_link("fore", 5.0, "0.25 0 0"),
              urdf_joint("wrist", "fore", "hand", "0.5 0 0", "0 1 0"), urdf_link("hand", 2.0, "0.08 0 0"),
              '<joint name="tool_joint" type="fixed"><parent link="hand"/><child link="tool"/>'
              '<origin xyz="0.15 0 0" rpy="0 0 0"/></joint>', '<link name="tool"/>', "</robot>"]
    return "\n".join(parts)


def column_robot_poses(urdf_hidden: str, n: int, tilt=(2e-6, 2e-5), R=None, t=None, marker=(0.0, 0.0, 0.0),
                       sigma: float = 0.01, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(q (n, 5): the lift in mm and the arm's joints in rad, the marker's positions (n, 3) mm in the instrument
    frame) of the column robot (:func:`column_robot_urdf` with ``hidden_tilt``, written at ``urdf_hidden``)
    whose column top tilts under the arm's weight: the tilt angles about x and y are ``-c(z) g`` with
    ``g`` pinocchio's gravity torques at the two hidden joints and a compliance growing with the extension
    ``z`` (m), ``c(z) = tilt[0] + tilt[1] z`` rad/(N m) (the overlaps of a telescopic column shrink as it
    extends), solved as a fixed point; random postures over the travel, an instrument frame (R, t mm), a
    marker offset on ``tool`` (mm) and iid noise ``sigma`` (mm)."""
    m = pin.buildModelFromUrdf(urdf_hidden)
    m.gravity.linear = np.array(GRAVITY)
    d = m.createData()
    fid = m.getFrameId("tool")
    iq = {nm: m.idx_qs[m.getJointId(nm)] for nm in (*COLUMN_JOINTS, "tilt_x", "tilt_y")}
    rng = np.random.default_rng(seed)
    q = np.column_stack([rng.uniform(*COLUMN_TRAVEL, n), rng.uniform(-3.0, 3.0, n), rng.uniform(-0.6, 0.6, n),
                         rng.uniform(-1.2, 1.2, n), rng.uniform(-1.5, 1.5, n)])
    R = np.eye(3) if R is None else np.asarray(R, dtype=float)
    t = np.zeros(3) if t is None else np.asarray(t, dtype=float)
    out = np.empty((n, 3))
    tilt_idx = [iq["tilt_x"], iq["tilt_y"]]
    for k, row in enumerate(q):
        th = np.zeros(m.nq)
        for nm, v in zip(COLUMN_JOINTS, row):
            th[iq[nm]] = v
        c = tilt[0] + tilt[1] * row[0]
        for _ in range(100):
            g = pin.computeGeneralizedGravity(m, d, th)
            new = -c * g[tilt_idx]
            done = np.max(np.abs(new - th[tilt_idx])) < 1e-15
            th[tilt_idx] = new
            if done:
                break
        pin.framesForwardKinematics(m, d, th)
        M = d.oMf[fid]
        out[k] = R @ ((M.rotation @ (np.asarray(marker) / 1000.0) + M.translation) * 1000.0) + t
    out += rng.normal(scale=sigma, size=out.shape) if sigma > 0 else 0.0
    return q * np.array([1000.0, 1.0, 1.0, 1.0, 1.0]), out
