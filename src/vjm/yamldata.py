"""YAML files read as data: plain mappings, lists, numbers and strings, never objects or code.

``yaml.safe_load`` builds no Python object from a tag (``!!python/object/apply:os.system`` and
the like): such a file is refused with one line naming the tag and its line, before anything in
it is used.  A key given twice in one mapping is refused too, naming both lines (YAML would keep
the last one silently).  Every YAML file vjm reads goes through :func:`read_yaml`.
"""
from __future__ import annotations

import yaml

from .errors import VjmError


class _UniqueKeys(yaml.SafeLoader):
    """``yaml.SafeLoader`` that refuses a key given twice in one mapping (PyYAML keeps the last one
    silently: a second ``geometry:`` would replace the first).  Keys brought in by a ``<<`` merge
    may be overridden, as YAML says."""

    def flatten_mapping(self, node):
        # called on every mapping before its merges are spliced in (and again, on the merged ones,
        # after): check each node once, as written
        checked = self.__dict__.setdefault("_checked", set())
        if id(node) not in checked:
            checked.add(id(node))
            lines: dict = {}
            for key_node, _ in node.value:
                if key_node.tag == "tag:yaml.org,2002:merge":
                    continue
                key = self.construct_object(key_node, deep=False)
                try:
                    first = lines.get(key)
                except TypeError:  # an unhashable key: the base class refuses it
                    continue
                line = key_node.start_mark.line + 1
                if first is not None:
                    where = f"first on line {first}" if first != line else "both on this line"
                    raise yaml.constructor.ConstructorError(
                        None, None, f"the key {key!r} is given twice ({where}); YAML would keep only the "
                        "last: remove one", key_node.start_mark)
                lines[key] = line
        super().flatten_mapping(node)


def read_yaml(path, what: str = "model file"):
    """The document in ``path`` as plain data (VjmError naming the file on any failure)."""
    try:
        with open(path, encoding="utf-8") as fh:
            return yaml.load(fh, Loader=_UniqueKeys)  # a SafeLoader: builds no object from a tag
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
