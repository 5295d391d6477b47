"""Independent truth for `vjm diagnose`: measurement sets of the Orthoglide 3-PUU and 3-PRPaR.

Nothing here uses :mod:`vjm.discrepancy` (neither its effect library nor its
simulator), so a diagnosis that passes on these sets finds what a richer
machine does, not what its own effect code wrote.  The true deflections are

* the elastic deflection of a **richer model file** (a mapping in the
  ``data/orthoglide/puu.yaml`` format: a real beam foot of other proportions
  than the leg's, a foot compliance with its bending couplings, elastic passive
  joints, an actuator whose compliance grows along its travel ...) solved by
  the vjm model (linear ``C(p) w``) or by :mod:`vjm.stiffness.nonlinear` (finite
  rotations: geometric nonlinearity);
* plus terms written out here, with their own kinematics of the 3-PUU (its
  rigid inverse kinematics in closed form, not vjm's chains):

  - ``weight``: a weight ``m g`` (N) on the platform at the end-effector point,
    along ``GRAVITY``, carried by the machine together with the applied load;
  - ``backlash``: every actuator slips by ``b`` (mm) in the direction of its
    force.  The force of actuator i is ``tau_i = (J^-T F)_i`` with
    ``J = dq/dp`` of the closed-form inverse kinematics (a slip is a rigid,
    stress-free motion of the translational 3-PUU, so by the unit-load theorem
    the actuator forces depend on the force part of the wrench only); the
    platform moves by ``dp = J^-1 (b sign(tau))`` without rotating;
  - ``joint_backlash``: every U joint's cross (3-PRPaR: every pivot) tilts by
    ``b`` (rad) about its constrained direction(s), toward the moment it carries
    there.  Solved by :mod:`vjm.stiffness.nonlinear` on the true machine with stiff joint springs: the
    moments are read off the springs' rotations under the load, and the slips
    are imposed as the springs' rest values (``offsets``) in a second,
    load-free equilibrium of the whole overconstrained machine;
  - out-of-library effects: ``hysteresis`` (a fraction of the previous load's
    elastic deflection at the same posture remains: friction in the joints)
    and ``contact`` (a Hertz-like contact at the tool whose deflection grows as
    ``|F|^(2/3)`` along the force: it stiffens with the load).

The Delta 3-RRPaR and a 6-dof hexapod at tilted orientations are in :mod:`truth_platforms`
(their own kinematics and statics, same rules).

The 3-PRPaR (``data/orthoglide/prpar.yaml``, parallelogram legs) shares the
3-PUU's actuators, workspace and leg inverse kinematics, so the terms above
hold for it as written; its bar's effects are richer prpar.yaml files.

Every effect of the library has a true machine in :data:`LIBRARY`, and
:func:`signature_chi2` says whether a data set can show it at all (the
noise-free gap between true and given deflections once the model given has
refit its own actuator and link scales).

Noise: independent Gaussian on each component, ``sigma_t`` (mm) and
``sigma_r`` (rad), written as columns (known sigmas) or left out with every
row repeated (unknown sigmas, pure error from the repeats).  Defects of the
noise are made here too (:func:`measure`): a component noisier than the others,
a laser tracker's noise growing with the distance, a file that states another
sigma than the real one; per-component sigmas are written as
``sigma_dx..sigma_rz``.

Units N, mm, rad; wrench order Fx Fy Fz Mx My Mz, twist dx dy dz rx ry rz,
world axes at the end-effector point (the frame of ``puu.yaml``).
"""
from __future__ import annotations

import copy
import csv
import os
from dataclasses import dataclass, field

import numpy as np
import yaml

import vjm
from vjm.modelio.read import model_from_dict
from vjm.stiffness import nonlinear

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PUU = os.path.join(ROOT, "data", "orthoglide", "puu.yaml")
#: the 3-PRPaR: the 3-PUU's actuators, workspace and leg inverse kinematics, parallelogram legs
PRPAR = os.path.join(ROOT, "data", "orthoglide", "prpar.yaml")
#: gravity direction in world axes (unit vector), as `vjm diagnose`'s weight assumes
GRAVITY = np.array([0.0, 0.0, -1.0])
#: the Orthoglide's Cartesian workspace cube Q1..Q2 (seed Fig. 4c), mm
WORKSPACE = (-73.65, 126.35)
COLUMNS = ("x", "y", "z", "Fx", "Fy", "Fz", "Mx", "My", "Mz", "dx", "dy", "dz", "rx", "ry", "rz")
MATERIALS = {"aluminium": (70_000.0, 0.33), "steel": (210_000.0, 0.30)}  # E (MPa), nu


# --- model files -----------------------------------------------------------------------------

def nominal(path: str = PUU) -> dict:
    """The mapping of ``data/orthoglide/puu.yaml`` (or of ``path``; a fresh deep copy)."""
    with open(path, encoding="utf-8") as fh:
        return yaml.safe_load(fh)


def variant(base: dict, **changes) -> dict:
    """A deep copy of a model mapping with top-level keys replaced (``foot=..., joints=...``)."""
    d = copy.deepcopy(base)
    for k, v in changes.items():
        d[k] = copy.deepcopy(v)
    return d


def build(d: dict) -> vjm.Model:
    """A vjm Model from a model-file mapping (paths relative to data/orthoglide)."""
    return model_from_dict(copy.deepcopy(d), os.path.dirname(PUU))


def write_model(d: dict, path) -> str:
    """Write a model mapping as a YAML model file; returns the path."""
    with open(path, "w", encoding="utf-8") as fh:
        yaml.safe_dump(d, fh, sort_keys=False)
    return str(path)


# --- link compliances written out (Timoshenko cantilever, seed eq. 14 + shear) ---------------

def rect_torsion_constant(a: float, b: float) -> float:
    """Saint-Venant J of a solid a x b rectangle, series of Timoshenko & Goodier (a >= b)."""
    a, b = max(a, b), min(a, b)
    n = np.arange(1, 200, 2, dtype=float)
    return a * b**3 / 3.0 * (1.0 - 192.0 / np.pi**5 * (b / a) * np.sum(np.tanh(n * np.pi * a / (2 * b)) / n**5))


def rect_beam_compliance(length, width, height, material="aluminium", twist=True, coupling=True,
                         soft=None) -> np.ndarray:
    """Tip compliance (tip frame, x along the beam, width along y) of a clamped rectangular beam.

    ``twist=False``: a link that bends but does not twist (torsion 1e-4 of the
    beam's); ``coupling=False``: the bending couplings c26, c35 left out (a
    model without translation-rotation coupling); ``soft``: compliance
    multipliers of the section's rigidities, keys ``axial`` (1/EA),
    ``bending_y`` (1/EIy: c33's bending part, c35, c55), ``bending_z`` (1/EIz),
    ``torsion`` (1/GJ); shear is left as it is.
    """
    E, nu = MATERIALS[material]
    G = E / (2.0 * (1.0 + nu))
    f = {"axial": 1.0, "bending_y": 1.0, "bending_z": 1.0, "torsion": 1.0, **(soft or {})}
    L, A = float(length), width * height
    EA, GJ = E * A / f["axial"], G * rect_torsion_constant(width, height) / f["torsion"]
    EIy, EIz = E * width * height**3 / 12.0 / f["bending_y"], E * height * width**3 / 12.0 / f["bending_z"]
    kA = 10.0 * (1.0 + nu) / (12.0 + 11.0 * nu) * A  # Cowper's shear area of a rectangle
    C = np.zeros((6, 6))
    C[0, 0] = L / EA
    C[1, 1] = L**3 / (3 * EIz) + L / (G * kA)
    C[2, 2] = L**3 / (3 * EIy) + L / (G * kA)
    C[3, 3] = L / GJ * (1.0 if twist else 1e-4)
    C[4, 4] = L / EIy
    C[5, 5] = L / EIz
    if coupling:
        # right-handed: a tip force Fy turns the tip by +rz, Fz by -ry
        C[1, 5] = C[5, 1] = L**2 / (2 * EIz)
        C[2, 4] = C[4, 2] = -(L**2) / (2 * EIy)
    return C


def inline(C) -> dict:
    """A ``{compliance: 6x6}`` link entry."""
    return {"compliance": np.asarray(C, dtype=float).tolist()}


# --- 3-PUU kinematics written out ------------------------------------------------------------

def actuator_coordinates(P, L: float) -> np.ndarray:
    """Rigid inverse kinematics of the 3-PUU (n, 3): ``q_i = p_i + L - sqrt(L^2 - |p|^2 + p_i^2)``.

    Actuator i moves along world axis i; q = 0 at the isotropic posture p = 0.
    """
    P = np.atleast_2d(np.asarray(P, dtype=float))
    s = L**2 - np.sum(P**2, axis=1, keepdims=True) + P**2
    if np.any(s <= 0):
        raise ValueError("unreachable posture")
    return P + L - np.sqrt(s)


def actuator_jacobian(P, L: float) -> np.ndarray:
    """``J = dq/dp`` (n, 3, 3): ``J_ii = 1``, ``J_ij = p_j / sqrt(L^2 - |p|^2 + p_i^2)``."""
    P = np.atleast_2d(np.asarray(P, dtype=float))
    s = np.sqrt(L**2 - np.sum(P**2, axis=1, keepdims=True) + P**2)  # (n, 3): one root per leg i
    J = P[:, None, :] / s[:, :, None]
    idx = np.arange(3)
    J[:, idx, idx] = 1.0
    return J


def actuator_forces(P, W, L: float) -> np.ndarray:
    """Force of each actuator (n, 3), N, positive when the load pushes it towards increasing q.

    Virtual work of a stress-free actuator motion: ``F . dp = tau . dq`` with
    ``dq = J dp``, so ``tau = J^-T F``; moments do not load the actuators.
    """
    J = actuator_jacobian(P, L)
    F = np.broadcast_to(np.asarray(W, dtype=float), (J.shape[0], 6))[:, :3]
    return np.linalg.solve(np.swapaxes(J, 1, 2), F[:, :, None])[:, :, 0]


def slip_twist(P, e, L: float) -> np.ndarray:
    """Platform twist (n, 6) when the actuators slip by ``e`` (n, 3) mm: ``dp = J^-1 e``, no rotation."""
    J = actuator_jacobian(P, L)
    out = np.zeros((J.shape[0], 6))
    out[:, :3] = np.linalg.solve(J, np.asarray(e, dtype=float)[:, :, None])[:, :, 0]
    return out


def reachable(P, L: float) -> np.ndarray:
    P = np.atleast_2d(P)
    return np.all(L**2 - np.sum(P**2, axis=1, keepdims=True) + P**2 > 0.05 * L**2, axis=1)


# --- the true machine ------------------------------------------------------------------------

@dataclass(frozen=True)
class Truth:
    """A true machine: a model mapping solved by vjm plus additive terms written out here.

    Attributes
    ----------
    model : model-file mapping of the true springs (see :func:`nominal`, :func:`variant`)
    nonlinear : solve the springs by :mod:`vjm.stiffness.nonlinear` (finite rotations) instead of ``C w``
    weight : N, a weight on the platform along ``GRAVITY`` (>= 0)
    backlash : mm, each actuator slips by this in the direction of its force
    backlash_sign : ``"applied"`` (sign of the applied load's actuator force) or ``"total"``
        (applied load plus weight)
    joint_backlash : rad, each U joint tilts by this about its constrained direction, toward
        the moment the applied load puts there
    hysteresis : dimensionless, fraction of the previous load's elastic deflection (same
        posture, file order) that remains (out of library)
    contact : mm / N^(2/3), translation ``contact |F|^(2/3) F/|F|`` (out of library)
    softening : mm / N^2, each actuator's drive gives way by ``softening tau |tau|`` besides its
        linear spring: a spring that softens with its force (out of library; it shows as a
        compliance that grows with the load magnitude)
    """

    model: dict = field(default_factory=nominal)
    nonlinear: bool = False
    weight: float = 0.0
    backlash: float = 0.0
    backlash_sign: str = "applied"
    joint_backlash: float = 0.0
    hysteresis: float = 0.0
    contact: float = 0.0
    softening: float = 0.0

    def vjm_model(self) -> vjm.Model:
        return build(self.model)

    @property
    def L(self) -> float:
        return float(self.model["geometry"]["L"])


def elastic(truth: Truth, P, W) -> np.ndarray:
    """Deflection (n, 6) of the true springs under W + weight (linear C w or nonlinear equilibrium)."""
    m = truth.vjm_model()
    P = np.asarray(P, dtype=float)
    Wt = np.array(np.broadcast_to(np.asarray(W, dtype=float), (len(P), 6)))
    Wt[:, :3] += truth.weight * GRAVITY
    if truth.nonlinear:
        return nonlinear.deflection_map(m, P, Wt)
    U, inv = np.unique(P, axis=0, return_inverse=True)
    C = m.stiffness_map(U).C[inv.ravel()]
    return np.einsum("nij,nj->ni", C, Wt)


def backlash_twist(truth: Truth, P, W) -> np.ndarray:
    """(n, 6) platform twist of the actuators' backlash (zero where an actuator carries no force)."""
    W = np.array(np.broadcast_to(np.asarray(W, dtype=float), (len(P), 6)))
    if truth.backlash_sign == "total":
        W[:, :3] += truth.weight * GRAVITY
    tau = actuator_forces(P, W, truth.L)
    tol = 1e-9 * max(np.max(np.abs(tau)), 1e-300)
    e = truth.backlash * np.where(np.abs(tau) > tol, np.sign(tau), 0.0)
    return slip_twist(P, e, truth.L)


#: joint springs stiff enough that the joints are ideal to ~1e-8 (a steel leg's torsion: ~4e-7 rad/(N mm))
JOINT_STIFF = 1e13  # N mm/rad


def joint_slip_twist(truth: Truth, P, W) -> np.ndarray:
    """(n, 6) platform twist of the passive joints' clearance (the 3-PUU's U joints, the 3-PRPaR's
    pivots), zero slip where a joint carries no moment."""
    m = build(variant(truth.model, joints={"passive_stiffness": JOINT_STIFF}))
    ideal = {s.name for ch in build(variant(truth.model, joints={"passive_stiffness": None})).chains for s in ch.springs}
    joints = sorted({s.name for ch in m.chains for s in ch.springs} - ideal)
    P = np.asarray(P, dtype=float)
    W = np.array(np.broadcast_to(np.asarray(W, dtype=float), (len(P), 6)))
    _, info = nonlinear.deflection_map(m, P, W, return_info=True)
    rot = {j: np.stack([info["springs"][c][j][:, 0] for c in range(len(info["springs"]))], axis=1) for j in joints}
    tol = 1e-9 * max(max(np.abs(r).max() for r in rot.values()), 1e-300)
    slip = {j: (truth.joint_backlash * np.where(np.abs(r) > tol, np.sign(r), 0.0))[:, :, None] for j, r in rot.items()}
    return nonlinear.deflection_map(m, P, np.zeros_like(W), offsets=slip)


def contact_twist(truth: Truth, W) -> np.ndarray:
    """(n, 6) Hertz-like contact at the tool: ``contact |F|^(2/3)`` along F (stiffens with load)."""
    F = np.asarray(W, dtype=float)[:, :3]
    f = np.linalg.norm(F, axis=1, keepdims=True)
    out = np.zeros((len(F), 6))
    out[:, :3] = truth.contact * np.cbrt(f) ** 2 * np.divide(F, f, out=np.zeros_like(F), where=f > 0)
    return out


def softening_twist(truth: Truth, P, W) -> np.ndarray:
    """(n, 6) platform twist of actuators that soften with their force: slip ``softening tau |tau|``
    (mm), ``tau`` the actuator force of the applied load (:func:`actuator_forces`)."""
    tau = actuator_forces(P, W, truth.L)
    return slip_twist(P, truth.softening * tau * np.abs(tau), truth.L)


def hysteresis_twist(truth: Truth, P, W, t_elastic_applied) -> np.ndarray:
    """(n, 6) remnant of the previous row's elastic deflection at the same posture (rows in file order)."""
    out = np.zeros_like(t_elastic_applied)
    for k in range(1, len(P)):
        if np.array_equal(P[k], P[k - 1]):
            out[k] = truth.hysteresis * t_elastic_applied[k - 1]
    return out


def deflections(truth: Truth, P, W) -> np.ndarray:
    """True (noise-free) twists (n, 6), mm and rad, of the rows (P, W) measured in that order."""
    P = np.asarray(P, dtype=float)
    W = np.asarray(W, dtype=float)
    t = elastic(truth, P, W)
    if truth.backlash:
        t = t + backlash_twist(truth, P, W)
    if truth.joint_backlash:
        t = t + joint_slip_twist(truth, P, W)
    if truth.contact:
        t = t + contact_twist(truth, W)
    if truth.softening:
        t = t + softening_twist(truth, P, W)
    if truth.hysteresis:
        t0 = elastic(Truth(truth.model, truth.nonlinear), P, W)  # the applied load's own deflection, no weight
        t = t + hysteresis_twist(truth, P, W, t0)
    return t


# --- designs ---------------------------------------------------------------------------------

def postures(n: int, rng, box=WORKSPACE, L: float = 310.0) -> np.ndarray:
    """n uniform random postures (n, 3) of the cube ``box`` that the legs reach comfortably."""
    lo, hi = box
    out = np.empty((0, 3))
    while len(out) < n:
        Q = lo + (hi - lo) * rng.random((4 * n, 3))
        out = np.vstack([out, Q[reachable(Q, L)]])
    return out[:n]


def loads(k: int, rng, force: float = 100.0, moment: float = 5000.0, forces_only: bool = False,
          spread: tuple = (0.2, 1.0)) -> np.ndarray:
    """k wrenches (k, 6) in opposite pairs (w, -w): random force, moment and combined directions.

    Magnitudes uniform in ``spread`` x (force, moment), so that effects that are not
    linear in the load show.  ``forces_only``: no moments (a rig without torque arms).
    """
    out = []
    for j in range((k + 1) // 2):
        kind = "force" if forces_only else ("force", "moment", "both")[j % 3]
        w = np.zeros(6)
        a = rng.uniform(*spread)
        if kind in ("force", "both"):
            u = rng.standard_normal(3)
            w[:3] = a * force * u / np.linalg.norm(u)
        if kind in ("moment", "both"):
            u = rng.standard_normal(3)
            w[3:] = a * moment * u / np.linalg.norm(u)
        out += [w, -w]
    return np.array(out[:k])


def design(n_postures: int, n_loads: int, seed: int, box=WORKSPACE, **load_kw):
    """Rows (P, W): ``n_postures`` random postures x ``n_loads`` loads each (drawn per posture)."""
    rng = np.random.default_rng(seed)
    P0 = postures(n_postures, rng, box)
    P = np.repeat(P0, n_loads, axis=0)
    W = np.concatenate([loads(n_loads, rng, **load_kw) for _ in P0])
    return P, W


def level_design(n_postures: int, n_dirs: int, seed: int, levels=(0.5, 1.0), box=WORKSPACE, **load_kw):
    """Rows (P, W) with several load levels: ``n_postures`` random postures, at each ``n_dirs``
    loads (opposite pairs, full magnitude 100 N / 5000 N mm unless ``force``/``moment`` say
    otherwise) applied at every factor of ``levels``: the same posture and direction at each
    magnitude."""
    rng = np.random.default_rng(seed)
    P0 = postures(n_postures, rng, box)
    L0 = [loads(n_dirs, rng, spread=(1.0, 1.0), **load_kw) for _ in P0]
    W = np.concatenate([np.concatenate([a * L for a in levels]) for L in L0])
    return np.repeat(P0, n_dirs * len(levels), axis=0), W


# --- measurements ----------------------------------------------------------------------------

@dataclass(frozen=True)
class Measurements:
    """Rows of a measurement file: P (n, 3), W (n, 6), T (n, 6) (NaN = not measured), sigmas or None.

    ``sigma``: (n, 6) per-component stated sigmas (columns ``sigma_dx..sigma_rz``) instead of
    ``sigma_t``/``sigma_r``; NaN where a component is not measured."""

    P: np.ndarray
    W: np.ndarray
    T: np.ndarray
    sigma_t: float | None
    sigma_r: float | None
    sigma: np.ndarray | None = None

    def write(self, path) -> str:
        """The README's CSV: ``x,y,z,Fx..Mz,dx..rz[,sigma_t[,sigma_r] | ,sigma_dx..sigma_rz]``; blank = not measured."""
        cols = list(COLUMNS)
        sig = [] if self.sigma_t is None else [self.sigma_t] + ([] if self.sigma_r is None else [self.sigma_r])
        cols += ["sigma_t", "sigma_r"][:len(sig)]  # no sigma_r column when rotations were not measured
        per = [] if self.sigma is None else [j for j in range(6) if np.isfinite(self.sigma[:, j]).any()]
        cols += ["sigma_" + COLUMNS[9 + j] for j in per]
        tmp = f"{path}.tmp"
        with open(tmp, "w", newline="", encoding="utf-8") as fh:
            wr = csv.writer(fh)
            wr.writerow(cols)
            for k, (p, w, t) in enumerate(zip(self.P, self.W, self.T)):
                rec = [repr(float(v)) for v in (*p, *w)] + ["" if np.isnan(v) else repr(float(v)) for v in t]
                rec += [repr(float(v)) for v in sig]
                rec += ["" if np.isnan(self.sigma[k, j]) else repr(float(self.sigma[k, j])) for j in per]
                wr.writerow(rec)
        os.replace(tmp, path)
        return str(path)

    def __add__(self, other: "Measurements") -> "Measurements":
        sig = None if self.sigma is None or other.sigma is None else np.vstack([self.sigma, other.sigma])
        return Measurements(np.vstack([self.P, other.P]), np.vstack([self.W, other.W]),
                            np.vstack([self.T, other.T]), self.sigma_t, self.sigma_r, sig)


def tracker_sigma(P, origin, a, b) -> np.ndarray:
    """(n, 3) standard deviation of a laser tracker's dx, dy, dz at points P (mm) seen from ``origin``:
    ``sqrt(a^2 + (b d)^2)`` per axis, d the distance (mm); ``a`` (mm) and ``b`` (mm per mm) scalars or
    one per axis (the angle encoders' noise grows with the distance, the range meter's less)."""
    d = np.linalg.norm(np.asarray(P, float) - np.asarray(origin, float), axis=1)
    return np.sqrt(np.asarray(a, float) ** 2 + (np.asarray(b, float) * d[:, None]) ** 2) * np.ones((1, 3))


def measure(truth: Truth, P, W, seed: int, sigma_t: float = 1e-3, sigma_r: float | None = 1e-5,
            known_sigmas: bool = True, repeats: int = 1, axis_factor=None, tracker=None,
            stated_factor: float = 1.0, per_component: bool = False) -> Measurements:
    """Noisy measurements of ``truth`` at rows (P, W).

    ``sigma_r=None``: rotations not measured (blank).  ``known_sigmas=False``:
    no sigma columns; use ``repeats >= 2`` so that the file holds pure error
    (each row measured ``repeats`` times in a row, independent noise).

    Defects of the noise, made here: ``axis_factor`` (6,) multiplies the real noise of each
    component (dx..rz); ``tracker = (origin, a, b)`` makes the translations' real noise a laser
    tracker's (:func:`tracker_sigma`); ``stated_factor`` is the stated sigma over the real one (0.5:
    the file states half the real noise).  With ``axis_factor``, ``tracker`` or ``per_component`` the
    stated sigmas are written per component (``sigma_dx..sigma_rz``), else as ``sigma_t``/``sigma_r``.
    """
    P = np.repeat(np.asarray(P, dtype=float), repeats, axis=0)
    W = np.repeat(np.asarray(W, dtype=float), repeats, axis=0)
    T = deflections(truth, P, W)
    rng = np.random.default_rng(seed)
    sd = np.empty((len(P), 6))
    sd[:, :3] = sigma_t if tracker is None else tracker_sigma(P, *tracker)
    sd[:, 3:] = np.nan if sigma_r is None else sigma_r
    if axis_factor is not None:
        sd = sd * np.asarray(axis_factor, float)
    T[:, :3] += sd[:, :3] * rng.standard_normal((len(P), 3))
    if sigma_r is None:
        T[:, 3:] = np.nan
    else:
        T[:, 3:] += sd[:, 3:] * rng.standard_normal((len(P), 3))
    if not known_sigmas:
        return Measurements(P, W, T, None, None)
    if axis_factor is not None or tracker is not None or per_component:
        return Measurements(P, W, T, None, None, stated_factor * sd)
    return Measurements(P, W, T, stated_factor * sigma_t, None if sigma_r is None else stated_factor * sigma_r)


def with_outliers(m: Measurements, fraction: float, rng, size=(20.0, 60.0), sigma_t: float = 1e-3,
                  sigma_r: float = 1e-5) -> tuple[Measurements, np.ndarray]:
    """``m`` with gross errors: ``round(fraction n)`` rows, each with one measured component off by
    ``size`` (uniform, random sign) times its noise sigma (the file's, else ``sigma_t``/``sigma_r``);
    and the sorted positions (0-based) of the rows changed (file row = position + 2)."""
    n = len(m.P)
    rows = np.sort(rng.choice(n, int(round(fraction * n)), replace=False))
    st = sigma_t if m.sigma_t is None else m.sigma_t
    sr = sigma_r if m.sigma_r is None else m.sigma_r
    T = m.T.copy()
    for r in rows:
        c = rng.choice(np.flatnonzero(np.isfinite(T[r])))
        T[r, c] += rng.choice([-1.0, 1.0]) * rng.uniform(*size) * (st if c < 3 else sr)
    return Measurements(m.P, m.W, T, m.sigma_t, m.sigma_r), rows


def read_rows(path) -> tuple[np.ndarray, np.ndarray]:
    """(P, W) of a CSV with columns x,y,z,Fx..Mz (e.g. ``next_measurements.csv``), '#' lines skipped."""
    with open(path, newline="", encoding="utf-8") as fh:
        rows = [r for r in csv.reader(fh) if r and not r[0].lstrip().startswith("#")]
    hdr = [h.strip() for h in rows[0]]
    cols = [hdr.index(c) for c in COLUMNS[:9]]
    A = np.array([[float(r[c]) for c in cols] for r in rows[1:]], dtype=float).reshape(-1, 9)
    return A[:, :3], A[:, 3:]


# --- library effects hidden in a true machine ------------------------------------------------
# The model file given to the diagnosis, per case: puu.yaml, or puu.yaml with a rigid foot, with
# a foot compliance that lacks the bending couplings c26, c35, or with a slender foot (10 x 20
# section) whose bending about its z axis shows; for the parallelogram bar's effects prpar.yaml.
NOMINAL = nominal()
PRPAR_NOMINAL = nominal(PRPAR)
FOOT = (50.0, 60.0, 10.0)   # puu.yaml's foot: length, width (y), height (z), aluminium
SLENDER_FOOT = (50.0, 10.0, 20.0)
LEG = (310.0, 30.0, 10.0)   # puu.yaml's leg
BAR = (310.0, 30.0, 5.0)    # prpar.yaml's bar, one of the two of each parallelogram
MODELS = {
    "puu": NOMINAL,
    "rigid_foot": variant(NOMINAL, foot={"rigid": True}),
    "uncoupled_foot": variant(NOMINAL, foot=inline(rect_beam_compliance(*FOOT, coupling=False))),
    "slender_foot": variant(NOMINAL, foot=inline(rect_beam_compliance(*SLENDER_FOOT))),
    "prpar": PRPAR_NOMINAL,
}
#: the machine each model given stands for (its nominal mapping is the true machine's start)
MACHINE = {"prpar": "prpar"}
BASES = {"puu": NOMINAL, "prpar": PRPAR_NOMINAL}
#: the acceptance design of each machine (:func:`design` arguments).  The 3-PRPaR's: 12 postures
#: (its compliance costs ~10 x the 3-PUU's) and moments up to 20 N m (a 200 mm torque arm at
#: 100 N), so that its bar's torsion, which the parallelogram carries mostly by axial bar
#: forces, shows at all.
DESIGNS = {"puu": {"n_postures": 24, "n_loads": 12, "seed": 11},
           "prpar": {"n_postures": 12, "n_loads": 12, "seed": 12, "moment": 20_000.0}}


def _foot(s):      # a real foot: a bracket 40 x 16, 90 long (not the leg's proportions), s x as compliant
    return {"foot": inline(s * rect_beam_compliance(90.0, 40.0, 16.0))}, {}


def _foot_shape(x):  # "a foot is missing": a bracket of unknown section rigidities and length
    soft = dict(zip(("axial", "bending_y", "bending_z", "torsion"), np.exp(x[:4])))
    return {"foot": inline(rect_beam_compliance(90.0 * np.exp(x[4]), 40.0, 16.0, soft=soft))}


def _coupling(key, dims):
    """``key``'s c26, c35 at s x their beam value (the beam's other terms kept)."""
    def make(s):
        C = rect_beam_compliance(*dims)
        C[1, 5] *= s
        C[5, 1] *= s
        C[2, 4] *= s
        C[4, 2] *= s
        return {key: inline(C)}, {}
    return make


def _soft(key, dims, mode):
    """``key``'s section rigidity of ``mode`` divided by 1 + s: that mode (1 + s) x as compliant, shear kept."""
    return lambda s: ({key: inline(rect_beam_compliance(*dims, soft={mode: 1.0 + s}))}, {})


def _extension_torsion(key, dims):
    """``key``'s beam with an extension-torsion coupling ``c14 = c41 = s sqrt(c11 c44)`` (a pretwisted link)."""
    def make(s):
        C = rect_beam_compliance(*dims)
        C[0, 3] = C[3, 0] = s * np.sqrt(C[0, 0] * C[3, 3])
        return {key: inline(C)}, {}
    return make


def _slope(s):     # actuator compliance c(q) = c0 (1 + s q), s per mm, q_ref = 0 (the isotropic posture)
    k = NOMINAL["actuator"]["stiffness"]
    return {"actuator": {"stiffness": k, "compliance_slope": s / k, "q_ref": 0.0}}, {}


@dataclass(frozen=True)
class Hidden:
    """A library effect as a true machine shows it: ``make(size) -> (model-file changes, Truth terms)``.

    ``seen``: whether, at ``size`` on its machine's acceptance design (:data:`DESIGNS`), the true
    machine differs from the model given by more than the noise can hide, once the model given
    has refit its calibration (:func:`signature_chi2`); the tests check this claim on the truth
    before they hold the diagnosis to it.
    """

    model: str       # key of MODELS: the model file given to the diagnosis
    size: float      # the size used by the acceptance tests
    unit: str
    make: object
    seen: bool = True
    #: the effect with all the freedom a user's question leaves it (:func:`on_top_chi2`):
    #: ``shape(x) -> model-file changes`` over ``len(shape_start)`` log-parameters; None: its size
    shape: object = None
    shape_start: tuple = ()

    @property
    def machine(self) -> str:
        return MACHINE.get(self.model, "puu")


LIBRARY = {
    "foot_compliance": Hidden("rigid_foot", 1.0, "x bracket 40x16x90 alu", _foot, shape=_foot_shape,
                              shape_start=(0.0,) * 5),
    "foot_bending_coupling": Hidden("uncoupled_foot", 1.0, "x beam c26, c35", _coupling("foot", FOOT)),
    "foot_torsion": Hidden("puu", 0.3, "extra x foot torsion compliance", _soft("foot", FOOT, "torsion")),
    "leg_torsion": Hidden("puu", 0.05, "extra x leg torsion compliance", _soft("leg", LEG, "torsion")),
    "passive_joint_compliance": Hidden("puu", 1e-8, "rad/(N mm)",
                                       lambda s: ({"joints": {"passive_stiffness": 1.0 / s}}, {})),
    "actuator_travel_stiffness": Hidden("puu", 2e-3, "1/mm", _slope),
    "clearance": Hidden("puu", 2e-3, "mm", lambda s: ({}, {"backlash": s})),
    "passive_clearance": Hidden("puu", 2e-5, "rad", lambda s: ({}, {"joint_backlash": s})),
    "gravity": Hidden("puu", 3.0, "N", lambda s: ({}, {"weight": s})),
    "geometric_nonlinearity": Hidden("puu", 1.0, "x (100 N, 5000 N mm) loads",
                                     lambda s: ({}, {"nonlinear": True})),
    # one deformation mode of a link, its section rigidity divided by 1 + size; couplings written in
    # the beam's compliance.  Not seen: the foot's axial compliance is in series with the actuator
    # along the same axis at every posture (the calibration's actuator scale takes it whole); the
    # leg's bending about y and its c26, c35 carry no load between the two U joints.
    "foot_axial": Hidden("puu", 19.0, "extra x foot axial compliance", _soft("foot", FOOT, "axial"), seen=False),
    "foot_bending_y": Hidden("puu", 0.7, "extra x foot bending-y compliance", _soft("foot", FOOT, "bending_y")),
    "foot_bending_z": Hidden("slender_foot", 1.5, "extra x foot bending-z compliance",
                             _soft("foot", SLENDER_FOOT, "bending_z")),
    "foot_extension_torsion": Hidden("puu", 0.5, "c14 / sqrt(c11 c44)", _extension_torsion("foot", FOOT)),
    "leg_axial": Hidden("puu", 16.0, "extra x leg axial compliance", _soft("leg", LEG, "axial")),
    "leg_bending_y": Hidden("puu", 19.0, "extra x leg bending-y compliance", _soft("leg", LEG, "bending_y"),
                            seen=False),
    "leg_bending_z": Hidden("puu", 0.7, "extra x leg bending-z compliance", _soft("leg", LEG, "bending_z")),
    "leg_bending_coupling": Hidden("puu", 0.0, "x beam c26, c35", _coupling("leg", LEG), seen=False),
    "leg_extension_torsion": Hidden("puu", 0.035, "c14 / sqrt(c11 c44)", _extension_torsion("leg", LEG)),
    # the 3-PRPaR's parallelogram bar (both bars of every leg); bending about y (the pivots' axis)
    # is released by the pivots
    "bar_axial": Hidden("prpar", 1.0, "extra x bar axial compliance", _soft("leg", BAR, "axial")),
    "bar_bending_y": Hidden("prpar", 19.0, "extra x bar bending-y compliance", _soft("leg", BAR, "bending_y"),
                            seen=False),
    "bar_bending_z": Hidden("prpar", 0.15, "extra x bar bending-z compliance", _soft("leg", BAR, "bending_z")),
    "bar_torsion": Hidden("prpar", 1.0, "extra x bar torsion compliance", _soft("leg", BAR, "torsion")),
    "bar_bending_coupling": Hidden("prpar", 0.97, "x beam c26, c35", _coupling("leg", BAR)),
    "bar_extension_torsion": Hidden("prpar", 0.6, "c14 / sqrt(c11 c44)", _extension_torsion("leg", BAR)),
}


def hide(*effects) -> tuple[dict, Truth]:
    """(model mapping given to the diagnosis, true machine) with library effects hidden.

    ``effects``: names of :data:`LIBRARY` or ``(name, size)`` pairs.  The model given is
    puu.yaml unless one effect needs another (a rigid foot, a foot without couplings, a
    slender foot, prpar.yaml); two effects that need different models given, or that both
    change the same part of the true model file (e.g. two foot effects), are refused.
    """
    items = [(e, LIBRARY[e].size) if isinstance(e, str) else e for e in effects]
    keys = {LIBRARY[n].model for n, _ in items} - {"puu"}
    if len(keys) > 1:
        raise ValueError(f"effects {[n for n, _ in items]} need different model files ({sorted(keys)})")
    key = keys.pop() if keys else "puu"
    return MODELS[key], true_machine(items, MACHINE.get(key, "puu"))


def true_machine(items, machine: str = "puu") -> Truth:
    """The true ``machine`` ("puu" or "prpar") with the effects ``items`` ((name, size) pairs) hidden."""
    true_model, kw, changed = dict(BASES[machine]), {}, set()
    for n, s in items:
        changes, terms = LIBRARY[n].make(s)
        if changed & (set(changes) | set(terms)):
            raise ValueError(f"effects {[n for n, _ in items]} change the same part of the machine")
        changed |= set(changes) | set(terms)
        true_model.update(changes)
        kw.update(terms)
    return Truth(variant(true_model), **kw)


def pairs() -> list[tuple[str, str]]:
    """Every pair of seen LIBRARY effects that can be hidden together."""
    out = []
    names = [n for n, h in LIBRARY.items() if h.seen]
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            try:
                hide(a, b)
            except ValueError:
                continue
            out.append((a, b))
    return out


def acceptance_rows(name: str) -> tuple[np.ndarray, np.ndarray]:
    """(P, W) of the acceptance design of the machine effect ``name`` is hidden in."""
    return design(**DESIGNS[LIBRARY[name].machine])


# --- what the data can see of a true machine ---------------------------------------------------

def calibrated(given: dict, actuator_scale: float, link_scale: float) -> dict:
    """``given`` with its nominal parameters changed as the diagnosis' calibration changes them:
    actuator stiffness x ``actuator_scale``; foot and leg compliances x ``link_scale`` in extension
    and bending (terms with torsion x its root, torsion kept), written out on vjm's 6x6 matrices."""
    m = build(given)
    d = np.where(np.arange(6) == 3, 1.0, np.sqrt(link_scale))
    links = {k: inline(getattr(m, k).compliance * np.outer(d, d))
             for k in ("foot", "leg") if getattr(m, k).compliance is not None}
    act = {**given["actuator"], "stiffness": given["actuator"]["stiffness"] * actuator_scale}
    return variant(given, actuator=act, **links)


def signature_chi2(given: dict, truth: Truth, P, W, sigma_t: float = 1e-3,
                   sigma_r: float = 1e-5) -> tuple[float, float]:
    """Chi-square of the noise-free gap between the true machine's deflections and the model
    given's (sum of (gap / sigma)^2 over the rows): as given, and after the model given's
    actuator and link scales are refit to the true deflections (least squares, the two scales
    free; what no calibration can reach).  It is the non-centrality the effect adds: far above
    the noise (hundreds) it must be named, below 1 nothing can see it."""
    from scipy.optimize import least_squares

    P, W = np.asarray(P, dtype=float), np.asarray(W, dtype=float)
    t = deflections(truth, P, W)
    w = np.array([1 / sigma_t] * 3 + [1 / sigma_r] * 3)

    def gap(x):
        return ((t - elastic(Truth(calibrated(given, *np.exp(x))), P, W)) * w).ravel()

    raw = float(np.sum(gap(np.zeros(2)) ** 2))
    fit = least_squares(gap, np.zeros(2), x_scale=0.1, xtol=1e-12, ftol=1e-12)
    return raw, float(np.sum(fit.fun ** 2))


def on_top_chi2(pair, P, W, sigma_t: float = 1e-3, sigma_r: float = 1e-5) -> dict:
    """For each effect of a hidden ``pair`` (names or ``(name, size)``, as :func:`hide`): the chi-square
    of the noise-free gap between the true machine (both hidden at their sizes) and the model
    given with only the *other* effect, at the size (or, with a ``shape``, the shape) and with the
    actuator and link scales that fit the truth best (least squares, in this module's own terms).
    What that effect shows besides the other: ~0 when the other alone, at another size or shape,
    is the pair (collinear signatures; a foot of other proportions that takes a leg's bending)."""
    import dataclasses

    from scipy.optimize import least_squares

    P, W = np.asarray(P, dtype=float), np.asarray(W, dtype=float)
    t = deflections(hide(*pair)[1], P, W)
    w = np.array([1 / sigma_t] * 3 + [1 / sigma_r] * 3)
    items = [(e, LIBRARY[e].size) if isinstance(e, str) else e for e in pair]
    # the pair's machine: each effect alone is hidden in the same machine as the pair
    machine = next((LIBRARY[n].machine for n, _ in items if LIBRARY[n].machine != "puu"), "puu")
    out = {}
    for (h, _), (other, s0) in ((items[0], items[1]), (items[1], items[0])):
        hd = LIBRARY[other]

        def gap(x, other=other, s0=s0, hd=hd):
            try:
                if hd.shape is None:
                    tro = true_machine([(other, s0 * (1.0 + x[2]))], machine)
                else:
                    tro = Truth(variant(BASES[machine], **hd.shape(x[2:])))
                tt = dataclasses.replace(tro, model=calibrated(tro.model, *np.exp(x[:2])))
                return ((t - deflections(tt, P, W)) * w).ravel()
            except vjm.VjmError:
                # a size past what the part can be (a compliance no longer positive definite): a
                # large gap, so that the trust region steps back
                return np.full(t.size, 1e6)

        x0 = np.zeros(3) if hd.shape is None else np.r_[0.0, 0.0, hd.shape_start]
        fit = least_squares(gap, x0, x_scale=0.1, xtol=1e-10, ftol=1e-10)
        out[h] = float(np.sum(fit.fun ** 2))
    return out


# --- reading a diagnosis report (report.json keys) --------------------------------------------

def accounts_for(rep: dict, name: str, named=None) -> bool:
    """``name`` is named, or a named effect stands for a confounded group that holds it
    (the report's way of saying "A or B: this data cannot tell them apart").  ``named``: the
    set of effects of one explanation (default: the report's named effects)."""
    named = rep["named_effects"] if named is None else named
    return name in named or any(name in g and any(n in g for n in named) for g in rep["confounded"])


def explanations(rep: dict) -> list:
    """The sets of effects the report offers: the named one, then the other explanations the data
    do not exclude (``alternatives``: BIC within Occam's window of the named set's)."""
    return [list(rep["named_effects"])] + [list(a["named_effects"]) for a in rep.get("alternatives", [])]


def _claims_only(rep: dict, named, hidden, at_most: bool) -> bool:
    """``named`` accounts for every hidden effect, each of its effects is a hidden one (or in a
    confounded group with one), and it names as many effects as were hidden (``at_most``: no more)."""
    n_ok = 0 < len(named) <= len(hidden) if at_most else len(named) == len(hidden)
    own = all(n in hidden or any(n in g and h in g for g in rep["confounded"] for h in hidden) for n in named)
    return n_ok and own and all(accounts_for(rep, h, named) for h in hidden)


def names_exactly(rep: dict, hidden) -> bool:
    """One explanation of the report (the named effects, or an alternative the report says the data
    support as well) accounts for every hidden effect, and each of its effects is a hidden one (or in
    a confounded group with one): nothing else is claimed."""
    return any(_claims_only(rep, named, hidden, False) for named in explanations(rep))


def names_at_group_level(rep: dict, hidden) -> bool:
    """As :func:`names_exactly`, but one named effect may stand for a confounded group that holds
    two hidden ones ("leg_extension_torsion or foot_extension_torsion: this data cannot tell them
    apart"): every hidden effect accounted for, every named one hidden or grouped with a hidden
    one, and no more effects named than were hidden."""
    return any(_claims_only(rep, named, hidden, True) for named in explanations(rep))
