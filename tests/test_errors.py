"""Error types: bad input is a ValueError, a failed solve a RuntimeError; both stay one-line CLI errors."""
import dataclasses

import numpy as np
import pytest
from meshes import bar_link_mesh

import vjm
from linkfea.beam.closed_form import Section
from linkfea.fem.fit import check_compliance
from linkfea.fem.problem import solve_link
from linkfea.runtime.errors import LinkFeaError, SolverError
from vjm.errors import EquilibriumError, VjmError, user_errors
from vjm.stiffness.nonlinear import deflection_map

PUU = "data/orthoglide/puu.yaml"


def _raised(call):
    try:
        call()
    except Exception as exc:  # the test inspects whatever was raised
        return exc
    return None


def test_bad_input_is_caught_by_except_value_error(tmp_path):
    """A missing model file, a negative section constant, an indefinite matrix: all caught as ValueError."""
    bad = tmp_path / "m.yaml"
    bad.write_text("architecture: no-such-machine\n")
    calls = [lambda: vjm.load_model(tmp_path / "missing.yaml"),
             lambda: vjm.load_model(bad),
             lambda: Section(A=-1.0, Iy=1.0, Iz=1.0, J=1.0, Asy=1.0, Asz=1.0),
             lambda: check_compliance(np.diag([1.0, 1.0, 1.0, 1.0, 1.0, -1.0]))]
    caught = []
    for call in calls:
        try:
            call()
        except ValueError as exc:
            caught.append(exc)
    assert [type(e) for e in caught] == [VjmError, VjmError, LinkFeaError, LinkFeaError]
    assert not any(isinstance(e, RuntimeError) for e in caught)


def test_singular_stiffness_is_a_runtime_error(steel):
    """A piece not connected to the clamp makes K singular: a SolverError, i.e. a RuntimeError."""
    mesh = bar_link_mesh(40.0, 6.0, 4.0, 4, 2, 2)
    n = len(mesh.points)
    far = np.array([[100.0, 0, 0], [101.0, 0, 0], [100.0, 1, 0], [100.0, 0, 1]])
    bad = dataclasses.replace(mesh, points=np.vstack([mesh.points, far]),
                              tets=np.vstack([mesh.tets, [[n, n + 1, n + 2, n + 3]]]),
                              block=np.r_[mesh.block, False])
    exc = _raised(lambda: solve_link(bad, steel))
    assert isinstance(exc, SolverError) and isinstance(exc, RuntimeError)
    assert isinstance(exc, LinkFeaError)  # the CLI still reports it on one line


def test_equilibrium_not_found_is_a_runtime_error():
    """10 kN m about x and y has no equilibrium reachable by load stepping (see test_vjm_nonlinear)."""
    puu = vjm.load_model(PUU)
    P = np.array([[0.0, 0.0, 0.0]])
    W = np.array([[0.0, 0.0, 0.0, 1e7, 1e7, 0.0]])
    with pytest.raises(RuntimeError, match="equilibrium not found") as info:
        deflection_map(puu, P, W)
    assert isinstance(info.value, EquilibriumError)
    assert isinstance(info.value, user_errors())
