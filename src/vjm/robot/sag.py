"""The tool's sag under the robot's own weight, labelled: :class:`Sag`.

:meth:`vjm.robot.RobotModel.self_weight` returns one.  It reads as the plain twist array it wraps
(``np.asarray(sag)``, ``sag[:, :3]``, ``sag.shape``, arithmetic and numpy functions give ndarrays),
so code written for the bare (n, 6) or (6,) array runs unchanged, and it says what it holds: the
tool, the joint values, the components and their units.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.lib.mixins import NDArrayOperatorsMixin

from linkfea.mechanics.compliance import TWIST

#: units of the twist components, in :data:`TWIST` order
UNITS = ("mm", "mm", "mm", "rad", "rad", "rad")


@dataclass(frozen=True, eq=False, repr=False)
class Sag(NDArrayOperatorsMixin):
    """The tool's deflection twist under the robot's own weight (and a payload and a tool wrench).

    ``twist`` (6,) or (n, 6): dx dy dz in mm, rx ry rz in rad (a rotation vector), base axes at the tool
    point; ``q`` the joint values (the same leading axis) named by ``q_names``; ``tool`` the tool frame.
    """

    twist: np.ndarray
    tool: str
    q: np.ndarray
    q_names: tuple
    components: tuple = TWIST
    units: tuple = UNITS

    # -- an ndarray to the code that reads it as one ---------------------------------------------------
    def __array__(self, dtype=None, copy=None):
        return self.twist if dtype is None else self.twist.astype(dtype)

    def __array_ufunc__(self, ufunc, method, *inputs, **kwargs):
        def plain(x):
            return x.twist if isinstance(x, Sag) else x

        if "out" in kwargs:
            kwargs["out"] = tuple(plain(o) for o in kwargs["out"])
        return getattr(ufunc, method)(*(plain(x) for x in inputs), **kwargs)

    def __getattr__(self, name: str):
        # the array's other methods and properties (.sum(), .T, .copy() ...): reached only for names
        # the dataclass lacks; dunder names are left alone (copy and pickle look for them)
        if name.startswith("__") or name == "twist":
            raise AttributeError(name)
        return getattr(self.twist, name)

    def __getitem__(self, key):
        return self.twist[key]

    def __len__(self) -> int:
        return len(self.twist)

    def __iter__(self):
        return iter(self.twist)

    @property
    def shape(self) -> tuple:
        return self.twist.shape

    @property
    def ndim(self) -> int:
        return self.twist.ndim

    @property
    def dtype(self):
        return self.twist.dtype

    def reshape(self, *shape) -> np.ndarray:
        return self.twist.reshape(*shape)

    def tolist(self) -> list:
        return self.twist.tolist()

    # -- what it says -----------------------------------------------------------------------------------
    @property
    def translation(self) -> np.ndarray:
        """dx dy dz, mm."""
        return self.twist[..., :3]

    @property
    def rotation(self) -> np.ndarray:
        """rx ry rz, rad."""
        return self.twist[..., 3:]

    @property
    def length(self):
        """|(dx, dy, dz)|, mm."""
        return np.linalg.norm(self.translation, axis=-1)

    def to_dict(self) -> dict:
        """Names and units with the values (JSON-ready)."""
        return {"tool": self.tool, "q_names": list(self.q_names), "q": np.asarray(self.q).tolist(),
                "components": list(self.components), "units": list(self.units), "twist": self.twist.tolist()}

    def __repr__(self) -> str:
        t = self.twist
        if t.ndim == 1:
            parts = ", ".join(f"{c} {v:.4g} {u}" for c, v, u in zip(self.components, t, self.units))
            return f"<Sag at {self.tool}: {parts}; |d| = {float(self.length):.4g} mm>"
        n = np.asarray(self.length)
        return (f"<Sag at {self.tool}, {len(t)} configurations: |d| {np.nanmin(n):.4g}..{np.nanmax(n):.4g} mm; "
                f"twist (n, 6): {' '.join(self.components)} in {', '.join(dict.fromkeys(self.units))}>")
