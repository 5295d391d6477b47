"""Independent truth for `vjm diagnose` on other architectures: the Delta 3-RRPaR and a 6-dof hexapod.

Part of the truth generator (:mod:`truth`); nothing here uses :mod:`vjm.discrepancy`.  The
elastic deflections are the vjm model's ``C(p) w`` of the true machine's model file, as in
:mod:`truth`; the hidden effects are written out here with their own kinematics and statics:

* **Delta 3-RRPaR** (``data/orthoglide/delta.yaml``): every rotary actuator slips by ``b`` (rad)
  in the direction of its torque.  Closed-form inverse kinematics of the Delta written out
  here (:func:`delta_actuators`: arm ``i`` at ``phi_i = 0, 120, 240`` deg turns about its
  tangent axis at radius ``R``; the bar of length ``L`` joins the arm's tip to the platform
  joint at radius ``r``; elbow out), its Jacobian ``J = dq/dp`` by implicit differentiation
  of the bar-length constraint.  A slip is a rigid, stress-free motion of the translational
  Delta, so by virtual work the torques are ``tau = J^-T F`` (moments are carried by the
  parallelograms, not the actuators) and the platform moves by ``dp = J^-1 (b sign tau)``
  without rotating.
* **6-UPS hexapod** (``data/machines/hexapod_6ups.yaml``, a description file) measured at
  tilted orientations, with a platform weight whose centre of mass lies off the
  end-effector point: a weight ``m g`` at ``R c`` (``c`` in platform axes, ``R`` the
  platform's rotation, Rodrigues' formula written out here) puts the wrench ``(m g, (R c) x
  m g)`` on the end-effector point.  With ``c`` along the platform's z axis, a level
  platform feels no moment; the moment grows with the tilt.

Units N, mm, rad; poses of the hexapod ``x, y, z, ox, oy, oz`` (rotation vector, rad, world
axes, as ``vjm stiffness --at`` and the measurement file's ``ox,oy,oz`` columns).
"""
from __future__ import annotations

import csv
import os
from dataclasses import dataclass

import numpy as np
import truth as tr

import vjm

DELTA = os.path.join(tr.ROOT, "data", "orthoglide", "delta.yaml")
HEXAPOD = os.path.join(tr.ROOT, "data", "machines", "hexapod_6ups.yaml")
DELTA_PHI = np.radians([0.0, 120.0, 240.0])


# --- Delta 3-RRPaR kinematics written out -----------------------------------------------------

def _delta_local(P, geo, i):
    """Platform joint B (n, 3) and arm basis of arm i: radial, tangent, up coordinates."""
    phi = DELTA_PHI[i]
    er, et = np.array([np.cos(phi), np.sin(phi), 0.0]), np.array([-np.sin(phi), np.cos(phi), 0.0])
    B = np.stack([P @ er + geo["r"], P @ et, P[:, 2]], axis=1)
    return B, np.stack([er, et, [0.0, 0.0, 1.0]])


def delta_actuators(P, geo) -> np.ndarray:
    """Arm angles q (n, 3), rad (down from the horizontal), elbow out: ``|B - E(q)| = L`` with the
    elbow ``E = (R + a cos q, 0, -a sin q)`` in the arm's radial, tangent, up coordinates."""
    P = np.atleast_2d(np.asarray(P, float))
    R, a, L = geo["R"], geo["arm"], geo["L"]
    out = np.empty((len(P), 3))
    for i in range(3):
        B, _ = _delta_local(P, geo, i)
        u, v, w = B[:, 0] - R, B[:, 1], B[:, 2]
        # -2 u a cos q + 2 w a sin q = L^2 - u^2 - v^2 - w^2 - a^2 =: K
        A, Bs, K = -2 * u * a, 2 * w * a, L**2 - u**2 - v**2 - w**2 - a**2
        rho = np.hypot(A, Bs)
        if np.any(np.abs(K) > rho):
            raise ValueError("unreachable posture")
        base, d = np.arctan2(Bs, A), np.arccos(K / rho)
        q1, q2 = base + d, base - d
        out[:, i] = np.where(np.cos(q1) >= np.cos(q2), q1, q2)  # elbow out: the tip farther out
    return out


def delta_jacobian(P, geo) -> np.ndarray:
    """``J = dq/dp`` (n, 3, 3) from ``f = |B - E(q)|^2 - L^2 = 0``: ``dq/dp = -(df/dp) / (df/dq)``."""
    P = np.atleast_2d(np.asarray(P, float))
    q = delta_actuators(P, geo)
    R, a = geo["R"], geo["arm"]
    J = np.empty((len(P), 3, 3))
    for i in range(3):
        B, basis = _delta_local(P, geo, i)
        E = np.stack([R + a * np.cos(q[:, i]), 0 * q[:, i], -a * np.sin(q[:, i])], axis=1)
        dE = np.stack([-a * np.sin(q[:, i]), 0 * q[:, i], -a * np.cos(q[:, i])], axis=1)
        d = B - E
        J[:, i, :] = -(d @ basis) / np.einsum("nj,nj->n", -d, dE)[:, None]
    return J


def delta_backlash_twist(P, W, b: float, geo) -> tuple[np.ndarray, np.ndarray]:
    """(platform twist (n, 6), arm torques (n, 3) N mm) when every arm slips by ``b`` rad toward
    its torque ``tau = J^-T F``."""
    J = delta_jacobian(P, geo)
    F = np.asarray(W, float)[:, :3]
    tau = np.linalg.solve(np.swapaxes(J, 1, 2), F[:, :, None])[:, :, 0]
    tol = 1e-9 * max(np.max(np.abs(tau)), 1e-300)
    e = b * np.where(np.abs(tau) > tol, np.sign(tau), 0.0)
    out = np.zeros((len(P), 6))
    out[:, :3] = np.linalg.solve(J, e[:, :, None])[:, :, 0]
    return out, tau


def delta_reachable(P, geo, margin: float = 0.05) -> np.ndarray:
    """(n,) the arms reach every posture with angles inside +-(90 deg - margin)."""
    out = []
    for p in np.atleast_2d(np.asarray(P, float)):
        try:
            out.append(bool(np.all(np.abs(delta_actuators(p[None], geo)) < np.pi / 2 - margin)))
        except ValueError:
            out.append(False)
    return np.array(out, bool)


def delta_design(n_postures: int, n_loads: int, seed: int, box=((-120, -120, -560), (120, 120, -400)),
                 **load_kw):
    """Rows (P, W) of the Delta: random postures of ``box`` its arms reach, loads as :func:`truth.loads`."""
    geo = tr.nominal(DELTA)["geometry"]
    rng = np.random.default_rng(seed)
    lo, hi = (np.asarray(b, float) for b in box)
    P0 = np.empty((0, 3))
    while len(P0) < n_postures:
        Q = lo + (hi - lo) * rng.random((4 * n_postures, 3))
        ok = delta_reachable(Q, geo)
        P0 = np.vstack([P0, Q[ok]])
    P0 = P0[:n_postures]
    W = np.concatenate([tr.loads(n_loads, rng, **load_kw) for _ in P0])
    return np.repeat(P0, n_loads, axis=0), W


def delta_deflections(P, W, backlash: float = 0.0, model: dict | None = None) -> np.ndarray:
    """True twists (n, 6) of the Delta: its model file's ``C w`` plus the arms' backlash."""
    d = tr.nominal(DELTA) if model is None else model
    t = tr.elastic(tr.Truth(d), P, W)
    if backlash:
        t = t + delta_backlash_twist(P, W, backlash, d["geometry"])[0]
    return t


# --- 6-dof hexapod at tilt ---------------------------------------------------------------------

def rotation(o) -> np.ndarray:
    """Rotation matrices (n, 3, 3) of rotation vectors o (n, 3): Rodrigues' formula."""
    o = np.atleast_2d(np.asarray(o, float))
    th = np.linalg.norm(o, axis=1)
    k = o / np.where(th > 0, th, 1.0)[:, None]
    K = np.zeros((len(o), 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -k[:, 2], k[:, 1], -k[:, 0]
    K = K - np.swapaxes(K, 1, 2)
    s, c = np.sin(th)[:, None, None], np.cos(th)[:, None, None]
    return np.eye(3) + s * K + (1 - c) * K @ K


@dataclass(frozen=True)
class PlatformWeight:
    """A weight ``weight`` (N) on the platform, centre of mass at ``lever`` (mm, platform axes) from the
    end-effector point."""

    weight: float
    lever: tuple = (0.0, 0.0, 0.0)

    def wrench(self, poses) -> np.ndarray:
        """(n, 6) wrench at the end-effector point, world axes: ``(m g, (R c) x m g)``."""
        poses = np.asarray(poses, float)
        F = self.weight * tr.GRAVITY
        arm = rotation(poses[:, 3:]) @ np.asarray(self.lever, float)
        out = np.zeros((len(poses), 6))
        out[:, :3] = F
        out[:, 3:] = np.cross(arm, F)
        return out


def hexapod_deflections(poses, W, load: PlatformWeight | None = None, path: str = HEXAPOD) -> np.ndarray:
    """True twists (n, 6) of the hexapod at poses (n, 6) under W (n, 6) and the platform weight."""
    m = vjm.load_model(path)
    poses = np.asarray(poses, float)
    Wt = np.array(W, float) + (0.0 if load is None else load.wrench(poses))
    U, inv = np.unique(poses, axis=0, return_inverse=True)
    C = m.stiffness_map(U).C[inv.ravel()]
    return np.einsum("nij,nj->ni", C, Wt)


def tilted_design(n_postures: int, n_loads: int, seed: int, tilt: float = 0.1, force: float = 1000.0,
                  moment: float = 1e5, path: str = HEXAPOD):
    """Rows (poses (n, 6), W) of the hexapod: random positions of its workspace box, each with an
    orientation whose rotation-vector components are uniform in ``[-tilt, tilt]`` rad, reachable."""
    m = vjm.load_model(path)
    rng = np.random.default_rng(seed)
    lo, hi = m.workspace.lo, m.workspace.hi
    P0 = np.empty((0, 6))
    while len(P0) < n_postures:
        Q = np.hstack([lo + (hi - lo) * rng.random((4 * n_postures, 3)),
                       tilt * (2 * rng.random((4 * n_postures, 3)) - 1)])
        P0 = np.vstack([P0, Q[m.reachable(Q)]])
    P0 = P0[:n_postures]
    W = np.concatenate([tr.loads(n_loads, rng, force=force, moment=moment) for _ in P0])
    return np.repeat(P0, n_loads, axis=0), W


def noisy(T, seed: int, sigma_t: float, sigma_r: float) -> np.ndarray:
    rng = np.random.default_rng(seed)
    T = np.array(T, float)
    T[:, :3] += sigma_t * rng.standard_normal((len(T), 3))
    T[:, 3:] += sigma_r * rng.standard_normal((len(T), 3))
    return T


def write(path, poses, W, T, sigma_t: float, sigma_r: float) -> str:
    """The measurement CSV ``x,y,z[,ox,oy,oz],Fx..Mz,dx..rz,sigma_t,sigma_r`` (orientation columns for
    poses (n, 6))."""
    poses = np.asarray(poses, float)
    cols = list(tr.COLUMNS[:3]) + (["ox", "oy", "oz"] if poses.shape[1] == 6 else []) + list(tr.COLUMNS[3:])
    with open(path, "w", newline="", encoding="utf-8") as fh:
        wr = csv.writer(fh)
        wr.writerow(cols + ["sigma_t", "sigma_r"])
        for p, w, t in zip(poses, W, T):
            wr.writerow([repr(float(v)) for v in (*p, *w, *t, sigma_t, sigma_r)])
    return str(path)
