"""The robot formats a model file may hold, as a registry of readers (in the style of pinocchio's ``parsers``).

A reader is an object (a module, usually) with

* ``KEYS``: the top-level keys of a model file it reads (``("urdf",)``);
* ``DESCRIBES``: how a message names it (``"urdf: (a file)"``);
* ``recognises(mapping) -> bool``: whether a model file's mapping is of this format;
* ``read(mapping, base_dir) -> Tree``: the kinematic tree (:class:`vjm.robot.tree.Tree`, mm, kg) it describes,
  ``base_dir`` the folder the model file's paths are relative to.

The springs, masses, payload, gravity, tools and home of the file are read once for every format by
:mod:`vjm.modelio.robotfile`.  A new format is one module and one entry of :data:`READERS`.
"""
from __future__ import annotations

from typing import Protocol

from . import dh, urdf


class RobotReader(Protocol):
    KEYS: tuple[str, ...]
    DESCRIBES: str

    def recognises(self, mapping) -> bool: ...

    def read(self, mapping: dict, base_dir: str): ...


#: name -> reader, in the order messages list them
READERS: dict[str, RobotReader] = {"urdf": urdf, "dh": dh}   # type: ignore[dict-item]


def recognised(mapping) -> list[str]:
    """The names of the readers that recognise a model file's mapping."""
    return [name for name, r in READERS.items() if r.recognises(mapping)]


def format_keys() -> tuple[str, ...]:
    """The top-level keys the registered formats read."""
    return tuple(k for r in READERS.values() for k in r.KEYS)


def one_of() -> str:
    """The registered formats as a message lists them: ``urdf: (a file) and dh: (a table)``."""
    names = [r.DESCRIBES for r in READERS.values()]
    return names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]
