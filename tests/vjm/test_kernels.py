"""``python -m vjm.kernels`` compiles every kernel ahead of use: its groups' public calls reach the
compiled path (a dispatcher of each kernel module holds a compiled signature afterwards), in a fresh
process, so what other tests compiled in this one does not count."""
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

import vjm
from vjm import kernels

ROOT = Path(vjm.__file__).parent
#: every kernel module of the package (compiled functions called from Python live in modules named
#: ``*kernel``; their compiled helpers elsewhere, such as nonlinear_block, are compiled into them)
MODULES = sorted("vjm." + ".".join(p.relative_to(ROOT).with_suffix("").parts) for p in ROOT.rglob("*kernel.py")
                 if "@njit" in p.read_text())

PROBE = """
import importlib, sys
from numba.core.registry import CPUDispatcher
from vjm import kernels
kernels.compile_groups(kernels.GROUPS)
for name in sys.argv[1:]:
    mod = importlib.import_module(name)
    used = [k for k, v in vars(mod).items() if isinstance(v, CPUDispatcher) and v.signatures]
    print(name, len(used))
"""


def test_the_groups_reach_every_kernel():
    out = subprocess.run([sys.executable, "-c", PROBE, *MODULES], capture_output=True, text=True,
                         check=True).stdout.split()
    counts = dict(zip(out[::2], map(int, out[1::2])))
    assert set(counts) == set(MODULES) and all(counts[m] > 0 for m in MODULES), counts


def test_unknown_group_is_one_error_line(capsys):
    assert kernels.main(["mapp"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error:") and "map" in err[0]


FIT_PROBE = """
import numpy as np, vjm
from vjm.effects import modelops
from vjm.maps import map_kernel
from vjm.stiffness import linear
m = vjm.load_model("puu")
P = np.array([[0.0, 0.0, 0.0], [10.0, -5.0, 3.0], [-8.0, 4.0, 12.0]])
print(linear.kernels_compiled(), modelops.compliance_map(m, P, repeated=True).shape, len(map_kernel.machine_block.signatures))
"""


def test_a_small_fit_never_waits_for_the_compiler(tmp_path):
    """A fit's maps of a few poses run the numpy path while the kernels are not compiled (an empty numba
    cache: a first small diagnosis after a pip install), and the kernels once they are."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    env.pop("VJM_MAP_KERNEL", None)
    out = subprocess.run([sys.executable, "-c", FIT_PROBE], capture_output=True, text=True, check=True,
                         env=env).stdout.split()
    assert out[0] == "False" and out[-1] == "0", out   # nothing compiled, and no compile started


def test_a_fit_runs_the_kernels_once_they_are_compiled(monkeypatch):
    from vjm.effects import modelops

    asked = []
    m = vjm.load_model("puu")
    monkeypatch.setattr(type(m), "stiffness_map", lambda self, P, kernel=None: asked.append(kernel))
    monkeypatch.delenv("VJM_MAP_KERNEL", raising=False)
    for compiled in (True, False):
        monkeypatch.setattr(modelops, "kernels_compiled", lambda c=compiled: c)
        modelops.stiffness_result(m, np.zeros((3, 3)), repeated=True)
        modelops.stiffness_result(m, np.zeros((modelops.REPEATED_FROM, 3)), repeated=True)
        modelops.stiffness_result(m, np.zeros((3, 3)))
    assert asked == ["numba", "numba", None, None, "numba", None]
