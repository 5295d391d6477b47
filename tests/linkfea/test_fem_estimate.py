"""The recovered-stress estimate of the compliance's discretization error (linkfea.fem.estimate).

References that do not come from the estimate: the same bar on finer structured meshes
(Richardson over three of them), whose limit is checked against Timoshenko's cantilever and
Saint-Venant's torsion within the modelling tolerances of test_fem_beam; the P2 energy identity
(the discrete compliance is below the converged one); a part with and without a sharp corner.
"""
import numpy as np
import pytest
from meshes import bar_link_mesh

from linkfea.beam.closed_form import cantilever_compliance, rect_section, rect_torsion_constant
from linkfea.fem.convergence import richardson
from linkfea.fem.estimate import SAFETY_FACTOR, estimate_error
from linkfea.fem.fit import compliance_from_solution
from linkfea.fem.p2 import lame
from linkfea.fem.problem import solve_link

L, W, HH = 200.0, 20.0, 10.0
SIZES = [(20, 4, 2), (30, 6, 3), (40, 8, 4)]  # cells of 10, 6.7 and 5 mm


@pytest.fixture(scope="module")
def sequence(steel):
    """(edge length, compliance, estimate) of the bar on three structured meshes, coarse to fine."""
    lam, mu = lame(steel)
    out = []
    for n in SIZES:
        mesh = bar_link_mesh(L, W, HH, *n)
        sol = solve_link(mesh, steel)
        C = compliance_from_solution(sol).matrix
        out.append((mesh.edge_length, C, estimate_error(sol, np.diag(C), lam, mu)))
    return out


def test_estimate_brackets_the_true_error_of_the_bar(sequence, steel):
    """On the coarsest mesh, the estimate of each diagonal entry is within [0.5, 3] x the true error.

    The true error is the coarsest value against the Richardson limit of the three meshes (the
    estimate plays no part in it); that limit agrees with Timoshenko (bending, axial) within 1%
    and with Saint-Venant's torsion within 3% (restrained warping), as in test_fem_beam.
    """
    d = np.arange(6)
    rich = richardson([s[0] for s in sequence], [s[1] for s in sequence])
    C0 = cantilever_compliance(L, rect_section(W, HH, steel.nu), steel.E, steel.nu, shear=True)
    C0[3, 3] = L / (steel.G * rect_torsion_constant(W, HH))
    limit = rich.extrapolated[d, d]
    assert np.all(np.abs(limit / C0[d, d] - 1) < [0.01, 0.01, 0.01, 0.03, 0.01, 0.01])
    for h, C, est in sequence[:2]:
        true = (limit - C[d, d]) / limit
        assert np.all(true > 0)  # P2 is too stiff: the energy identity
        eff = est.relative / true
        assert np.all((eff >= 0.5) & (eff <= 3.0)), (h, eff)


def test_estimate_bounds_the_off_diagonal_entries(sequence):
    """|C_ij - C_h,ij| <= bound_ij (Cauchy-Schwarz on the error energies), against the finest mesh's
    change for the coupling entries of the bar (Fy-rz, Fz-ry)."""
    rich = richardson([s[0] for s in sequence], [s[1] for s in sequence])
    _, C, est = sequence[0]
    for i, j in [(1, 5), (2, 4)]:
        true = abs(rich.extrapolated[i, j] - C[i, j])
        assert true <= est.bound[i, j]
        assert est.bound[i, j] < 10 * true  # not vacuous


def test_estimate_decreases_with_the_mesh_and_is_cheap_to_read(sequence):
    """The estimate falls with h (order > 1 in the relative error); ``matrix`` is the largest
    diagonal entry; the indicator holds one value per element and sums to the raw estimate."""
    rel = np.array([s[2].relative for s in sequence])
    assert np.all(np.diff(rel, axis=0) < 0)
    h = np.array([s[0] for s in sequence])
    order = np.log(rel[0] / rel[-1]) / np.log(h[0] / h[-1])
    assert np.all(order > 1.0), order
    est = sequence[-1][2]
    assert est.matrix == pytest.approx(est.relative.max())
    assert est.safety_factor == SAFETY_FACTOR
    assert len(est.indicator) == len(bar_link_mesh(L, W, HH, *SIZES[-1]).tets)
    assert np.all(est.indicator >= 0) and est.indicator.sum() >= est.raw.max()
    doc = est.to_dict()
    assert len(doc["diagonal"]) == 6 and np.array(doc["bound"]).shape == (6, 6)


def test_a_rigid_motion_has_no_estimated_error(steel):
    """A displacement field that is exactly representable (here a uniform strain, linear u) has
    a continuous stress: the recovered field equals it and the estimate is zero to round-off."""
    lam, mu = lame(steel)
    mesh = bar_link_mesh(40.0, 6.0, 4.0, 4, 2, 2)
    sol = solve_link(mesh, steel)
    x = sol.points
    u = np.stack([np.stack([1e-3 * x[:, 0], -3e-4 * x[:, 1], -3e-4 * x[:, 2]], axis=1)] * 6)
    import dataclasses

    est = estimate_error(dataclasses.replace(sol, displacements=u), np.ones(6), lam, mu)
    assert np.all(est.raw < 1e-20)


def test_pipeline_reports_the_estimate_and_the_sharp_edges(tmp_path):
    """Every compute carries the estimate (result.json, the result object); the sharp re-entrant
    edges of an L-shaped link are counted and explained, a straight bar has none."""
    import json

    import cadquery as cq

    from linkfea import ComputeOptions
    from linkfea.pipeline import compute, sharp_edges_note

    res = compute("bar", ComputeOptions(mesh_size=10.0), cache_dir=tmp_path)
    err = res.error_diagonal
    assert err is not None and err.shape == (6,) and np.all((err > 0) & (err < 0.2))
    assert res.diagnostics.sharp_edges["count"] == 0
    assert "estimate" in res.timing
    doc = json.loads(json.dumps(res.to_dict()))
    assert doc["diagnostics"]["discretization_error"]["diagonal"] == pytest.approx(list(err))
    assert "estimated discretization error" in res._repr_html_()
    from rich.console import Console

    from linkfea.cli import show

    con = Console(record=True, width=140)
    show(res, con)
    text = con.export_text()
    assert "estimated discretization error" in text and f"{100 * err[3]:.2g}%" in text

    class Link:
        body = (cq.Workplane("XY").box(40, 10, 10, centered=False)
                .union(cq.Workplane("XY").box(10, 10, 40, centered=False))).val()

    note = sharp_edges_note(Link())
    assert note["count"] == 1 and "singular" in note["note"] and "machining radius" in note["note"]
