"""The model edits and per-pose quantities of the effects: everything an effect (and the diagnosis'
calibration) reads from, or changes in, a :class:`vjm.model.machine.ParallelModel`.

One home for the coupling to the VJM core: the helpers only use the public model API (immutable
``Model``, ``replace``, ``stiffness_map``, ``inverse_kinematics``, ``joint_forces``,
``vjm.stiffness.nonlinear``) so a change there is absorbed here.
"""
from __future__ import annotations

import os

import numpy as np

from ..errors import VjmError
from ..model.links import LinkSpring
from ..stiffness.linear import KERNEL_ENV, kernels_compiled

# --------------------------------------------------------------- per-pose quantities


#: a fit evaluates the map of the same poses thousands of times: its maps (``repeated=True``) run the
#: compiled kernels (loaded once per process, about 1 s) whenever they are compiled already -- from one pose
#: on, a compiled map of the 3-PUU or the hexapod costs about 0.3 ms against 1.6-2.5 ms on the numpy path,
#: the 3-PRPaR's 2-3 ms against 4-5 ms -- and, where they are not, from this many poses, where a fit saves
#: about what their compile costs once per install (about 20 s).  ``VJM_MAP_KERNEL`` set in the environment
#: decides instead.
REPEATED_FROM = 16


def stiffness_result(model, P, repeated: bool = False):
    """``model.stiffness_map(P)``.  The model keeps the kinematics of recent pose batches and
    shares them (and its chains) with the models ``replace`` derives from it (same geometry), so a
    fit that changes stiffness parameters only redoes the spring part (eq. 11, 13).  ``repeated``: the
    map of a fit, compiled (see :data:`REPEATED_FROM`).  Only the fits ask for it: a caller that
    cuts its poses into chunks (``simulate``, for its progress) keeps the default, so that its numbers do
    not depend on the chunks."""
    n = np.shape(getattr(P, "frames", P))[0]
    compiled = repeated and not os.environ.get(KERNEL_ENV) and (n >= REPEATED_FROM or kernels_compiled())
    return model.stiffness_map(P, kernel="numba" if compiled else None)


def compliance_map(model, P, repeated: bool = False) -> np.ndarray:
    """(m, 6, 6) compliance C at postures P (world axes at the end-effector point)."""
    return stiffness_result(model, P, repeated).C


def kvalues_map(model, P, repeated: bool = False) -> np.ndarray:
    """(m, 2) ``k_tran``, ``k_rot`` at postures P (vjm's definitions)."""
    r = stiffness_result(model, P, repeated)
    return np.stack([r.k_tran, r.k_rot], axis=1)


def actuator_coords(model, P) -> np.ndarray:
    """(m, n_chains) actuator coordinates; VjmError if a posture is unreachable."""
    return np.asarray(model.inverse_kinematics(P), float)


def actuator_influence(model, P) -> np.ndarray:
    """(m, n_chains, 6): ``a_i`` with actuator force ``tau_i = a_i . w`` for a wrench w at the end-effector.

    Linear in w, so the six unit wrenches give it column by column.
    """
    m = len(P)
    cols = [np.asarray(model.joint_forces(P, np.broadcast_to(np.eye(6)[j], (m, 6)))["actuator"]) for j in range(6)]
    return np.stack(cols, axis=-1)


def actuator_spring_name(model) -> str:
    """The name of the actuated joints' spring, the same in every chain (the one an actuator slips in)."""
    names = set()
    for ch in model.chains:
        a = ch.actuated[0]
        names |= {s.name for s in ch.springs if s.vars == (a,)}
    if len(names) != 1:
        raise VjmError("clearance: the model's chains have no single actuator spring to slip")
    return names.pop()


#: compliance (rad/(N mm)) of the probe springs put into ideal passive joints to read the moment each
#: carries about its constrained direction: 1e-15 is 1e-8 of a steel leg's torsion compliance, so the
#: load sharing is the ideal joints' to that relative order
JOINT_PROBE_COMPLIANCE = 1e-15


def joint_spring_names(model) -> tuple:
    """Names of the 1-dof passive-joint springs (U-joint crosses, pivots) the model's chains carry
    with elastic passive joints (``joints.passive_stiffness``); () if its joints have none."""
    ideal = {s.name for ch in with_passive_compliance(model, 0.0).chains for s in ch.springs}
    elastic = with_passive_compliance(model, JOINT_PROBE_COMPLIANCE)
    return tuple(dict.fromkeys(s.name for ch in elastic.chains for s in ch.springs if s.name not in ideal))


def joint_spring_influence(model, P) -> np.ndarray:
    """(m, n_springs, 6): ``a_s`` with the moment of passive-joint spring s ``tau_s = a_s . w`` (N mm)
    under a wrench w at the end-effector, for every such spring of every chain (chain by chain).

    ``tau_s = J_s^T f_i``: the chain's share ``f_i`` of the load (eq. 9, 12) projected on the
    spring's Jacobian column.  A model with ideal passive joints gets probe springs of
    :data:`JOINT_PROBE_COMPLIANCE`, so the moments are those its joints carry as reactions.
    By the unit-load theorem ``a_s`` is also the end-effector twist of a unit rotation imposed in
    that spring (a slip of the joint about its constrained direction).
    """
    mj = model if passive_compliance(model) > 0 else with_passive_compliance(model, JOINT_PROBE_COMPLIANCE)
    names = set(joint_spring_names(model))
    kin = mj.kinematics(P)
    m = kin.n
    F = np.stack([np.asarray(mj.joint_forces(kin, np.broadcast_to(np.eye(6)[j], (m, 6)))["chain_wrench"])
                  for j in range(6)], axis=-1)  # (m, n_chains, 6 wrench comps, 6 unit loads)
    cols = []
    for k, (ch, J) in enumerate(zip(kin.chains, kin.jacobians)):
        for s in ch.springs:
            if s.name in names:
                cols.append(np.einsum("ni,nij->nj", J[:, :, s.vars[0]], F[:, k]))
    return np.stack(cols, axis=1) if cols else np.zeros((m, 0, 6))


_NL_MEMO: dict = {}


def nonlinear_delta(model, P, W) -> np.ndarray:
    """(n, 6) nonlinear-equilibrium deflection minus the linear one, per (posture, wrench) row.

    All rows are solved together by vjm.stiffness.nonlinear's batched Newton; results
    are memoized per (model, P, W): the model is immutable and kept
    referenced by the memo.
    """
    from ..stiffness import nonlinear

    P = np.ascontiguousarray(P, dtype=float)
    W = np.ascontiguousarray(W, dtype=float)
    key = (id(model), P.tobytes(), W.tobytes())
    hit = _NL_MEMO.get(key)
    if hit is not None and hit[0] is model:
        return hit[1]
    # repeated (posture, load) rows, common in real measurements, are solved once
    PW, first, inv = np.unique(np.hstack([P, W]), axis=0, return_index=True, return_inverse=True)
    Pu, Wu = P[first], W[first]
    C = stiffness_result(model, Pu).C
    lin = np.einsum("nij,nj->ni", C, Wu)
    nl = np.asarray(nonlinear.deflection_map(model, Pu, Wu), float)
    out = (nl - lin)[inv.reshape(-1)]
    if len(_NL_MEMO) > 16:
        _NL_MEMO.clear()
    _NL_MEMO[key] = (model, out)
    return out


def workspace_box(model):
    """(lo, hi) corners of the design box, mm: the model's workspace (:attr:`vjm.model.machine.ParallelModel.workspace`:
    ``geometry.workspace`` if given, else the architecture's box; Orthoglide: Q1 to Q2, seed Fig. 4c)."""
    ws = model.workspace
    return ws.lo.copy(), ws.hi.copy()


# --------------------------------------------------------------- parameters


def _link(C):
    return LinkSpring(np.asarray(C, float), None)


def _scaled(link: LinkSpring, d: np.ndarray, D: np.ndarray) -> LinkSpring:
    """``link`` with its compliance congruent by ``diag(d)`` (``D = outer(d, d)``): the same matrix as
    ``C * D`` checked again, without the check a checked matrix does not need."""
    from linkfea.mechanics.compliance import Compliance

    if isinstance(link.value, Compliance) and np.all(np.isfinite(d)) and np.all(d > 0):
        return LinkSpring(link.value.congruence(d), None)
    return _link(link.compliance * D)   # checked when the model is made: a bad factor named there


def foot_is_rigid(model) -> bool:
    return model.foot.compliance is None


def actuator_is_rotary(model) -> bool:
    """The actuated joints turn (the Delta's arms; a description's ``Rz(q0) actuated``): their slips
    and travels are angles, rad."""
    if str(getattr(model.arch, "actuator_unit", "")).endswith("/rad"):
        return True
    desc = getattr(model, "description", None)
    if desc is None:
        return False
    kinds = {e.kind for ch in desc.chains for e in ch.elements if e.role == "actuated"}
    return bool(kinds) and all(k.startswith("r") for k in kinds)


def with_actuator_scale(model, s: float):
    """Actuator stiffness multiplied by ``s``."""
    if s == 1.0:
        return model
    a = model.actuator
    return model.replace(actuator=type(a)(a.stiffness * s, a.compliance_slope, a.q_ref))


#: congruence weights of the calibration's link scale: every direction but torsion (rx)
_LINK_SCALE_MASK = np.array([1.0, 1.0, 1.0, 0.0, 1.0, 1.0])


def with_link_scale(model, s: float):
    """Link compliances (foot and leg) scaled by ``s`` in extension and bending, torsion kept.

    ``C' = D C D`` with ``D = diag(sqrt s, sqrt s, sqrt s, 1, sqrt s, sqrt s)``: a
    congruence, so C' stays symmetric positive definite; extension/bending
    terms scale by ``s`` (a Young's modulus or section error), cross terms with
    torsion by ``sqrt s`` and the torsion compliance not at all.  Torsion is
    left out on purpose: in a U-U leg it is in series with the passive-joint
    springs and the two cannot be told apart from end-effector data.
    """
    if s == 1.0:
        return model
    d = np.where(_LINK_SCALE_MASK > 0, np.sqrt(s), 1.0)
    D = np.outer(d, d)
    ch = {k: _scaled(getattr(model, k), d, D) for k in ("foot", "leg") if getattr(model, k).compliance is not None}
    return model.replace(**ch)


#: deformation modes of a link's 6-dof spring (frame x along the link): the compliance
#: indices each mode owns (Fx..Mz order).  Bending about y couples Fz with My, about z Fy with Mz.
MODES = {"axial": (0,), "bending_y": (2, 4), "bending_z": (1, 5), "torsion": (3,)}


def link_label(model, key: str) -> str:
    """The word users read for the model's link ``key``: foot, leg, or bar (parallelogram legs)."""
    if key == "leg" and model.arch.leg_bars == 2:  # one bar of a parallelogram leg
        return "bar"
    return key


def link_compliance(model, key: str):
    return getattr(model, key).compliance


def with_mode_factor(model, key: str, mode: str, f: float):
    """Link ``key``'s compliance with mode ``mode`` multiplied by ``f`` (a section stiffness / f).

    ``C' = D C D`` with ``D = sqrt(f)`` on the mode's indices and 1 elsewhere: the
    mode's own block (e.g. c22, c26, c66 for bending about z, as a beam's EIz
    scales them all) scales by ``f``, its couplings to other modes by ``sqrt f``;
    a congruence, so C' stays symmetric positive definite.
    """
    if f == 1.0:
        return model
    C = link_compliance(model, key)
    if C is None:
        raise VjmError(f"{link_label(model, key)}_{mode} needs a flexible {link_label(model, key)}")
    d = np.ones(6)
    d[list(MODES[mode])] = np.sqrt(f)
    return model.replace(**{key: _scaled(getattr(model, key), d, np.outer(d, d))})


#: c26 / sqrt(c22 c66) of an Euler-Bernoulli cantilever (eq. 14): (L^2/2) / (L^2/sqrt 3)
BEAM_BENDING_COUPLING = np.sqrt(3.0) / 2.0


def bending_coupling(model, key: str) -> float:
    """Current bending coupling of link ``key`` as a fraction ``kappa`` of the beam-consistent value
    (kappa = 1 for an eq. 14 cantilever: c26 = L^2/2EIz, c35 = -L^2/2EIy)."""
    C = link_compliance(model, key)
    if C is None:
        return 0.0
    for i, j, sgn in ((1, 5, 1.0), (2, 4, -1.0)):
        den = BEAM_BENDING_COUPLING * np.sqrt(C[i, i] * C[j, j])
        if den > 0 and C[i, j] != 0:
            return float(sgn * C[i, j] / den)
    return 0.0


def with_bending_coupling(model, key: str, kappa: float):
    """Link ``key`` with ``c26 = kappa (sqrt3/2) sqrt(c22 c66)`` and ``c35 = -kappa (sqrt3/2) sqrt(c33 c55)``.

    ``kappa = 1`` is the translation-rotation coupling of a cantilever beam of the
    link's own bending compliances (eq. 14), ``0`` none; ``|kappa| < 2/sqrt 3``
    keeps each bending block positive definite.
    """
    C = link_compliance(model, key)
    if C is None:
        raise VjmError(f"{link_label(model, key)}_bending_coupling needs a flexible {link_label(model, key)}")
    return model.replace(**{key: _link(_bending_coupled(C, kappa))})


def _bending_coupled(C, kappa):
    C = np.array(C, float)
    k = BEAM_BENDING_COUPLING * float(kappa)
    C[1, 5] = C[5, 1] = k * np.sqrt(C[1, 1] * C[5, 5])
    C[2, 4] = C[4, 2] = -k * np.sqrt(C[2, 2] * C[4, 4])
    return C


def extension_torsion(model, key: str = "leg") -> float:
    """Current extension-torsion coupling ``kappa = c14 / sqrt(c11 c44)`` of link ``key``."""
    C = link_compliance(model, key)
    if C is None or C[0, 0] <= 0 or C[3, 3] <= 0:
        return 0.0
    return float(C[0, 3] / np.sqrt(C[0, 0] * C[3, 3]))


def with_extension_torsion(model, key: str, kappa: float):
    """Link ``key`` with the extension-torsion coupling ``c14 = c41 = kappa sqrt(c11 c44)``.

    An axial force then twists the link and a torque stretches it (pretwisted
    or helically stiffened links, unsymmetric FEA links); ``|kappa| < 1``
    keeps the compliance positive definite.  Straight prismatic beams (eq. 14)
    have ``kappa = 0``.
    """
    C = link_compliance(model, key)
    if C is None:
        raise VjmError(f"{link_label(model, key)}_extension_torsion needs a flexible {link_label(model, key)}")
    return model.replace(**{key: _link(_extension_torsion_coupled(C, kappa))})


def _extension_torsion_coupled(C, kappa):
    C = np.array(C, float)
    C[0, 3] = C[3, 0] = float(kappa) * np.sqrt(C[0, 0] * C[3, 3])
    return C


#: fraction of a coupling's positive-definite range the fit may span: the edge itself is a singular
#: link (a combined deflection mode with no compliance), so the bound stays just inside it
ADMISSIBLE = 0.99


def _coupling_limits(C, couple) -> tuple[float, float]:
    """Range of the coupling ``kappa`` (set by ``couple(C, kappa)``) that keeps ``C`` positive definite.

    The limits are where the smallest eigenvalue of the diagonally scaled compliance reaches
    zero (bisection on each side, the link's other couplings included), times
    :data:`ADMISSIBLE`: a fit bounded more tightly would clip estimates the link can
    physically have (e.g. a beam's ``kappa = 1`` bending coupling estimated at 1.13 +- 0.06
    against a bound of 1.1, short of the limit ``2/sqrt 3``).
    """
    def margin(k):
        Ck = couple(C, k)
        d = np.sqrt(np.diag(Ck))
        return float(np.linalg.eigvalsh(Ck / np.outer(d, d))[0])

    out = []
    for sgn in (-1.0, 1.0):
        lo, hi = 0.0, 1.0
        if margin(0.0) <= 0.0:
            return 0.0, 0.0
        while margin(sgn * hi) > 0.0 and hi < 1e3:
            lo, hi = hi, 2.0 * hi
        for _ in range(50):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if margin(sgn * mid) > 0.0 else (lo, mid)
        out.append(sgn * ADMISSIBLE * lo)
    return out[0], out[1]


def bending_coupling_limits(model, key: str) -> tuple[float, float]:
    """Admissible range of link ``key``'s bending coupling ``kappa`` (:func:`with_bending_coupling`)."""
    return _coupling_limits(link_compliance(model, key), _bending_coupled)


def extension_torsion_limits(model, key: str) -> tuple[float, float]:
    """Admissible range of link ``key``'s extension-torsion ``kappa`` (:func:`with_extension_torsion`)."""
    return _coupling_limits(link_compliance(model, key), _extension_torsion_coupled)


def cantilever_compliance(axial, bending_y, bending_z, torsion, length) -> np.ndarray:
    """6x6 tip compliance of a cantilever along x of free section stiffnesses (eq. 14 without shear).

    Parameters are the tip compliances users can picture: ``axial`` = c11 =
    L/EA (mm/N), ``bending_z`` = c22 = L^3/3EIz (mm/N, tip deflection along y
    per N), ``bending_y`` = c33 = L^3/3EIy (mm/N), ``torsion`` = c44 = L/GJ
    (rad/(N mm)), and the length L (mm), which sets the rotation terms
    ``c66 = 3 c22 / L^2``, ``c26 = 3 c22 / (2L)``, ``c55 = 3 c33 / L^2``,
    ``c35 = -3 c33 / (2L)`` (signs of eq. 14: Fy turns the tip by +rz).
    """
    from linkfea.beam.closed_form import eq14

    L = float(length)
    # eq. 14 with unit moduli and the section values these tip compliances stand for
    return eq14(L, 1.0, 1.0, L / axial, L**3 / (3.0 * bending_y), L**3 / (3.0 * bending_z), L / torsion)


def with_foot_cantilever(model, axial, bending_y, bending_z, torsion, length, floor=1e-9):
    """A foot that is a cantilever of free section (see :func:`cantilever_compliance`); rigid when
    every compliance is 0.  Compliances below ``floor`` x the actuator compliance (translations;
    divided by length^2 for torsion) are raised to it so the spring stays positive definite."""
    vals = np.array([axial, bending_y, bending_z, torsion], float)
    if not np.any(vals > 0):
        return model.replace(foot=LinkSpring.rigid())
    ct = floor / model.actuator.stiffness
    a, by, bz = (max(float(v), ct) for v in (axial, bending_y, bending_z))
    t = max(float(torsion), ct / float(length) ** 2)
    return model.replace(foot=_link(cantilever_compliance(a, by, bz, t, length)))


def gravity_direction(model) -> np.ndarray:
    """Unit gravity direction in world axes: ``geometry.gravity: [gx, gy, gz]`` if given, else -z."""
    g = model.geometry.get("gravity")
    v = np.array([0.0, 0.0, -1.0]) if g is None else np.asarray(g, float).reshape(3)
    n = np.linalg.norm(v)
    if not np.isfinite(n) or n == 0:
        raise VjmError(f"geometry.gravity must be a non-zero direction [gx, gy, gz], got {g!r}")
    return v / n


def platform_rotations(P) -> np.ndarray:
    """(n, 3, 3) platform rotations of poses P: the rotation of columns 3:6 (``ox,oy,oz``, a rotation
    vector) of (n, 6) poses, the identity for points (n, 3)."""
    from ..kinematics.poses import rotation_matrix

    P = np.asarray(P, float)
    if P.shape[1] == 6:
        return rotation_matrix(P[:, 3:])
    return np.broadcast_to(np.eye(3), (len(P), 3, 3))


def passive_compliance(model) -> float:
    k = model.joints.passive_stiffness
    return 0.0 if k is None else 1.0 / float(k)


def with_passive_compliance(model, c: float):
    """Passive-joint springs of compliance ``c`` rad/(N mm) (ideal joints at c = 0)."""
    from ..model.machine import Joints

    return model.replace(joints=Joints(None if c <= 0 else 1.0 / c))


def actuator_relative_slope(model) -> float:
    """Slope of the actuator compliance relative to its value at q_ref: ``c(q) = c0 (1 + s (q - q_ref))``, 1/mm."""
    return float(model.actuator.compliance_slope * model.actuator.stiffness)


def with_actuator_relative_slope(model, s: float):
    a = model.actuator
    return with_actuator_slope(model, float(s) / a.stiffness)


def relative_slope_bounds(model, q, floor: float = 0.05, cap: float = 20.0):
    """Bounds of the relative slope ``s`` over the actuator travel ``q`` present in the data.

    The actuator compliance must stay above ``floor`` x c0 everywhere in the data
    (``1 + s (q - q_ref) >= floor``) and change by at most ``cap`` x c0 over it
    (``|s| max|q - q_ref| <= cap``): the positivity bound comes from the data's
    own travel, so a steep but physical slope is not clipped.
    """
    dq = np.asarray(q, float).ravel() - model.actuator.q_ref
    dq = dq[np.isfinite(dq)]
    span = float(np.max(np.abs(dq))) if dq.size else float(model.geometry.get("L", 100.0))
    span = max(span, 1e-9)
    lo, hi = -cap / span, cap / span
    if dq.size and dq.max() > 0:
        lo = max(lo, -(1.0 - floor) / dq.max())
    if dq.size and dq.min() < 0:
        hi = min(hi, (1.0 - floor) / -dq.min())
    return lo, hi


def with_actuator_slope(model, slope: float):
    a = model.actuator
    return model.replace(actuator=type(a)(a.stiffness, float(slope), a.q_ref))


def with_effect_entry(model, name: str, values: dict):
    """Model whose ``effects:`` mapping carries ``name: values``."""
    eff = dict(model.effects)
    eff[name] = dict(values)
    return model.replace(effects=eff)
