"""The compiled kernels' one-time compilation, ahead of their first use.

numba compiles each kernel on its first call and keeps the machine code in a cache beside the source
(``cache=True``); every later process loads it in about a second.  On a fresh install that first call
costs about a minute and a half of CPU in all (the path kernel alone about 40 s).  Whoever calls first
pays it: a user's first long toolpath, or every worker of a parallel test run that reaches the same
kernel before the cache is written.  ``python -m vjm.kernels`` pays it once, up front, with one process
per group of kernels so that two cores compile in parallel; ``make test`` runs it beside the lint.

Each group compiles its kernels through the public calls that use them, on inputs a few poses long, so
the compiled signatures are exactly those that real calls load.

Usage: ``python -m vjm.kernels [group ...]`` (groups: ``map``, ``ik``, ``path``, ``robot``; default all,
in parallel).
"""
from __future__ import annotations

import subprocess
import sys
import time
from typing import Any

import numpy as np


def _map() -> None:
    """The batched stiffness map (:mod:`vjm.maps.map_kernel`), on the bundled 3-PUU."""
    import vjm

    m = vjm.load_model("puu")
    P = np.zeros((4, 3))
    P[:, 0] = np.linspace(-20.0, 20.0, 4)
    m.stiffness_map(P, kernel="numba")


def _ik() -> None:
    """The numerical inverse kinematics of description files (:mod:`vjm.kinematics.ik_kernel`) and
    the map kernel on a 6-dof platform, on the bundled hexapod."""
    import vjm
    from vjm.kinematics import ik
    from vjm.kinematics.poses import as_poses

    m = vjm.load_model("machines/hexapod_6ups.yaml")
    # the IK kernels serve batches of COMPILED_FROM poses or more; anchors and predictions from 4 x ANCHOR_EVERY
    side = int(np.ceil(np.sqrt(max(ik.COMPILED_FROM, 4 * ik.ANCHOR_EVERY))))
    x, y = np.meshgrid(np.linspace(-10.0, 10.0, side), np.linspace(-10.0, 10.0, side))
    X = np.zeros((side * side, 6))
    X[:, 0], X[:, 1], X[:, 2] = x.ravel(), y.ravel(), 550.0
    m.stiffness_map(X, kernel="numba")   # its legs in closed form (ik_kernel.leg)
    closed, ik.CLOSED_FORM = ik.CLOSED_FORM, False
    try:   # and by Newton, as the legs of other machines
        m.arch.solve_all(m, as_poses(X + 1.0, 6))
    finally:
        ik.CLOSED_FORM = closed


def _path() -> None:
    """The nonlinear equilibrium along a path (:mod:`vjm.stiffness.nonlinear_kernel`), on the 3-PUU:
    the kernel serves blocks of at least ``KERNEL_MIN`` points."""
    import vjm
    from vjm.toolpath import equilibrium

    m = vjm.load_model("puu")
    n = max(equilibrium.KERNEL_MIN, 2)
    P = np.zeros((n, 3))
    P[:, 0] = np.linspace(-20.0, 20.0, n)
    W = np.zeros((n, 6))
    W[:, 0] = 100.0
    s = equilibrium.equilibria(m, P, W)
    _path_entries(m, P, W, s)


def _path_entries(m, P, W, s) -> None:
    """The path kernel's entry points called one by one (the linearization, the Newton step, the
    right-hand side, the block factorization and solve, the residual check), as a check of the
    compiled equations against the numpy ones calls them: each is compiled for those calls too."""
    from vjm.stiffness import nonlinear as nl
    from vjm.stiffness import nonlinear_kernel as K
    from vjm.toolpath import equilibrium as eq

    b = eq._Block(m, P, W, None)
    tab, (v0, R0, S, D, fixed, kappa, kd, xr, Wd, Pd) = eq._pack(b)
    nv = s.state.shape[1] - 6 - b.nc
    z = np.concatenate([eq._to_x(b.chains, s.state[:, :nv]), s.state[:, nv:]], axis=1)
    pt = (v0[0], R0[0], S[0], D[0], fixed[0])
    gk, Gk, Hk = np.empty(b.nc), np.empty((b.nc, b.nx + 6)), np.empty((b.nx + 6, b.nx + 6))
    K.linearize(tab, pt, z[0], Pd[0], True, gk, Gk, Hk)
    dk = K.newton_step(tab, pt, z[0], Wd[0], Pd[0], kappa[0], kd[0], xr[0])
    rhs = np.empty(len(dk))
    K._rhs(gk, Gk, z[0], Wd[0], kappa[0], xr[0], rhs)
    if K.nonlinear_block.factor(tab, b.nx, kd[0], Gk, Hk, K.nonlinear_block.workspace(tab)):
        K.nonlinear_block.full_solve(tab, b.nx, kd[0], Gk, Hk, rhs)
    K.residual_ok(tab, pt, z[0], Wd[0], Pd[0], kappa[0], xr[0], b.lref, eq.RTOL, nl.ROUNDOFF)


def _robot() -> None:
    """The serial chain's stiffness (:mod:`vjm.robot.kernel`) and its self-weight equilibrium
    (:mod:`vjm.robot.sagkernel`), on the bundled UR10."""
    import vjm

    r: Any = vjm.load_model("robots/ur10/ur10.yaml")
    q = np.tile([0.0, -1.2, 1.5, -1.9, -1.57, 0.0], (4, 1))
    q[:, 1] += np.linspace(0.0, 0.2, 4)
    r.stiffness(q)
    r.self_weight(q)


GROUPS = {"map": _map, "ik": _ik, "path": _path, "robot": _robot}


def compile_groups(names) -> None:
    """Compile (or load from the cache) the kernels of the groups ``names``, in this process."""
    for name in names:
        GROUPS[name]()


def main(argv=None) -> int:
    args = list(sys.argv[1:] if argv is None else argv)
    here = "--here" in args  # compile in this process (the children of a parallel run)
    names = [a for a in args if a != "--here"] or list(GROUPS)
    bad = [n for n in names if n not in GROUPS]
    if bad:
        print(f"error: unknown kernel group {bad[0]!r} (groups: {', '.join(GROUPS)})", file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    if here or len(names) == 1 or "path" not in names:
        compile_groups(names)
    else:
        # the path kernel is about half of the whole compile: it gets a process, the others share one
        parts = [["path"], [n for n in names if n != "path"]]
        procs = [subprocess.Popen([sys.executable, "-m", "vjm.kernels", "--here", *p]) for p in parts if p]
        if any(p.wait() for p in procs):
            return 1
    if not here:
        print(f"vjm kernels ready: {', '.join(names)} ({time.perf_counter() - t0:.1f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
