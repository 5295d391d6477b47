"""A robot's model file written back (the mapping it was read from, its URDF path made absolute)."""
from __future__ import annotations

import os

from ..errors import VjmError


def save_robot(model, path) -> None:
    """Write a robot's model file: its mapping as read, with the URDF path made absolute (atomic)."""
    import yaml

    from linkfea.files.atomic import write_text

    from ..modelio.write import HEADER

    if model.raw is None:
        raise VjmError("this robot model was not read from a file; write its YAML by hand (see vjm.robot.robotfile)")
    d = dict(model.raw)
    if "urdf" in d:
        d["urdf"] = model.tree.source
    write_text(os.path.abspath(os.fspath(path)), HEADER + yaml.safe_dump(d, sort_keys=False))
