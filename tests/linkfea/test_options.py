"""ComputeOptions: one value, checked once, shared by compute, the CLI, the sweep and its keys."""
from __future__ import annotations

import dataclasses

import pytest

from linkfea.options import ComputeOptions
from linkfea.runtime.errors import LinkFeaError


@pytest.mark.parametrize("kw, message", [
    ({"mesh_size": 0.0}, r"^mesh_size must be > 0 mm, got 0$"),
    ({"block_ratio": 1.0}, r"^block_ratio must be > 1, got 1$"),
    ({"block_ratio": float("inf")}, r"^block_ratio must be a finite number > 1"),
    ({"envelope": 0.1}, r"^envelope must be in \(0, 0.1\), got 0.1$"),
    ({"mode": "soft"}, r"^unknown mode 'soft'; use rigid or block$"),
    ({"assembler": "x"}, r"^unknown assembler 'x'; use kernel or skfem$"),
    ({"solver": "lu"}, r"^unknown solver 'lu'; use auto, direct or iterative$"),
    ({"mesher": "tetgen"}, r"^unknown mesher 'tetgen'; use gmsh or pytetwild$"),
    ({"tolerance": 1.5}, r"^tolerance must be in \(0, 1\) \(a fraction: 0.01 = 1%\), got 1.5$"),
    ({"tolerance": float("nan")}, r"^tolerance must be a finite number in \(0, 1\)"),
    ({"tolerance": "1%"}, r"^tolerance must be a number in \(0, 1\)"),
    ({"tolerance": 0.01, "convergence": True}, r"do not go together"),
    ({"tolerance": 0.01, "mesher": "pytetwild"}, r"use --mesher gmsh"),
    ({"max_dofs": 0}, r"^max_dofs must be a whole number >= 1, got 0$"),
])
def test_bad_option_is_refused_when_made(kw, message):
    with pytest.raises(LinkFeaError, match=message):
        ComputeOptions(**kw)


def test_options_are_frozen_and_normalised():
    o = ComputeOptions(mesh_size=4, block_ratio=100)
    assert isinstance(o.mesh_size, float) and o.mesh_size == 4.0 and o.block_ratio == 100.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        o.mode = "block"  # type: ignore[misc]
    with pytest.raises(LinkFeaError, match=r"unknown compute options \['epsilon'\]"):
        ComputeOptions.from_mapping({"epsilon": 1e-3})
    assert ComputeOptions.from_mapping({"mesh_size": None, "mode": "block"}) == ComputeOptions(mode="block")


def test_block_ratio_rule_is_the_same_in_the_solver():
    """The solver applies the options' rule (> 1), not a looser one of its own."""
    from linkfea.fem.problem import solve_link

    with pytest.raises(LinkFeaError, match=r"^block_ratio must be > 1, got 0.5$"):
        solve_link(object(), None, mode="block", block_ratio=0.5)


def test_tolerance_needs_gmsh_once_the_mesher_is_resolved():
    o = ComputeOptions(tolerance=0.01)
    assert o.for_input("bar").mesher == "gmsh"
    with pytest.raises(LinkFeaError, match="use --mesher gmsh"):
        o.for_input("part.stl")


def test_key_options_spell_the_sweep_keys_as_before():
    """Design keys of existing sweeps stay valid: mode always, block ratio in block mode only, others when set."""
    assert ComputeOptions().key_options() == {"mode": "rigid"}
    assert ComputeOptions(block_ratio=50.0).key_options() == {"mode": "rigid"}
    assert ComputeOptions(mode="block").key_options() == {"mode": "block", "block_ratio": 1000.0}
    assert ComputeOptions(mesh_size=3, envelope=5e-4, convergence=True, mesher="gmsh").key_options() == \
        {"mode": "rigid", "mesh_size": 3.0, "envelope": 5e-4, "convergence": True, "mesher": "gmsh"}
    # options linkfea sweep does not take still name the design when changed
    assert ComputeOptions(solver="iterative").key_options() == {"mode": "rigid", "solver": "iterative"}


def test_sweep_key_uses_the_options_spelling():
    from linkfea.sweep import design_key, make_sweep

    a = make_sweep("bar", ["length=100,120"], {"mesh_size": 5, "convergence": False})
    b = make_sweep("bar", ["length=100,120"], ComputeOptions(mesh_size=5.0))
    assert a == b
    assert a.options == {"mode": "rigid", "mesh_size": 5.0}
    assert a.designs[0].key == design_key(a.source_sha, {"length": 100.0}, {"mode": "rigid", "mesh_size": 5.0})
    with pytest.raises(LinkFeaError, match=r"^block_ratio must be > 1"):
        make_sweep("bar", ["length=100,120"], {"mode": "block", "block_ratio": 0.5})
