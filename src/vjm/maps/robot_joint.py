"""Maps in joint space: two joints varied over a grid, the others held, for a serial or tree robot.

A serial robot's users work in joint space: the stiffness (and the self-weight sag) as a function
of two joints -- the shoulder and the elbow, say -- with the wrist held, tells where to work.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import VjmError


@dataclass(frozen=True, eq=False)
class JointMap:
    """k_tran (mm/N), k_rot (rad/(N mm)) and optionally the self-weight sag (mm) over a grid of two joints.

    ``axes``: the two joints' names; ``a``, ``b``: their values (rad, or mm); arrays are indexed
    ``[i, j]`` for ``a[i]``, ``b[j]``; ``q``: every configuration (n_a, n_b, nq)."""

    axes: tuple
    a: np.ndarray
    b: np.ndarray
    q: np.ndarray
    k_tran: np.ndarray
    k_rot: np.ndarray
    sag: np.ndarray | None = None
    #: the stiffness matrices (n_a, n_b, 6, 6), world axes at the tool point
    K: np.ndarray | None = None

    def plot(self, name: str = "k_tran", ax=None):
        """A filled contour of ``k_tran``, ``k_rot`` or ``sag`` (the sag's length, mm) over the two joints."""
        import matplotlib.pyplot as plt

        if name == "sag":
            if self.sag is None:
                raise VjmError("this map has no self-weight sag (joint_map(..., self_weight=True))")
            v, unit = np.linalg.norm(self.sag[..., :3], axis=-1), "mm"
        elif name in ("k_tran", "k_rot"):
            v, unit = getattr(self, name), "mm/N" if name == "k_tran" else "rad/(N mm)"
        else:
            raise VjmError(f"name must be k_tran, k_rot or sag, got {name!r}")
        if ax is None:
            _, ax = plt.subplots()
        cs = ax.contourf(self.b, self.a, v, levels=20)
        ax.figure.colorbar(cs, ax=ax, label=f"{name} ({unit})")
        ax.set_xlabel(self.axes[1])
        ax.set_ylabel(self.axes[0])
        return ax


def joint_map(model, q0, joints, ranges, n=41, tool: str | None = None,
              self_weight: bool = False) -> JointMap:
    """The map of ``model`` over joints ``joints`` (two names) in ``ranges`` ((lo, hi), (lo, hi)), the
    other joints at ``q0``; n values per joint (one integer, or one per joint)."""
    q0 = np.asarray(q0, dtype=float)
    if q0.shape != (model.nq,):
        raise VjmError(f"q0 must have {model.nq} values ({', '.join(model.q_names)}), got shape {q0.shape}")
    if len(joints) != 2 or joints[0] == joints[1]:
        raise VjmError(f"a joint map varies two different joints, got {joints!r}")
    idx = []
    for j in joints:
        if j not in model.q_names:
            raise VjmError(f"no joint {j!r} with a coordinate of its own; joints: {', '.join(model.q_names)}")
        idx.append(model.q_names.index(j))
    ns = (n, n) if isinstance(n, (int, np.integer)) and not isinstance(n, bool) else n
    if not isinstance(ns, (tuple, list)) or len(ns) != 2 or not all(isinstance(k, (int, np.integer)) and not isinstance(k, bool) and k >= 2 for k in ns):
        raise VjmError(f"n must be an integer >= 2 (or one per joint), got {n!r}")
    a, b = (np.linspace(float(lo), float(hi), int(k)) for (lo, hi), k in zip(ranges, ns))
    shape = (len(a), len(b))
    Q = np.broadcast_to(q0, shape + (model.nq,)).copy()
    Q[:, :, idx[0]] = a[:, None]
    Q[:, :, idx[1]] = b[None, :]
    flat = Q.reshape(-1, model.nq)
    r = model.stiffness(flat, tool)
    sag = model.self_weight(flat, tool).reshape(shape + (6,)) if self_weight else None
    return JointMap(tuple(joints), a, b, Q, r.k_tran.reshape(shape), r.k_rot.reshape(shape), sag,
                    r.K.reshape(shape + (6, 6)))
