"""vjm design with FEA links: a run killed by SIGKILL loses no FEA design, a rerun resumes from the cache,
and a run whose designs are all cached runs no FEA and gives the same answer."""
import json
import os
import signal
import sys
from pathlib import Path

import freshrun
import pytest

PUU = Path(__file__).resolve().parents[2] / "data" / "orthoglide" / "puu.yaml"
SPEC = f"""machine: {PUU}
links:
  leg:
    cad: parallelogram_bar
    fixed: {{boss_height: 20, height: 16}}
    free: {{width: [8, 24]}}
    compute: {{mesh_size: 6}}
constraints: {{k_tran_max: 0.0153}}
budget: 4
seed: 1
"""
ARGS = ["design", "s.yaml", "--out", "o", "--workers", "1"]


def _run(folder: Path, fault: str | None = None) -> freshrun.Result:
    """The command in a process of its own (tests/freshrun.py), SIGKILLed at ``fault`` if given; its process group
    (the Dask workers of a killed run, still computing the next design) is killed after it."""
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    env.pop("LINKFEA_FAULT", None)
    if fault:
        env["LINKFEA_FAULT"] = fault
    return freshrun.command(["vjm", *ARGS], folder, env)


@pytest.mark.skipif(sys.platform == "win32", reason="SIGKILL")
def test_a_killed_run_resumes_from_the_cache_and_a_cached_rerun_runs_no_fea(tmp_path):
    (tmp_path / "s.yaml").write_text(SPEC)
    killed = _run(tmp_path, "design-written:2")
    assert killed.returncode == -signal.SIGKILL, killed.stderr
    results = tmp_path / "o" / "links" / "leg" / "results"
    kept = sorted(p.name for p in results.glob("*.json"))
    assert len(kept) == 2 and not (tmp_path / "o" / "design.json").exists()

    resumed = _run(tmp_path)
    assert resumed.returncode == 0, resumed.stderr
    doc = json.loads((tmp_path / "o" / "design.json").read_text())
    assert doc["fea_computed"] == doc["fea_runs"] - 2           # the two killed-run designs were not redone
    assert set(kept) <= {Path(h["result"]).name for h in doc["history"]}
    assert doc["fea_runs"] <= 4 and doc["feasible"] and doc["k_tran_max"] <= 0.0153

    again = _run(tmp_path)
    assert again.returncode == 0, again.stderr
    doc2 = json.loads((tmp_path / "o" / "design.json").read_text())
    assert doc2["fea_computed"] == 0
    for k in ("parameters", "moving_mass_kg", "k_tran_max", "history", "fea_runs"):
        assert doc2[k] == doc[k]
    # the verified design's links are FEA results: the optimum's JSON is the cached result, with its STEP
    leg = json.loads((tmp_path / "o" / "optimum_leg.json").read_text())
    assert leg["mass_kg"] * 3 == pytest.approx(doc["moving_mass_kg"], rel=1e-12)
    assert (tmp_path / "o" / "optimum_leg.step").read_text(errors="replace").startswith("ISO-10303-21")
    assert doc["constraints"][0]["error_bar"] > 0                 # the FEA's error bar, carried to k_tran_max
