"""Independent truth for absolute poses of a parallel machine: the 6-UPS hexapod's platform measured by an
instrument at commanded strut lengths.

Nothing here uses vjm (neither :mod:`vjm.discrepancy` nor :mod:`vjm.robot` nor vjm's chains): the hexapod of
``data/machines/hexapod_6ups.yaml`` is written out from the numbers of its file.  Each strut joins a base
joint ``b_i`` (radius ``RB`` in the base plane z = 0) to a platform joint ``c_i`` (radius ``RP`` in the
platform's plane, platform axes); its length is ``|p + R c_i - b_i|`` for the platform pose (p, R).  Leg
``A_k`` (k = 0, 1, 2) has its base joint at ``120 k + 10`` deg and its platform joint at ``120 k + 50`` deg,
leg ``B_k`` the mirror image (``120 k - 10``, ``120 k - 50``); the legs in the order A1 A2 A3 B1 B2 B3.

* inverse kinematics (:func:`lengths`) in closed form;
* forward kinematics (:func:`platform_pose`): scipy's ``least_squares`` on the six lengths, from the
  home pose, the rotation as a rotation vector (scipy's ``Rotation``);
* a measurement (:func:`measure`): the true strut lengths are the commanded ones plus hidden offsets, the
  marker ``p + R m`` is seen in the instrument frame ``R_i x + t_i`` with Gaussian noise.
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

RB, RP, HOME_Z = 350.0, 200.0, 550.0
LEGS = ("A1", "A2", "A3", "B1", "B2", "B3")
#: the actuators' columns: vjm's names of the struts (chain.variable)
COLUMNS = tuple(f"{leg}.l" for leg in LEGS)


def _circle(radius: float, degrees) -> np.ndarray:
    a = np.radians(np.asarray(degrees, dtype=float))
    return np.column_stack([radius * np.cos(a), radius * np.sin(a), np.zeros_like(a)])


BASE = _circle(RB, [10, 130, 250, -10, 110, 230])
TOP = _circle(RP, [50, 170, 290, -50, 70, 190])


def lengths(p, rotvec, base_shift=None) -> np.ndarray:
    """Strut lengths (n, 6) mm at platform positions p (n, 3) and rotation vectors (n, 3); ``base_shift``
    (6, 3) mm moves the base joints."""
    p, rotvec = np.atleast_2d(p), np.atleast_2d(rotvec)
    b = BASE if base_shift is None else BASE + base_shift
    R = Rotation.from_rotvec(rotvec).as_matrix()
    c = np.einsum("nij,kj->nki", R, TOP) + p[:, None, :]
    return np.linalg.norm(c - b[None], axis=2)


def platform_pose(L, start=None) -> tuple[np.ndarray, np.ndarray]:
    """The platform pose (p (3,), rotation vector (3,)) at strut lengths L (6,), by least squares on the six
    lengths from ``start`` (default the home pose)."""
    x0 = np.array([0.0, 0.0, HOME_Z, 0.0, 0.0, 0.0]) if start is None else np.asarray(start, dtype=float)
    sol = least_squares(lambda x: lengths(x[:3], x[3:])[0] - L, x0, method="lm", xtol=1e-15, ftol=1e-15,
                        gtol=1e-15)
    return sol.x[:3], sol.x[3:]


def random_poses(n: int, rng, reach: float = 70.0, tilt: float = 0.08) -> tuple[np.ndarray, np.ndarray]:
    """n platform poses: positions within ``reach`` mm of the home point (z within it too), rotation vectors
    within ``tilt`` rad per component."""
    p = np.column_stack([rng.uniform(-reach, reach, (n, 2)), HOME_Z + rng.uniform(-reach, reach, n)])
    return p, rng.uniform(-tilt, tilt, (n, 3))


def measure(n: int, seed: int, offsets=None, marker=(0.0, 0.0, 0.0), R=np.eye(3), t=(0.0, 0.0, 0.0),
            sigma: float = 0.01, base_shift=None) -> tuple[np.ndarray, np.ndarray, dict]:
    """(commanded strut lengths (n, 6), measured points (n, 3) in the instrument frame, the true poses): the
    platform at random poses, the struts commanded at their true lengths minus the hidden ``offsets`` (6,),
    the base joints moved by ``base_shift`` (6, 3) mm."""
    rng = np.random.default_rng(seed)
    p, w = random_poses(n, rng)
    off = np.zeros(6) if offsets is None else np.asarray(offsets, dtype=float)
    q = lengths(p, w, base_shift) - off
    x = p + Rotation.from_rotvec(w).apply(np.asarray(marker, dtype=float))
    m = x @ np.asarray(R).T + np.asarray(t) + rng.normal(0.0, sigma, (n, 3))
    return q, m, {"p": p, "rotvec": w}


def write_csv(path, q, m, header=COLUMNS + ("platform.x", "platform.y", "platform.z")) -> str:
    """A pose file in vjm's names."""
    with open(path, "w", encoding="utf-8") as f:
        f.write(",".join(header) + "\n")
        for a, b in zip(q, m):
            f.write(",".join(f"{v:.10f}" for v in np.r_[a, b]) + "\n")
    return str(path)
