"""A robot's model file written back: the mapping it was read from, its file paths made absolute.

The file carries the checksum line of :mod:`vjm.modelio.write`, so that a later save replaces it (and only
it: a file vjm did not write, or one edited since, is refused before anything is written)."""
from __future__ import annotations

import os

from ..errors import VjmError


def absolute_paths(doc: dict, base: str) -> dict:
    """``doc`` with the file paths it names (the URDF, linkfea results of link springs, 6x6 joint springs and
    masses) made absolute from ``base``, the folder of the file it was read from."""
    def fix(entry):
        if isinstance(entry, dict) and isinstance(entry.get("linkfea"), str):
            return {**entry, "linkfea": os.path.normpath(os.path.join(base, entry["linkfea"]))}
        return entry

    out = dict(doc)
    if isinstance(out.get("urdf"), str):
        out["urdf"] = os.path.normpath(os.path.join(base, out["urdf"]))
    for key in ("links", "masses"):
        if isinstance(out.get(key), dict):
            out[key] = {k: fix(v) for k, v in out[key].items()}
    if isinstance(out.get("joints"), dict):
        out["joints"] = {k: {**v, "spring6": fix(v["spring6"])} if isinstance(v, dict) and "spring6" in v else v
                         for k, v in out["joints"].items()}
    return out


def save_robot(model, path) -> None:
    """Write a robot's model file: its mapping as read, its file paths made absolute (atomic, checksummed)."""
    from linkfea.files.atomic import write_text

    from .write import ROBOT_HEADER, check_model_out, model_file_text

    if model.raw is None:
        raise VjmError("this robot model was not read from a file, or its tree or springs were replaced since: "
                       "its file would not say what it holds; write its YAML by hand (see vjm.modelio.robotfile)")
    path = os.path.abspath(os.fspath(path))
    check_model_out(path)
    base = os.path.dirname(model.path) if model.path else os.path.dirname(model.tree.source)
    write_text(path, model_file_text(absolute_paths(model.raw, base), ROBOT_HEADER))
