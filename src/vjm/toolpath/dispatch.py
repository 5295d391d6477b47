"""``vjm.path`` on any model: a parallel machine's pipeline (:mod:`vjm.toolpath.run`) or a serial
robot's (:mod:`vjm.toolpath.robot`), chosen by the model's type."""
from __future__ import annotations

from ..errors import VjmError
from . import robot, run

#: options of the parallel pipeline that a robot does not take (with why, for the error line)
PARALLEL_ONLY = {"foot": "a robot's link springs are in its model file (links:)",
                 "leg": "a robot's link springs are in its model file (links:)",
                 "workers": None, "uncertainty": None}


def path(model, toolpath, *args, seed=None, tool_frame=None, **options):
    """Deflection of the tool along a toolpath and the compensated toolpath, on a parallel machine
    (:func:`vjm.toolpath.run.path`: every parameter) or on a serial robot
    (:func:`vjm.toolpath.robot.robot_path`), by the model's type.

    seed : robots only: the configuration (nq,) held along the path (default the model file's ``home:``)
    tool_frame : robots only: the tool frame of the tree (default its first); ``tool`` is then the TCP
        in that frame's axes
    """
    from ..robot.model import RobotModel

    m = run._model(model, options.get("foot"), options.get("leg"))
    if not isinstance(m, RobotModel):
        if seed is not None or tool_frame is not None:
            raise VjmError(f"--seed and --tool-frame are for serial robots; {getattr(m, 'name', model)} is a "
                           f"parallel machine")
        return run.path(m, toolpath, *args, **options)
    if args:
        raise VjmError("vjm.path on a robot takes its options by name (wrench=, tool=, ...)")
    for k, why in PARALLEL_ONLY.items():
        v = options.pop(k, None)
        if why is not None and v is not None:
            raise VjmError(f"{k}: {why}")
    return robot.robot_path(m, toolpath, seed=seed, tool_frame=tool_frame, **options)
