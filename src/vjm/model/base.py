"""The one model type, :class:`Model`: a parallel machine or a serial / tree robot.

A :class:`Model` is immutable and holds parameters only (pinocchio's Model / Data split): every
evaluation returns a fresh result.  What it models is its *kind*, the class that carries the
structure and the computations:

* ``"parallel"``: :class:`vjm.model.machine.ParallelModel`, a platform on chains (a built-in
  architecture or a machine description), evaluated at platform poses;
* ``"serial"``: :class:`vjm.robot.model.RobotModel`, a chain or tree of joints from a URDF or a DH
  table, evaluated at joint configurations ``q``.

Both answer the same calls by the same names: ``stiffness``, ``stiffness_map``, ``deflection``,
``save``, ``replace`` (and ``name``, ``path``, ``kind``).  A call that belongs to one kind only
(``self_weight``, ``joint_map``, ``cartesian_map`` of a robot; ``map``, ``joint_forces``, ``grid`` ...
of a parallel machine) raises :class:`NotForKind`, one line naming the model and what it does take.

>>> import vjm
>>> robot, machine = vjm.load_model("robots/ur10/ur10.yaml"), vjm.load_model("puu")
>>> isinstance(robot, vjm.Model), isinstance(machine, vjm.Model), robot.kind, machine.kind
(True, True, 'serial', 'parallel')
>>> machine.self_weight([0, 0, 0])
Traceback (most recent call last):
...
vjm.model.base.NotForKind: ...puu.yaml: a parallel machine; self_weight is for serial robots (...)
>>> robot.require("parallel", "vjm sweep")
Traceback (most recent call last):
...
vjm.model.base.NotForKind: ...ur10.yaml: a serial robot; vjm sweep is for parallel machines (evaluate it in joint space: ...)
"""
from __future__ import annotations

from typing import Any, ClassVar

from ..errors import VjmError

#: what each kind evaluates, for the error line of a call it does not take
TAKES = {"parallel": "evaluate it at platform poses: stiffness(p), stiffness_map(P), deflection, map, "
                     "joint_forces",
         "serial": "evaluate it in joint space: stiffness(q), stiffness_map(Q), deflection, self_weight, "
                   "joint_map, cartesian_map"}
#: the kinds' names in an error line, one and many
NOUN = {"parallel": "a parallel machine", "serial": "a serial robot"}
NOUNS = {"parallel": "parallel machines", "serial": "serial robots"}
#: the attributes each kind has, filled as the kinds' classes are defined (see Model.__init_subclass__)
_ATTRIBUTES: dict[str, frozenset] = {}


class NotForKind(VjmError, AttributeError):
    """A call of one kind of model asked of the other (``self_weight`` of a parallel machine, ``map`` of a
    robot): one line naming the model and what it takes.  An AttributeError too, so ``hasattr`` is False."""


class Model:
    """Immutable VJM model of a machine: a parallel machine (``kind == "parallel"``) or a serial or tree
    robot (``kind == "serial"``); see the module docstring.  Read one with :func:`vjm.load_model`.

    The shared calls (each kind documents its arguments: a pose for a parallel machine, a configuration
    ``q`` for a robot):

    * ``stiffness(x)``, ``stiffness_map(X)``: a :class:`~vjm.stiffness.linear.StiffnessResult` (K, C in
      world axes at the end-effector or tool point, k_tran, k_rot, rank ...), one or a batch;
    * ``deflection(X, wrench)``: the linear deflection twist ``C w``;
    * ``save(path)``: the model file; ``replace(**changes)``: a validated, modified copy.
    """

    #: ``"parallel"`` or ``"serial"``
    kind: ClassVar[str] = ""
    name: str
    path: str | None

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        if cls.kind:
            # the dataclass fields without a default are annotations only (the decorator runs after this)
            names = set(dir(cls)) | set(cls.__dict__.get("__annotations__", {}))
            _ATTRIBUTES[cls.kind] = frozenset(a for a in names if not a.startswith("_"))

    def _not_for(self, what: str, kind: str | None = None) -> NotForKind:
        """The error of ``what`` (a call, a command) asked of this model: it is for the ``kind`` of model (default:
        the kinds that have an attribute ``what``)."""
        where = getattr(self, "path", None) or getattr(self, "name", None) or "this model"
        kinds = [kind] if kind else [k for k, names in _ATTRIBUTES.items() if k != self.kind and what in names]
        other = " or ".join(NOUNS[k] for k in kinds) or "another kind of model"
        return NotForKind(f"{where}: {NOUN.get(self.kind, 'a model')}; {what} is for {other} "
                          f"({TAKES.get(self.kind, '')})")

    def require(self, kind: str, what: str) -> None:
        """NotForKind if this model is not of ``kind``: ``what`` (a command, a call) is for that kind only."""
        if self.kind != kind:
            raise self._not_for(what, kind)

    def __getattr__(self, name: str) -> Any:
        # reached only for a name this kind lacks: the other kind's is one clear error, anything else as usual
        if not name.startswith("_") and any(name in names for k, names in _ATTRIBUTES.items() if k != self.kind):
            raise self._not_for(name)
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    # -- the shared calls: each kind defines them (its arguments: poses, or configurations q) ------------
    def stiffness(self, *args: Any, **kwargs: Any) -> Any:
        """The stiffness at one pose (parallel) or configuration ``q`` (serial): a StiffnessResult."""
        raise NotImplementedError

    def stiffness_map(self, *args: Any, **kwargs: Any) -> Any:
        """The stiffness at a batch of poses (parallel) or configurations (serial), a leading axis n."""
        raise NotImplementedError

    def deflection(self, *args: Any, **kwargs: Any) -> Any:
        """The linear deflection twist ``C w`` under a wrench at the end-effector or tool point."""
        raise NotImplementedError

    def save(self, path) -> None:
        """Write the model file (atomic; a file vjm did not write is never overwritten)."""
        raise NotImplementedError

    def replace(self, **changes) -> Any:
        """A validated copy with some fields changed (the model itself never changes)."""
        raise NotImplementedError

    # -- the calls one kind only takes: declared here so each raises the one error on the other ---------
    def self_weight(self, *args: Any, **kwargs: Any) -> Any:
        """Serial robots: the tool's deflection under the robot's own weight."""
        raise self._not_for("self_weight")

    def joint_map(self, *args: Any, **kwargs: Any) -> Any:
        """Serial robots: the stiffness (and sag) over two joints."""
        raise self._not_for("joint_map")

    def cartesian_map(self, *args: Any, **kwargs: Any) -> Any:
        """Serial robots: the stiffness (and sag) at tool points, through the IK."""
        raise self._not_for("cartesian_map")

    def map(self, *args: Any, **kwargs: Any) -> Any:
        """Parallel machines: the stiffness map over the workspace box."""
        raise self._not_for("map")

    def joint_forces(self, *args: Any, **kwargs: Any) -> Any:
        """Parallel machines: the load sharing between the chains."""
        raise self._not_for("joint_forces")
