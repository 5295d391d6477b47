"""Nonlinear static equilibrium of a VJM model under a platform wrench (finite rotations).

Independent of the linear solver: no Jacobian from :mod:`vjm.chain`, no
bordered system.  Unknowns are every free joint coordinate of every chain
(virtual springs, actuator spring ``theta0``, passive joints) and the
platform pose ``(p, phi)`` with ``R = Rx(phi1) Ry(phi2) Rz(phi3) R0``.  The
equilibrium is the stationary point of

    Pi = sum_s 1/2 theta_s^T K_s theta_s  -  F . (p - p0)  -  M . phi

subject to loop closure: each chain's end frame, evaluated with the full
nonlinear product of eq. 1, coincides with the platform frame.  It is
solved by Newton's method on the Lagrange (KKT) conditions; the
constraint gradients are computed by complex-step differentiation of the
forward kinematics (exact to round-off).  The dead-load moment's work
``M . phi`` differs from the exact one by O(phi^2), an even term that
central differences in the load cancel.

Springs are those of the model at the unloaded posture (the actuator
compliance at the nominal q; a parallelogram leg keeps its equivalent
spring K_Plg of that posture, which is singular along its own mobility:
steps use least squares).  The platform's deflection returned is
``(p - p0, rotation vector of R R0^T)``, world axes, mm and rad.
"""
from __future__ import annotations

import numpy as np

from .chain import forward
from .errors import VjmError
from .transforms import elementary, rotation_vector, vee

H_CS = 1e-20  # complex step


def _plat_R(phi):
    phi = np.asarray(phi)
    R = elementary("rx", phi[0:1])[0, :3, :3] @ elementary("ry", phi[1:2])[0, :3, :3] @ elementary("rz", phi[2:3])[0, :3, :3]
    return R


class _Problem:
    def __init__(self, model, p):
        p = np.asarray(p, dtype=float).reshape(1, 3)
        q, vals = model.arch.inverse_kinematics(model, p)
        comps = model.arch.compliances(model, p, vals, q)
        self.p0 = p[0]
        self.chains = []
        nx = 0
        for ch, v, c in zip(model.chains, vals, comps):
            free, springs = [], []
            for s in ch.springs:
                C = c.get(s.name)
                if C is None:
                    continue
                C = np.asarray(C, dtype=float)
                C = C[0] if C.ndim == 3 else C
                K = np.linalg.pinv(C, hermitian=True)
                springs.append((list(s.vars), K))
                free += list(s.vars)
            free += list(ch.passive)
            free = sorted(set(free))
            T0 = forward(ch, v)[0]
            self.chains.append(dict(ch=ch, v0=v[0], free=free, springs=springs, R0=T0[:3, :3],
                                    sl=slice(nx, nx + len(free))))
            nx += len(free)
        self.nx = nx
        self.nc = 6 * len(self.chains)

    # g_c(x_c, p, phi) for a batch of complex perturbations
    def _g(self, c, X, pp, phi):
        """X (m, nfree), pp (m, 3), phi (m, 3) -> g (m, 6)."""
        m = X.shape[0]
        v = np.broadcast_to(c["v0"], (m, c["ch"].n_vars)).astype(X.dtype).copy()
        v[:, c["free"]] += X
        T = forward(c["ch"], v)
        Rp = np.stack([_plat_R(f) for f in phi]) @ c["R0"]
        M = T[:, :3, :3] @ np.swapaxes(Rp, 1, 2)
        return np.concatenate([T[:, :3, 3] - pp, vee(M)], axis=1)

    def constraints(self, x, u):
        """g (nc,) and G (nc, nx + 6) at chain coordinates x and platform u = (dp, phi)."""
        g = np.zeros(self.nc)
        G = np.zeros((self.nc, self.nx + 6))
        pp, phi = self.p0 + u[:3], u[3:]
        for k, c in enumerate(self.chains):
            xc = x[c["sl"]]
            nf = xc.size
            m = nf + 6
            X = np.tile(xc.astype(complex), (m + 1, 1))
            PP = np.tile(pp.astype(complex), (m + 1, 1))
            PH = np.tile(phi.astype(complex), (m + 1, 1))
            X[np.arange(nf), np.arange(nf)] += 1j * H_CS
            PP[nf + np.arange(3), np.arange(3)] += 1j * H_CS
            PH[nf + 3 + np.arange(3), np.arange(3)] += 1j * H_CS
            gg = self._g(c, X, PP, PH)
            rows = slice(6 * k, 6 * k + 6)
            g[rows] = gg[-1].real
            G[rows, c["sl"]] = gg[:nf].imag.T / H_CS
            G[rows, self.nx:] = gg[nf:m].imag.T / H_CS
        return g, G

    def energy_grad_hess(self, x):
        grad = np.zeros(self.nx)
        H = np.zeros((self.nx, self.nx))
        for c in self.chains:
            pos = {var: c["sl"].start + i for i, var in enumerate(c["free"])}
            for vars_, K in c["springs"]:
                idx = [pos[v] for v in vars_]
                grad[idx] += K @ x[idx]
                H[np.ix_(idx, idx)] += K
        return grad, H


def _residual(prob, x, u, lam, w):
    g, G = prob.constraints(x, u)
    grad, H = prob.energy_grad_hess(x)
    r = np.concatenate([grad - G[:, :prob.nx].T @ lam, -w - G[:, prob.nx:].T @ lam, g])
    return r, G, H


def deflection(model, p, wrench, tol: float = 1e-11, max_iter: int = 60, return_info: bool = False):
    """Platform deflection twist (6,) at point ``p`` under ``wrench`` (Fx..Mz, N and N mm).

    Full nonlinear kinematics of every chain; see the module docstring.
    Raises VjmError if Newton's method does not converge.
    """
    w = np.asarray(wrench, dtype=float).reshape(6)
    prob = _Problem(model, p)
    nx, nc = prob.nx, prob.nc
    x, u, lam = np.zeros(nx), np.zeros(6), np.zeros(nc)
    N = nx + 6 + nc
    geometric = False
    prev = np.inf
    for it in range(max_iter):
        r, G, H = _residual(prob, x, u, lam, w)
        A = np.zeros((N, N))
        A[:nx, :nx] = H
        A[:nx + 6, nx + 6:] = -G.T
        A[nx + 6:, :nx + 6] = G
        if geometric:
            # d(G^T lam)/dz by forward differences of the exact (complex-step) gradients
            z0 = np.concatenate([x, u])
            base = G.T @ lam
            for j in range(nx + 6):
                h = 1e-7 * max(1.0, abs(z0[j]))
                z = z0.copy()
                z[j] += h
                _, Gj = prob.constraints(z[:nx], z[nx:])
                A[:nx + 6, j] -= (Gj.T @ lam - base) / h
        # equilibrate rows and columns, then a least-squares step (rank-5 parallelogram springs)
        rs = 1.0 / np.maximum(np.max(np.abs(A), axis=1), 1e-300)
        As = A * rs[:, None]
        cs = 1.0 / np.maximum(np.max(np.abs(As), axis=0), 1e-300)
        dz = np.linalg.lstsq(As * cs[None, :], -r * rs, rcond=1e-14)[0] * cs
        x += dz[:nx]
        u += dz[nx:nx + 6]
        lam += dz[nx + 6:]
        size = np.max(np.abs(u)) + 1e-300
        step = np.max(np.abs(dz[nx:nx + 6]))
        if step <= tol * size or step == 0.0:
            break
        if it >= 3 and step < 1e-9 * size and step > 0.5 * prev:
            break  # stagnation at round-off
        if it >= 2 and step > 0.2 * prev:
            geometric = True  # slow linear convergence: large load, add the geometric stiffness
        prev = step
    else:
        raise VjmError(f"nonlinear equilibrium did not converge at p = {np.round(prob.p0, 4).tolist()} "
                       f"under wrench {w.tolist()} (load too large for the model?)")
    R = _plat_R(u[3:])
    t = np.concatenate([u[:3], rotation_vector(R)])
    if return_info:
        return t, {"iterations": it + 1, "chain_wrench": lam.reshape(-1, 6)}
    return t


def deflection_map(model, P, W) -> np.ndarray:
    """Nonlinear deflections (n, 6) for points P (n, 3) and wrenches W (n, 6) or (6,)."""
    P = np.atleast_2d(np.asarray(P, dtype=float))
    W = np.broadcast_to(np.asarray(W, dtype=float), (P.shape[0], 6))
    return np.stack([deflection(model, p, w) for p, w in zip(P, W)])
