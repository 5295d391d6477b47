"""Maps in joint space: two joints varied over a grid, the others held, for a serial or tree robot.

A serial robot's users work in joint space: the stiffness (and the self-weight sag) as a function
of two joints -- the shoulder and the elbow, say -- with the wrist held, tells where to work.
A :class:`JointMap` is a map result like :class:`vjm.maps.compute.StiffnessMap`: ``save(dir)`` (the set
``vjm map --joints`` writes, :mod:`vjm.maps.robot_output`), ``plot``, ``summary`` and ``_repr_html_``.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import VjmError
from . import robot_output


@dataclass(frozen=True, eq=False)
class JointMap:
    """k_tran (mm/N), k_rot (rad/(N mm)) and optionally the self-weight sag (mm) over a grid of two joints.

    ``axes``: the two joints' names; ``a``, ``b``: their values (rad, or mm); arrays are indexed
    ``[i, j]`` for ``a[i]``, ``b[j]``; ``q``: every configuration (n_a, n_b, nq); ``q0`` the configuration
    the other joints are held at; ``model_name``, ``model_path``, ``tool``, ``q_names`` say whose map it is."""

    axes: tuple
    a: np.ndarray
    b: np.ndarray
    q: np.ndarray
    k_tran: np.ndarray
    k_rot: np.ndarray
    sag: np.ndarray | None = None
    #: the stiffness matrices (n_a, n_b, 6, 6), world axes at the tool point
    K: np.ndarray | None = None
    q0: tuple = ()
    tool: str | None = None
    q_names: tuple = ()
    model_name: str = ""
    model_path: str | None = None

    def summary_dict(self) -> dict:
        """What summary.json holds: the model, the tool, the two joints' ranges, the others' values, the
        ranges of k_tran, k_rot (and the largest sag)."""
        doc = {"kind": "joint space", "joints": list(self.axes),
               "ranges": [[float(v[0]), float(v[-1])] for v in (self.a, self.b)], "n": [len(self.a), len(self.b)],
               "q_fixed": [float(v) for v in self.q0]}
        return robot_output.summary_dict(self, doc)

    def summary(self) -> str:
        """One line: the two joints and their configurations, the ranges of k_tran and k_rot (and the sag)."""
        return robot_output.line(self.summary_dict())

    def _repr_html_(self) -> str:
        return robot_output.html(f"{self.model_name or 'robot'}: joint map", self.summary_dict())

    def csv_columns(self) -> tuple[list, list]:
        """map.csv's leading header and its arrays: a row per configuration (joint values, k_tran, k_rot)."""
        return [], [self.q.reshape(-1, self.q.shape[-1]), self.k_tran.reshape(-1, 1), self.k_rot.reshape(-1, 1)]

    def save(self, out, force: bool = False) -> Path:
        """Write ``out/``: map.npz, map.csv, k_tran.png, k_rot.png, summary.json (and sag.png) as one set
        (:mod:`vjm.maps.robot_output`: all new, or the old ones; ``force`` writes beside files of other
        origin); returns the folder."""
        arrays = {k: getattr(self, k) for k in ("a", "b", "q", "k_tran", "k_rot", "sag", "K")
                  if isinstance(getattr(self, k), np.ndarray)}
        return robot_output.write_set(out, self, {**arrays, "axes": np.array(self.axes)}, self.summary_dict(), force)

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
        ax.set_title(f"{robot_output.label(self)}\n{name} over {self.axes[0]} and {self.axes[1]}", fontsize=9)
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
                    r.K.reshape(shape + (6, 6)), tuple(float(v) for v in q0), model._tool(tool), tuple(model.q_names),
                    model.name, model.path)
