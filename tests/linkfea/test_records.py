"""The typed records of a link result write the result JSON's objects with the keys in the order the JSON
has always had, and read them back unchanged (the JSON stays byte-identical through them)."""
import json

from linkfea.result.records import Diagnostics, MeshInfo
from linkfea.solvers.factorization import Factorization, SolverRecord
from linkfea.solvers.factorizers import auto_factorizer, default_factorizer, needs
from linkfea.solvers.iterative import cg_amg_factorizer, cg_p1mg_factorizer

PLAIN = {"error_estimate": None, "error_estimate_note": "not computed",
         "discretization_error": {"diagonal": [0.01] * 6, "matrix": 0.01}, "sharp_edges": {"count": 0, "note": "none"},
         "symmetry_error": 1e-14, "fit_residual": 2e-14, "min_eigenvalue": 3e-9}
REFINED = {"refinement": {"reached": True, "steps": []}, **PLAIN}
CONVERGED = {"error_estimate": 0.02, "observed_order": 1.9, "convergence_sizes": [10.0, 7.07, 5.0],
             "error_estimate_note": "Richardson", **{k: v for k, v in PLAIN.items() if not k.startswith("error_estimate")}}


def test_diagnostics_keep_the_json_order_of_each_kind_of_run():
    for doc in (PLAIN, REFINED, CONVERGED):
        back = Diagnostics.from_dict(json.loads(json.dumps(doc))).to_dict()
        assert json.dumps(back) == json.dumps(doc)


def test_mesh_info_round_trips_in_order():
    doc = {"mesher": "gmsh", "mesher_version": "4.15.2", "n_nodes": 10, "n_tets": 20, "n_dofs": 90, "n_p2_nodes": 40,
           "edge_length": 4.5, "envelope": 0.0, "element": "P2 tetrahedron (10 nodes)",
           "quality": {"radius_ratio_min": 0.1}, "cache_key": ""}
    assert json.dumps(MeshInfo.from_dict(doc).to_dict()) == json.dumps(doc)


def test_solver_record_writes_convergence_and_choice_only_when_there_are():
    direct = SolverRecord.of("kernel", Factorization(print, "pardiso"))
    assert list(direct.to_dict()) == ["assembler", "factorizer", "fallback_reason"]
    cg = SolverRecord.of("kernel", Factorization(print, "cg+p1mg", convergence={"iterations": [3]}, choice={"chosen": "x"}))
    assert list(cg.to_dict()) == ["assembler", "factorizer", "fallback_reason", "convergence", "choice"]
    assert SolverRecord.from_dict(cg.to_dict()) == cg


def test_what_each_factorizer_needs_besides_the_matrix():
    assert needs(auto_factorizer) == needs(cg_p1mg_factorizer) == "coarse_space"
    assert needs(cg_amg_factorizer) == "near_nullspace"
    assert needs(default_factorizer) == ""
