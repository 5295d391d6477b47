"""Which file a bare name means: a local file wins over the bundled one, with a warning naming both,
and the result records the file used (absolute path and SHA-256).

The local script differs from the bundled one (a 150 mm bar instead of 200 mm), so the frame of
the result tells which one ran, independently of what the result says about its source.
"""
import hashlib
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from linkfea.runtime.errors import LinkFeaError, LinkFeaWarning
from linkfea.runtime.resources import cad_dir, find_script
from vjm.errors import VjmWarning
from vjm.resources import data_dir, data_file

BUNDLED_BAR = cad_dir() / "bar.py"
VJM = str(Path(sys.executable).parent / "vjm")


def _local_bar(folder: Path, length: float = 150.0) -> Path:
    p = folder / "cad" / "bar.py"
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(BUNDLED_BAR.read_text().replace('"length": 200.0', f'"length": {length}'))
    assert p.read_text() != BUNDLED_BAR.read_text()
    return p


def test_bare_name_prefers_a_local_script_and_warns(tmp_path, monkeypatch):
    local = _local_bar(tmp_path)
    monkeypatch.chdir(tmp_path)
    with pytest.warns(LinkFeaWarning, match=r"bar: using .*cad/bar\.py from this folder, not the bundled script"):
        assert find_script("bar") == local.resolve()
    with pytest.warns(LinkFeaWarning):
        assert find_script("bar.py") == local.resolve()
    # the bundled script stays reachable by its path
    assert find_script(str(BUNDLED_BAR)) == BUNDLED_BAR.resolve()


def test_bare_name_without_a_local_script_is_the_bundled_one(tmp_path, monkeypatch):
    import warnings

    monkeypatch.chdir(tmp_path)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert find_script("bar") == BUNDLED_BAR.resolve()
        assert find_script("cad/bar.py") == BUNDLED_BAR.resolve()  # the README's path, from any folder
    with pytest.raises(LinkFeaError, match="no link script or STEP file 'nothing'; bundled scripts: .*bar"):
        find_script("nothing")


def test_two_different_local_scripts_are_ambiguous(tmp_path, monkeypatch):
    _local_bar(tmp_path)
    (tmp_path / "bar.py").write_text(BUNDLED_BAR.read_text().replace('"length": 200.0', '"length": 120.0'))
    monkeypatch.chdir(tmp_path)
    with pytest.raises(LinkFeaError, match=r"two different local scripts \./bar\.py and \./cad/bar\.py"):
        find_script("bar")


def test_result_records_the_script_that_ran(tmp_path, monkeypatch):
    from linkfea import ComputeOptions
    from linkfea.pipeline import compute

    local = _local_bar(tmp_path)
    monkeypatch.chdir(tmp_path)
    with pytest.warns(LinkFeaWarning, match="from this folder"):
        res = compute("bar", ComputeOptions(mesh_size=10.0))
    assert res.frame.origin[0] == pytest.approx(150.0)  # the local 150 mm bar ran, not the bundled 200 mm one
    assert res.source == str(local.resolve())
    assert res.source_sha256 == hashlib.sha256(local.read_bytes()).hexdigest()
    doc = res.to_dict()
    assert doc["source"] == str(local.resolve()) and doc["source_sha256"] == res.source_sha256


def test_cli_names_the_script_and_warns_once(tmp_path):
    local = _local_bar(tmp_path)
    env = {**os.environ, "LINKFEA_CACHE_DIR": str(tmp_path / "cache")}
    p = subprocess.run([sys.executable, "-m", "linkfea", "compute", "bar", "--mesh-size", "10", "--no-picture",
                        "--out", "r.json"], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    warn = [ln for ln in p.stderr.splitlines() if ln.startswith("warning:")]
    assert len(warn) == 1 and str(local.resolve()) in warn[0] and str(BUNDLED_BAR.resolve()) in warn[0], p.stderr
    assert "Traceback" not in p.stderr
    sha = hashlib.sha256(local.read_bytes()).hexdigest()
    assert f"source: {local.resolve()} (sha256 {sha[:16]}" in p.stdout.replace("\n", ""), p.stdout
    doc = json.loads((tmp_path / "r.json").read_text())
    assert doc["source"] == str(local.resolve()) and doc["source_sha256"] == sha


# --------------------------------------------------------------------------- vjm model names
def test_vjm_bare_name_prefers_a_local_model_and_warns(tmp_path, monkeypatch):
    bundled = data_dir() / "orthoglide" / "puu.yaml"
    monkeypatch.chdir(tmp_path)
    assert data_file("puu").resolve() == bundled.resolve()  # no local file: the bundled one
    (tmp_path / "puu.yaml").write_text(bundled.read_text().replace("stiffness: 3816.1", "stiffness: 1908.0"))
    with pytest.warns(VjmWarning, match=r"puu: using .*puu\.yaml from this folder, not the bundled orthoglide/puu"):
        assert data_file("puu").resolve() == (tmp_path / "puu.yaml").resolve()


def test_vjm_stiffness_records_the_model_file(tmp_path):
    bundled = data_dir() / "orthoglide" / "puu.yaml"
    text = bundled.read_text().replace("stiffness: 3816.1", "stiffness: 1908.0")
    assert text != bundled.read_text()
    (tmp_path / "puu.yaml").write_text(text)

    def run(cwd):
        p = subprocess.run([VJM, "stiffness", "puu", "--at", "0,0,0", "--json"],
                           cwd=cwd, capture_output=True, text=True, timeout=120)
        assert p.returncode == 0, p.stderr
        return json.loads(p.stdout), p.stderr

    doc, err = run(tmp_path)
    local = (tmp_path / "puu.yaml").resolve()
    assert doc["model_file"] == {"path": str(local), "sha256": hashlib.sha256(local.read_bytes()).hexdigest()}
    assert len([ln for ln in err.splitlines() if ln.startswith("warning:")]) == 1 and str(local) in err
    away = tmp_path / "elsewhere"
    away.mkdir()
    doc2, err2 = run(away)
    assert doc2["model_file"]["path"] == str(bundled.resolve()) and "warning" not in err2
    # the halved actuator stiffness shows in the result: the local file is the one that was used
    assert doc["k_tran_mm_per_N"] > doc2["k_tran_mm_per_N"]


def test_a_local_copy_of_the_bundled_file_needs_no_warning(tmp_path, monkeypatch):
    import warnings

    (tmp_path / "cad").mkdir()
    (tmp_path / "cad" / "bar.py").write_bytes(BUNDLED_BAR.read_bytes())
    (tmp_path / "puu.yaml").write_bytes((data_dir() / "orthoglide" / "puu.yaml").read_bytes())
    monkeypatch.chdir(tmp_path)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert find_script("bar") == (tmp_path / "cad" / "bar.py").resolve()
        assert data_file("puu").resolve() == (tmp_path / "puu.yaml").resolve()


def test_shipped_files_have_one_place_decided_by_where_the_package_runs(tmp_path, monkeypatch):
    """From this source tree: the top-level cad/ and data/.  An installed package (here a stand-in in a
    site folder, without its _cad folder): its own folder, never the checkout's files beside it."""
    from linkfea.runtime.resources import CHECKOUT, shipped_dir

    assert cad_dir() == CHECKOUT / "cad" and data_dir() == CHECKOUT / "data"
    site = tmp_path / "site"
    (site / "standin_pkg").mkdir(parents=True)
    (site / "standin_pkg" / "__init__.py").write_text("")
    monkeypatch.syspath_prepend(str(site))
    assert (CHECKOUT / "cad").is_dir()
    assert shipped_dir("standin_pkg", "_cad", "cad") == (site / "standin_pkg" / "_cad").resolve()
