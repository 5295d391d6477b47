"""The shape of the packages: short functions and files, no import circle inside src/, and only the
public names in dir().

The limits: a function (or method, nested ones included) is at most 120 lines from its ``def`` to its
last line, decorators aside; a file of src/ at most 600 lines.  A longer one is split, not exempted.

Every import counts, module-level and function-level (and ``if TYPE_CHECKING:`` ones): a lazy
import hides a circle, it does not remove it.
"""
from __future__ import annotations

import ast
import importlib
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src"
MAX_FUNCTION_LINES = 120
MAX_FILE_LINES = 600


def sizes(src: Path) -> tuple[dict[str, int], dict[str, int]]:
    """(file -> its lines, "file:line name" -> the function's lines) of every .py file under ``src``."""
    files: dict[str, int] = {}
    functions: dict[str, int] = {}
    for path in sorted(src.rglob("*.py")):
        text = path.read_text(encoding="utf-8")
        rel = path.relative_to(src).as_posix()
        files[rel] = len(text.splitlines())
        for node in ast.walk(ast.parse(text, str(path))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                assert node.end_lineno is not None
                functions[f"{rel}:{node.lineno} {node.name}"] = node.end_lineno - node.lineno + 1
    return files, functions


def test_functions_and_files_are_short():
    files, functions = sizes(SRC)
    assert "linkfea/pipeline.py" in files and any(k.endswith(" compute") for k in functions)  # the walk sees src/
    assert {k: n for k, n in functions.items() if n > MAX_FUNCTION_LINES} == {}
    assert {k: n for k, n in files.items() if n > MAX_FILE_LINES} == {}


def test_sizes_count_def_to_last_line(tmp_path):
    (tmp_path / "m.py").write_text("@decorator\ndef f(x):\n    if x:\n        return 1\n\n    return 2\n\n\n"
                                   "class A:\n    def g(self):\n        def h():\n            pass\n        return h\n")
    files, functions = sizes(tmp_path)
    assert files == {"m.py": 13}
    assert functions == {"m.py:2 f": 5, "m.py:10 g": 4, "m.py:11 h": 2}


def import_graph(src: Path) -> dict[str, set[str]]:
    """Module -> the modules of the same top-level package it imports, from the ast of every file."""
    raw: dict[str, set[str]] = {}
    for path in sorted(src.rglob("*.py")):
        rel = path.relative_to(src).with_suffix("")
        parts = list(rel.parts)
        is_pkg = parts[-1] == "__init__"
        if is_pkg:
            parts = parts[:-1]
        mod = ".".join(parts)
        pkg = parts if is_pkg else parts[:-1]
        deps: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.ImportFrom):
                base = pkg[: len(pkg) - node.level + 1] if node.level else []
                target = ".".join(base + ([node.module] if node.module else []))
                deps.add(target)
                deps.update(f"{target}.{a.name}" for a in node.names)  # ``from . import mesh``
            elif isinstance(node, ast.Import):
                deps.update(a.name for a in node.names)
        raw[mod] = deps
    mods = set(raw)
    # A package's own __init__ is not an edge of its submodules (importing a.b runs a first anyway).
    return {m: {d for d in deps if d in mods and d != m and not m.startswith(d + ".")
                and d.split(".")[0] == m.split(".")[0]} for m, deps in raw.items()}


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                found.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return sorted(found)


def test_no_import_circle_in_src():
    graph = import_graph(SRC)
    assert {"linkfea.mesh", "linkfea.mesh.gmsh", "vjm.model.machine"} <= set(graph)  # the walk sees the packages
    assert "linkfea.mesh.linkmesh" in graph["linkfea.mesh.gmsh"]  # and the edges
    assert circles(graph) == []


def test_a_lazy_import_still_makes_a_circle(tmp_path):
    pkg = tmp_path / "p"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("from .a import f\n")
    (pkg / "a.py").write_text("from . import b\n\ndef f():\n    return b\n")
    (pkg / "b.py").write_text("def g():\n    from .a import f  # lazy\n    return f\n")
    (pkg / "c.py").write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from .sub.d import D\n")
    (pkg / "sub" / "__init__.py").write_text("")
    (pkg / "sub" / "d.py").write_text("from ..c import x\n")
    (pkg / "e.py").write_text("import p.a\n")
    graph = import_graph(tmp_path)
    assert graph["p.a"] == {"p.b"} and graph["p.b"] == {"p.a"}
    assert graph["p.e"] == {"p.a"}
    assert circles(graph) == [["p.a", "p.b"], ["p.c", "p.sub.d"]]


@pytest.mark.parametrize("name", ["linkfea", "vjm"])
def test_dir_shows_the_public_names_only(name):
    pkg = importlib.import_module(name)
    importlib.import_module(f"{name}.cli")  # a loaded submodule is an attribute, yet not in dir()
    assert dir(pkg) == sorted(pkg.__all__)
    for public in pkg.__all__:
        assert getattr(pkg, public) is not None
