"""``python -m vjm.kernels`` compiles every kernel ahead of use: its groups' public calls reach the
compiled path (a dispatcher of each kernel module holds a compiled signature afterwards), in a fresh
process, so what other tests compiled in this one does not count."""
import subprocess
import sys
from pathlib import Path

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
