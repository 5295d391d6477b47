"""vjm: virtual-joint-method stiffness of parallel machines and serial or tree robots.

One model type, :class:`Model`, of two kinds: a parallel machine evaluated at platform poses, a robot
(URDF or DH) evaluated at joint configurations q.

>>> import numpy as np, vjm
>>> m = vjm.load_model("puu")              # the bundled data/orthoglide/puu.yaml
>>> r = m.stiffness([0.0, 0.0, 0.0])       # at Q0; K in world axes at the end-effector point
>>> int(r.rank), bool(np.allclose(r.C @ r.K, np.eye(6)))
(6, True)
>>> print(f"k_tran = {r.k_tran:.3g} mm/N")  # the seed's Table 1: 2.78e-4 (actuator fitted to it)
k_tran = 0.000278 mm/N
>>> robot = vjm.load_model("robots/ur10/ur10.yaml")   # the same type, of the serial kind
>>> isinstance(robot, vjm.Model), robot.kind, robot.stiffness([0.0, -1.2, 1.5, -1.9, -1.57, 0.0]).K.shape
(True, 'serial', (6, 6))
"""

from .errors import EquilibriumError, VjmError
from .model.base import Model
from .model.links import LinkSpring
from .model.machine import Actuator, Joints
from .modelio.read import load_model, with_links
from .modelio.write import save_model
from .stiffness.linear import StiffnessResult

__all__ = ["VjmError", "EquilibriumError", "Model", "Actuator", "LinkSpring", "Joints", "StiffnessResult",
           "StiffnessMap", "JointMap", "CartesianMap", "Diagnosis", "PathResult", "Compensation",
           "load_model", "save_model", "with_links", "diagnose", "path", "design", "DesignResult"]

#: what the verbs return, imported on first use (matplotlib, scipy): name -> (module, attribute)
_LAZY = {"path": ("toolpath.dispatch", "path"), "PathResult": ("toolpath.result", "PathResult"),
         "StiffnessMap": ("maps.compute", "StiffnessMap"), "JointMap": ("maps.robot_joint", "JointMap"),
         "CartesianMap": ("maps.robot_cartesian", "CartesianMap"), "Diagnosis": ("discrepancy.diagnosis", "Diagnosis"),
         "Compensation": ("compensation", "Compensation"),
         "design": ("synthesis.run", "design"), "DesignResult": ("synthesis.result", "DesignResult")}


def __dir__():
    # the public names only (submodules stay importable as vjm.maps.compute etc.)
    return sorted(__all__)


def __getattr__(name):
    # ``vjm.path(...)``: deflection along a toolpath (vjm/toolpath/), and the result types, imported on first use
    if name in _LAZY:
        import importlib

        module, attr = _LAZY[name]
        return getattr(importlib.import_module(f"{__name__}.{module}"), attr)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def diagnose(model, data, **options):
    """What did the model leave out?  ``vjm diagnose`` as a function.

    Parameters
    ----------
    model : a :class:`Model`, the path of a model file or a bundled model name ("puu").
    data : measurements (``vjm.discrepancy.data.Deflections`` / ``StiffnessObs``) or a CSV path.
    options : ``alpha``, ``effects``, ``folds``, ``suggest``, ``forces_only``, ``progress`` (a callable given a
        line per selection round) ... of :func:`vjm.discrepancy.workflow.diagnose`.  The data kind is
        recognised by the registry of :mod:`vjm.discrepancy.kinds` (deflections, stiffness observations, a
        robot's or a parallel machine's absolute poses, and any kind registered there).

    Returns
    -------
    Diagnosis
        one type for every data kind: ``.verdict``, ``.named``, ``.confounded``, ``.summary()``,
        ``.updated_model`` (a :class:`Model`), ``.save(dir)``, ``.report`` (typed, frozen).

    >>> d = vjm.diagnose("data/orthoglide/puu.yaml", "measurements.csv")   # doctest: +SKIP
    >>> d.verdict, d.named                                                  # doctest: +SKIP
    """
    from .discrepancy.workflow import diagnose as _diagnose

    return _diagnose(model, data, **options)
