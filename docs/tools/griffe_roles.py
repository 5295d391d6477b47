"""Griffe extension for the API pages: the docstrings' Sphinx roles as cross-references.

The docstrings of ``src/`` name other objects as Sphinx does (``:class:`~vjm.maps.grid.Grid```,
``:func:`compute_map```, ``:mod:`.common```); markdown would show the role as text.  Each role becomes an
autorefs link, ``[`Grid`][vjm.maps.grid.Grid]``, when its target resolves, in the scope of the docstring's
object, to a public object the API pages show; else plain code (a constant known by its ``#:`` comment
only, a private helper), so that the strict build never meets a link it cannot resolve.  Loaded by
``mkdocs.yml``, after the doctest fences.
"""
from __future__ import annotations

import re

import griffe

#: a Sphinx cross-reference role: ``:kind:`target``` or ``:kind:`title <target>```
ROLE = re.compile(r":(?:py:)?(class|func|meth|mod|data|attr|exc|obj|const|any):`([^`]+)`")
#: where the API pages start: objects outside are never shown
PACKAGES = ("vjm", "linkfea")
_FENCE = re.compile(r"^```.*?^```", re.S | re.M)


def _member(collection, path: str):
    """The object at dotted ``path`` in the loaded packages, aliases followed; None if there is none."""
    parts = path.split(".")
    try:
        obj = collection.members[parts[0]]
        for name in parts[1:]:
            obj = obj.members[name]
        return obj.final_target if obj.is_alias else obj
    except (KeyError, griffe.AliasResolutionError, griffe.CyclicAliasError):
        return None


def _shown(obj) -> bool:
    """Does the API page render ``obj`` (public all the way down, documented, in one of the packages)?"""
    if obj is None or obj.path.split(".")[0] not in PACKAGES:
        return False
    if any(part.startswith("_") and part != "__init__" for part in obj.path.split(".")):
        return False
    o = obj
    while o is not None:
        if not (o.docstring and o.docstring.value.strip()) and not o.is_module:
            return False
        o = o.parent
    return True


def _candidates(obj, target: str) -> list[str]:
    """The dotted paths ``target`` may name, seen from ``obj``'s docstring, most likely first."""
    module = obj if obj.is_module else obj.module
    if target.startswith("."):
        dots = len(target) - len(target.lstrip("."))
        base = module.path.split(".") if module.is_package else module.path.split(".")[:-1]
        base = base[:len(base) - (dots - 1)] if dots > 1 else base
        return [".".join([*base, target.lstrip(".")]), f"{module.path}{target}"]
    out = [target]
    scope = obj
    while scope is not None:  # the object's own members, its class's, its module's, up
        out.append(f"{scope.path}.{target}")
        scope = scope.parent
    head, _, rest = target.partition(".")
    try:
        full = module.resolve(head)  # a name the module imports
    except (griffe.NameResolutionError, ValueError):
        full = None
    if full:
        out.append(f"{full}.{rest}" if rest else full)
    return out


def convert_roles(text: str, obj, collection) -> str:
    """``text`` with every role outside code fences made a cross-reference or plain code."""
    def one(m: re.Match) -> str:
        body = m.group(2).strip()
        title = None
        explicit = re.fullmatch(r"(.*?)\s*<([^>]+)>", body)
        if explicit:
            title, body = explicit.group(1), explicit.group(2)
        short = body.startswith("~")
        target = body.lstrip("~!").rstrip("()")
        shown = title or (target.split(".")[-1] if short else target.lstrip("."))
        for path in _candidates(obj, target):
            found = _member(collection, path)
            if _shown(found):
                return f"[`{shown}`][{found.path}]"
        return f"`{shown}`"

    pieces, last = [], 0
    for fence in _FENCE.finditer(text):
        pieces.append(ROLE.sub(one, text[last:fence.start()]))
        pieces.append(fence.group(0))
        last = fence.end()
    pieces.append(ROLE.sub(one, text[last:]))
    return "".join(pieces)


def _walk(obj):
    yield obj
    for member in obj.members.values():
        if not member.is_alias:
            yield from _walk(member)


class SphinxRoles(griffe.Extension):
    """Convert the roles of every docstring of a package once it is loaded (names resolve then)."""

    def on_package(self, *, pkg: griffe.Module, loader: griffe.GriffeLoader, **kwargs: object) -> None:
        for obj in _walk(pkg):
            if obj.docstring is not None and ":" in obj.docstring.value:
                obj.docstring.value = convert_roles(obj.docstring.value, obj, loader.modules_collection)
