"""Shared pytest fixtures, and how xdist shares the suite's tests between its workers."""
import os
import sys

import pytest

# Shared test helpers live next to the tests (tests/meshes.py, truth.py, brackets.py).
sys.path.insert(0, os.path.dirname(__file__))

# One OpenBLAS thread per process: the suite's workers (and the commands they start) already fill the
# cores, and OpenBLAS's threads on top of them wait on each other over the suite's small matrices (a
# diagnosis test took 15 s of wall time with one thread against 36 s with two on a busy 2-core machine).
# Set here, before numpy loads OpenBLAS, and inherited by the xdist workers and every subprocess.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from linkfea.mechanics.materials import get_material


@pytest.fixture(scope="session")
def steel():
    """Steel, E = 210 GPa, nu = 0.3 (N, mm, MPa)."""
    return get_material("steel")


#: test files whose tests are long (diagnoses) and whose module setup is cheap: under ``make test``
#: (``-n 2 --dist loadfile``) their tests go to the workers one by one, so that no single file
#: bounds the suite's time; every other file runs whole on one worker (module fixtures such as
#: meshes and FEA solutions built once)
SPREAD = {
    "test_bad_inputs.py",  # one subprocess per case, no fixture
    "test_docs.py",  # one fresh interpreter per block, no fixture
    "test_diagnose_truth.py",
    "test_diagnose_truth_prpar.py",
    "test_discrepancy_effects.py",
    "test_discrepancy_verdict.py",
    "test_discrepancy_workflow.py",
}


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config, log):
    """``--dist loadfile``, except for the files of :data:`SPREAD` (xdist's ``loadgroup`` would do
    this with marks, but it loses its groups under pytest 9: pytest-xdist issue 1386)."""
    if config.getvalue("dist") != "loadfile":
        return None
    from xdist.scheduler import LoadFileScheduling

    class SpreadFileScheduling(LoadFileScheduling):
        def _split_scope(self, nodeid: str) -> str:
            path = nodeid.split("::", 1)[0]
            return nodeid if os.path.basename(path) in SPREAD else path

    return SpreadFileScheduling(config, log)
