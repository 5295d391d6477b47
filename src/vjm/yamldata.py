"""YAML files read as data: plain mappings, lists, numbers and strings, never objects or code.

``yaml.safe_load`` builds no Python object from a tag (``!!python/object/apply:os.system`` and
the like): such a file is refused with one line naming the tag and its line, before anything in
it is used.
"""
from __future__ import annotations

import yaml

from .errors import VjmError


def read_yaml(path, what: str = "model file"):
    """The document in ``path`` as plain data (VjmError naming the file on any failure)."""
    try:
        with open(path, encoding="utf-8") as fh:
            return yaml.safe_load(fh)
    except yaml.constructor.ConstructorError as exc:
        mark = exc.problem_mark
        where = f"{path}, line {mark.line + 1}" if mark is not None else str(path)
        tag = _tag(exc.problem or "")
        if tag:
            raise VjmError(f"{what} {where}: the YAML tag {tag} is not allowed ({what}s are data and never run "
                           f"code; write plain values)") from None
        raise VjmError(f"cannot read {what} {where}: {' '.join(str(exc.problem).split())}") from None
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise VjmError(f"cannot read {what} {path}: {' '.join(str(exc).split())}") from None


def _tag(problem: str) -> str:
    """``!!python/object/apply:os.system`` from PyYAML's "could not determine a constructor for the tag '...'"."""
    if "constructor for the tag" not in problem or "'" not in problem:
        return ""
    tag = problem.split("'")[1]
    return tag.replace("tag:yaml.org,2002:", "!!", 1)
