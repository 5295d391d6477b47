"""The wheel installs like any other package and runs the README's commands from any folder.

The wheel is built from a copy of the source tree, installed without dependencies into a
fresh venv in a temporary folder (the venv sees the test interpreter's site-packages through
a ``.pth`` line, so numpy, cadquery ... are not reinstalled), and the commands run from yet
another folder with ``PYTHONPATH`` cleared: the bundled CAD scripts, model files and seed
table must come from the installed package, not from the checkout.
"""
import json
import os
import shutil
import site
import subprocess
import sys
import sysconfig
import venv
from pathlib import Path

import numpy as np
import pytest

from linkfea.beam.closed_form import cantilever_compliance, rect_section
from linkfea.mechanics.materials import get_material

ROOT = Path(__file__).resolve().parents[1]
pytestmark = pytest.mark.slow


def _run(cmd, cwd, env, timeout=600):
    p = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    assert p.returncode == 0, f"{cmd} failed ({p.returncode}):\n{p.stdout[-2000:]}\n{p.stderr[-3000:]}"
    return p


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """(bin folder, env, working folder) of a fresh venv holding only the built wheel."""
    tmp = tmp_path_factory.mktemp("wheel")
    src = tmp / "src-copy"
    ignore = shutil.ignore_patterns("__pycache__", "*.egg-info", "build", ".venv", ".cache", "out", "*.pyc")
    src.mkdir()
    for name in ("pyproject.toml", "setup.py", "README.md", "src", "cad", "data"):
        s = ROOT / name
        (shutil.copytree(s, src / name, ignore=ignore) if s.is_dir() else shutil.copy2(s, src / name))
    base = dict(os.environ)
    base.pop("PYTHONPATH", None)
    dist = tmp / "dist"
    _run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "--no-build-isolation", "-w", str(dist),
          str(src)], tmp, base)
    wheels = list(dist.glob("linkfea_vjm-*.whl"))
    assert len(wheels) == 1

    env_dir = tmp / "venv"
    venv.create(env_dir, with_pip=False, symlinks=True)
    py = env_dir / "bin" / "python"
    _run([sys.executable, "-m", "pip", "--python", str(py), "install", "-q", "--no-deps", "--no-index",
          str(wheels[0])], tmp, base)
    # Dependencies from the test interpreter's site-packages; a plain path line does not run
    # their .pth files, so an editable install of the checkout there stays out of sys.path.
    target = Path(_run([str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                       tmp, base).stdout.strip())
    shared = [p for p in dict.fromkeys(site.getsitepackages() + [sysconfig.get_paths()["purelib"]])
              if Path(p).is_dir()]
    (target / "_shared_deps.pth").write_text("\n".join(shared) + "\n")

    work = tmp / "elsewhere"
    work.mkdir()
    env = dict(base, LINKFEA_CACHE_DIR=str(tmp / "mesh-cache"), MPLBACKEND="Agg")
    where = _run([str(py), "-c", "import linkfea, vjm; print(linkfea.__file__); print(vjm.__file__)"],
                 work, env).stdout.split()
    for f in where:
        assert Path(f).is_relative_to(env_dir), f"imported from {f}, not from the installed wheel"
    return env_dir / "bin", env, work


def test_wheel_linkfea_compute_bundled_bar(installed):
    """`linkfea compute bar --no-picture` from another folder: the bundled script, a cantilever result.

    Check: C_yy of the 200 x 20 x 10 mm steel bar within 2% of Timoshenko (eq. 14 + shear),
    as the validation tests find for this link.
    """
    bindir, env, work = installed
    _run([str(bindir / "linkfea"), "compute", "bar", "--no-picture", "-q", "--out", "bar.json"], work, env)
    doc = json.loads((work / "bar.json").read_text())
    assert Path(doc["source"]).is_relative_to(bindir.parent), doc["source"]
    steel = get_material("steel")
    C_ref = cantilever_compliance(200.0, rect_section(20.0, 10.0, steel.nu), steel.E, steel.nu, shear=True)
    assert np.asarray(doc["compliance"])[1, 1] == pytest.approx(C_ref[1, 1], rel=0.02)


def test_wheel_vjm_table1_bundled_models(installed):
    """`vjm table1` with the README's model paths, from a folder that has no data/."""
    bindir, env, work = installed
    out = _run([str(bindir / "vjm"), "table1", "data/orthoglide/puu.yaml", "data/orthoglide/prpar.yaml"],
               work, env).stdout
    rows = [ln.split() for ln in out.splitlines() if ln.startswith("orthoglide-") and " Q" in ln]
    assert [r[1] for r in rows] == ["Q0", "Q1", "Q2"] * 2
    # The actuator stiffness of the bundled models is set so that k_tran(Q0) matches the seed.
    for r in rows:
        if r[1] == "Q0":
            assert float(r[4]) == pytest.approx(1.0, abs=0.01)


def test_wheel_vjm_diagnose_bundled_example(installed):
    """`vjm diagnose` on the bundled 3-PUU model and the seed's Table 1, from another folder."""
    bindir, env, work = installed
    _run([str(bindir / "vjm"), "diagnose", "puu", "seed_table1.csv", "--out", "diag"], work, env)
    report = json.loads((work / "diag" / "report.json").read_text())
    assert (work / "diag" / "report.html").stat().st_size > 0
    # The seed's Table 1 has k_tran and k_rot at Q0, Q1, Q2 for the 3-PUU: 6 observations.
    assert report["n_observations"] == 6
