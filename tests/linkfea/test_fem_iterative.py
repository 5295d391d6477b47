"""The iterative paths (CG + pyamg smoothed aggregation on P2; lockstep CG + the P2 / P1 / aggregation
V-cycle) against the direct factorization, and the memory-based choice between them."""
import numpy as np
import pytest
from meshes import bar_link_mesh

from linkfea.fem.fit import compliance_from_solution
from linkfea.fem.problem import solve_link
from linkfea.runtime.errors import LinkFeaError
from linkfea.solvers import multigrid
from linkfea.solvers.factorizers import auto_factorizer, factorizer_named
from linkfea.solvers.iterative import cg_amg_factorizer, cg_p1mg_factorizer, choose, direct_peak_bytes


def _scaled(A, B):
    d = np.sqrt(np.diag(B))
    return float(np.max(np.abs(A - B) / np.outer(d, d)))


@pytest.mark.parametrize("mode", ["rigid", "block"])
def test_iterative_and_direct_agree_on_a_small_link(steel, mode):
    """Same 6x6 to 1e-6 (relative to sqrt(C_ii C_jj)); CG's convergence is recorded per load case."""
    mesh = bar_link_mesh(60.0, 8.0, 6.0, 10, 2, 2, block_length=6.0, nb=1)
    direct = solve_link(mesh, steel, mode=mode)
    it = solve_link(mesh, steel, mode=mode, solver=cg_amg_factorizer)
    assert it.solver.factorizer == "cg+amg"
    conv = it.solver.convergence
    assert len(conv["iterations"]) == 6 and all(0 < n < 500 for n in conv["iterations"])
    # The stiff block (E x 1000) of block mode costs round-off in the recomputed residual.
    assert max(conv["relative_residual"]) < (1e-6 if mode == "rigid" else 1e-5)
    a, b = compliance_from_solution(direct).matrix, compliance_from_solution(it).matrix
    assert _scaled(b, a) < 1e-6


@pytest.mark.parametrize("mode,max_coarse", [("rigid", 600), ("rigid", 40), ("block", 40)])
def test_the_p1_multigrid_path_agrees_with_the_direct_solver(steel, mode, max_coarse, monkeypatch):
    """Same 6x6 to 1e-6; the hierarchy has the P1 level (and aggregation levels below it when the
    coarsest size allows), every load case converges, and the recorded residuals are true ones."""
    monkeypatch.setattr(multigrid, "MAX_COARSE", max_coarse)
    mesh = bar_link_mesh(60.0, 8.0, 6.0, 10, 2, 2, block_length=6.0, nb=1)
    direct = solve_link(mesh, steel, mode=mode)
    it = solve_link(mesh, steel, mode=mode, solver=cg_p1mg_factorizer)
    conv = it.solver.convergence
    assert it.solver.factorizer == "cg+p1mg"
    nv_free = conv["level_sizes"][1]
    assert nv_free < it.n_dofs / 4  # the P1 level: vertices only
    assert (conv["levels"] == 2) if max_coarse == 600 else (conv["levels"] >= 3)
    assert len(conv["iterations"]) == 6 and all(0 < n < 100 for n in conv["iterations"])
    assert max(conv["relative_residual"]) < (1e-6 if mode == "rigid" else 1e-5)
    a, b = compliance_from_solution(direct).matrix, compliance_from_solution(it).matrix
    assert _scaled(b, a) < 1e-6


def test_the_choice_follows_the_memory_estimate(steel, monkeypatch):
    """``choose`` scales the measured 12 GB at 871,710 DOF as n^(4/3); ``auto`` records its choice."""
    assert direct_peak_bytes(871_710) == pytest.approx(12.0e9)
    assert direct_peak_bytes(2 * 871_710) == pytest.approx(12.0e9 * 2 ** (4 / 3))
    assert choose(60_000, budget=8e9) == "direct" and choose(3_000_000, budget=8e9) == "iterative"
    assert choose(100_000, budget=1.0) == "direct"  # small links always factor: results do not depend on free memory
    mesh = bar_link_mesh(40.0, 6.0, 4.0, 8, 2, 2)
    import linkfea.solvers.iterative as iterative

    monkeypatch.setattr(iterative, "MIN_ITERATIVE_DOFS", 0)
    monkeypatch.setenv("LINKFEA_MEMORY", "1e-6")  # nothing fits: iterative
    small = solve_link(mesh, steel, solver=auto_factorizer)
    assert small.solver.choice["chosen"] == "iterative" and small.solver.factorizer == "cg+p1mg"
    monkeypatch.setenv("LINKFEA_MEMORY", "8")
    big = solve_link(mesh, steel, solver=auto_factorizer)
    assert big.solver.choice["chosen"] == "direct" and big.solver.factorizer in ("pardiso", "superlu")
    assert _scaled(compliance_from_solution(small).matrix, compliance_from_solution(big).matrix) < 1e-6
    with pytest.raises(LinkFeaError, match="unknown solver"):
        factorizer_named("gauss")


def test_the_choice_takes_the_iterative_path_where_it_is_faster():
    """Under 150k DOF always direct; from 250k always iterative (faster and lighter, measured);
    in between by the memory estimate.  Both estimates grow with the size, the iterative one linearly."""
    from linkfea.solvers.iterative import iterative_peak_bytes

    assert choose(149_999, budget=1.0) == "direct"
    assert choose(200_000, budget=1e12) == "direct" and choose(200_000, budget=1.0) == "iterative"
    assert choose(250_000, budget=1e12) == "iterative"
    assert iterative_peak_bytes(2_000_000) == pytest.approx(2 * iterative_peak_bytes(1_000_000))
    assert iterative_peak_bytes(871_710) < direct_peak_bytes(871_710) / 2


@pytest.mark.parametrize("mode", ["rigid", "block"])
def test_a_p1_level_with_nothing_to_aggregate_is_solved_directly(steel, mode, monkeypatch):
    """A P1 level above MAX_COARSE DOFs but at most MAX_COARSE 3-DOF blocks (pyamg counts blocks) gives pyamg
    nothing to coarsen: the P1 level is the coarsest, factored, and the 6x6 is the direct solver's."""
    mesh = bar_link_mesh(60.0, 8.0, 6.0, 10, 2, 2, block_length=6.0, nb=1)
    probe = solve_link(mesh, steel, mode=mode, solver=cg_p1mg_factorizer)
    n_p1 = probe.solver.convergence["level_sizes"][1]
    monkeypatch.setattr(multigrid, "MAX_COARSE", n_p1 // 2)  # above in DOFs, below in 3-DOF blocks
    it = solve_link(mesh, steel, mode=mode, solver=cg_p1mg_factorizer)
    assert it.solver.convergence["level_sizes"] == [it.n_dofs, n_p1]
    direct = solve_link(mesh, steel, mode=mode)
    assert _scaled(compliance_from_solution(it).matrix, compliance_from_solution(direct).matrix) < 1e-6
