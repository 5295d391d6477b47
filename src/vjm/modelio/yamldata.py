"""YAML files read as data: plain mappings, lists, numbers and strings, never objects or code.

``yaml.safe_load`` builds no Python object from a tag (``!!python/object/apply:os.system`` and
the like): such a file is refused with one line naming the tag and its line, before anything in
it is used.  A key given twice in one mapping is refused too, naming both lines (YAML would keep
the last one silently).  Every YAML file vjm reads goes through :func:`read_yaml`.
"""
from __future__ import annotations

import yaml

from ..errors import VjmError

MAX_NODES = 1_000_000
"""Most values (numbers, strings, list and mapping entries, counted with aliases expanded) a data file may
hold: a model file has a few hundred.  Aliases can multiply a small file (``b: &b [*a, *a, ...]`` nested
ten times is 10^10 values), and a program that walks the data would run out of memory."""


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


class _DataLoader(_UniqueKeys):
    """``yaml.SafeLoader`` that refuses an alias inside the node it names (``c: &c [*c, *c]``: a value
    that contains itself, endless to walk) and a document above :data:`MAX_NODES` values once its aliases
    are expanded."""

    def __init__(self, stream):
        super().__init__(stream)
        self._open: set = set()

    def compose_node(self, parent, index):
        if self.check_event(yaml.AliasEvent):
            event = self.peek_event()
            if event.anchor in self._open:
                raise yaml.composer.ComposerError(
                    None, None, f"the alias *{event.anchor} is inside the value &{event.anchor} names (a recursive "
                    "anchor: a value that contains itself); data files cannot hold one", event.start_mark)
            return super().compose_node(parent, index)
        anchor = getattr(self.peek_event(), "anchor", None)
        if anchor is None:
            return super().compose_node(parent, index)
        self._open.add(anchor)
        try:
            return super().compose_node(parent, index)
        finally:
            self._open.discard(anchor)


def _expanded_size(node, memo: dict) -> int:
    """Values in ``node`` with every alias expanded (a shared node counted each time it is used)."""
    key = id(node)
    if key not in memo:
        if isinstance(node, yaml.SequenceNode):
            memo[key] = 1 + sum(_expanded_size(n, memo) for n in node.value)
        elif isinstance(node, yaml.MappingNode):
            memo[key] = 1 + sum(_expanded_size(k, memo) + _expanded_size(v, memo) for k, v in node.value)
        else:
            memo[key] = 1
    return memo[key]


def _load(fh):
    loader = _DataLoader(fh)
    try:
        node = loader.get_single_node()
        if node is None:
            return None
        n = _expanded_size(node, {})
        if n > MAX_NODES:
            raise yaml.composer.ComposerError(
                None, None, f"it holds {n:.3g} values once its aliases are expanded, more than the {MAX_NODES:,} "
                "a data file may hold", None)
        return loader.construct_document(node)
    finally:
        loader.dispose()


def read_yaml(path, what: str = "model file"):
    """The document in ``path`` as plain data (VjmError naming the file on any failure)."""
    try:
        with open(path, encoding="utf-8") as fh:
            return _load(fh)
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
