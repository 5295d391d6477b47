"""Configurations per second of a 6R arm (the bundled UR10 with joint and link springs), side by side with
pinocchio's compiled kinematics in the same run.

* joint-space stiffness (K, C at the tool): ``RobotModel.stiffness(Q)`` batched, against a per-configuration
  loop of pinocchio (``computeJointJacobians`` + ``getFrameJacobian``, then C = J diag(c) J^T and its inverse
  in numpy: the compiled kinematics as an anchor, the joint springs only);
* self-weight deflection (equilibrium on the deflected geometry): ``RobotModel.self_weight(Q)`` (the
  compiled Newton of :mod:`vjm.robot.sagkernel`), the same equilibrium by the general solver
  (``vjm.stiffness.nonlinear.deflection_map`` with the body loads: the path every configuration took before, and
  the fallback), and pinocchio's ``computeGeneralizedGravity`` per configuration plus the linear sag
  ``J K^-1 g(q)`` (no equilibrium iteration: what the compiled library gives for the linear answer).

Each is timed ``REPEAT`` times and the best kept (as ``timeit``), by the process's CPU time
(``time.process_time``) and by the wall clock: on a machine shared with other jobs the CPU time is the
one-core figure, the wall clock what a user waits.  One core: run with ``OMP_NUM_THREADS=1`` (every
timed path is then single-threaded, so CPU time is one core's time).  Usage: ``python benchmarks/bench_serial.py [N]``.
"""
import os
import platform
import sys
import time

import numpy as np

import vjm

REPEAT = 3
#: issue 26 item 6 targets, configurations per second on one core
TARGET_STIFFNESS, TARGET_SAG = 200_000, 50_000
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


WALL: list = []


def best(fn):
    """Best CPU time of REPEAT runs (the best wall time goes to WALL)."""
    t, w = np.inf, np.inf
    for _ in range(REPEAT):
        t0, w0 = time.process_time(), time.perf_counter()
        fn()
        t, w = min(t, time.process_time() - t0), min(w, time.perf_counter() - w0)
    WALL.append(w)
    return t


def pin_stiffness(pm, pd, tool, Q, c):
    import pinocchio as pin

    out = np.empty((len(Q), 6, 6))
    for i, q in enumerate(Q):
        pin.computeJointJacobians(pm, pd, q)
        pin.updateFramePlacements(pm, pd)
        J = pin.getFrameJacobian(pm, pd, tool, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        C = (J * c) @ J.T
        out[i] = np.linalg.inv(C)
    return out


def pin_sag(pm, pd, tool, Q, c):
    import pinocchio as pin

    out = np.empty((len(Q), 6))
    for i, q in enumerate(Q):
        g = pin.computeGeneralizedGravity(pm, pd, q)
        pin.computeJointJacobians(pm, pd, q)
        pin.updateFramePlacements(pm, pd)
        J = pin.getFrameJacobian(pm, pd, tool, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        out[i] = J @ (-c * g)
    return out


def general_sag(m, Q):
    """The same equilibrium by vjm.stiffness.nonlinear's general solver (the robot's weights as its body loads)."""
    from vjm.robot.weight import body_loads
    from vjm.stiffness.nonlinear import deflection_map

    kin = m.kinematics(Q)
    loads = body_loads(m, kin.q, m.tools[0], np.asarray(m.gravity, dtype=float), m.payload)
    return deflection_map(m, kin, np.zeros(6), body_loads=[loads])


def main(n: int = 20_000) -> None:
    import pinocchio as pin

    m = vjm.load_model(os.path.join(ROOT, "data", "robots", "ur10", "ur10.yaml"))
    rng = np.random.default_rng(0)
    Q = rng.uniform(-2.0, 2.0, (n, m.nq))
    pm = pin.buildModelFromUrdf(m.tree.source)
    pd = pm.createData()
    tool = pm.getFrameId("tool0")
    c = np.array([1.0 / m.joint_springs[j].stiffness for j in m.q_names]) * 1e3  # rad/(N m)
    m.stiffness(Q[:10])
    t_vjm = best(lambda: m.stiffness(Q))
    t_pin = best(lambda: pin_stiffness(pm, pd, tool, Q, c))
    m.self_weight(Q[:10])
    t_sag = best(lambda: m.self_weight(Q))
    _, info = m.self_weight(Q, return_info=True)
    ng = max(50, n // 40)
    t_gen = best(lambda: general_sag(m, Q[:ng]))
    ns = max(50, n // 4)
    t_pin_sag = best(lambda: pin_sag(pm, pd, tool, Q[:ns], c))
    print(f"{platform.processor() or platform.machine()}, numpy {np.__version__}, pinocchio {pin.__version__}, "
          f"OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS', 'unset')}, load average {os.getloadavg()[0]:.1f}; "
          f"configurations per CPU second (per wall second: "
          f"{', '.join(f'{k / w:,.0f}' for k, w in zip((n, n, n, ng, ns), WALL))})")
    print(f"joint-space stiffness, {n} configurations: vjm {n / t_vjm:,.0f} /s (target {TARGET_STIFFNESS:,}), "
          f"pinocchio loop {n / t_pin:,.0f} /s")
    print(f"self-weight, {n} configurations: vjm compiled equilibrium {n / t_sag:,.0f} /s (target {TARGET_SAG:,}; "
          f"{int(info['fallback'].sum())} to the general solver, Newton iterations <= {info['iterations'].max()}), "
          f"general solver ({ng}) {ng / t_gen:,.0f} /s, pinocchio linear sag loop ({ns}) {ns / t_pin_sag:,.0f} /s")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 20_000)
