"""`linkfea compare` on a coarse bar, and its bad-input behaviour (issue 3: command, N <= 0)."""
import json

import numpy as np
import pytest
from typer.testing import CliRunner

from linkfea.beam.closed_form import cantilever_compliance, rect_section
from linkfea.cli import app
from linkfea.files.outputs import MANIFEST
from linkfea.mechanics.materials import get_material

FILES = ["compare.json", "compare.md", "compare.png"]


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return str(tmp_path_factory.mktemp("meshes"))


@pytest.fixture(scope="module")
def run_ok(tmp_path_factory, cache):
    out = tmp_path_factory.mktemp("cmp") / "bar"
    r = CliRunner().invoke(app, ["compare", "bar", "--beams", "2,1", "--param", "length=120", "--mesh-size", "6",
                                 "--out", str(out)], env={"LINKFEA_CACHE_DIR": cache})
    assert r.exit_code == 0, r.output
    return out, r.output


def test_compare_writes_json_md_png(run_ok):
    """A 120 x 20 x 10 steel bar.  Truth for the beam side: the closed-form cantilever (seed eq. 14,
    rectangle J by its series solution, Cowper kappa), independent of the sectionproperties cut;
    tolerance 0.5 % (sectionproperties' FE torsion and shear functions on its own section mesh).
    Truth for the FEA side, loosely: the bar's bending and axial compliances are beam-like within
    5 % (coarse 6 mm P2 mesh, L/h = 6 so clamp end effects of a few %).  Outputs complete, no
    temporary files left."""
    out, text = run_ok
    assert sorted(p.name for p in out.iterdir() if p.name != MANIFEST) == FILES
    doc = json.loads((out / "compare.json").read_text())
    assert doc["link"] == "bar" and doc["params"]["length"] == 120.0 and doc["beam_length"] == pytest.approx(120.0)
    assert [m["n"] for m in doc["beams"]] == [1, 2]
    steel = get_material("steel")
    sec = rect_section(20.0, 10.0, steel.nu)
    for m in doc["beams"]:
        for key, shear in (("compliance_euler_bernoulli", False), ("compliance_timoshenko", True)):
            Cb = cantilever_compliance(120.0, sec, steel.E, steel.nu, shear=shear)
            np.testing.assert_allclose(m[key], Cb, rtol=5e-3, atol=1e-9 * np.abs(Cb).max())
    C = np.array(doc["fea"]["compliance"])
    Ct = cantilever_compliance(120.0, sec, steel.E, steel.nu, shear=True)
    idx = [0, 1, 2, 4, 5]
    np.testing.assert_allclose(np.diag(C)[idx], np.diag(Ct)[idx], rtol=0.05)
    png = (out / "compare.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000
    md = (out / "compare.md").read_text()
    assert "| Timoshenko | 1 |" in md and "| Euler-Bernoulli | 2 |" in md
    assert "Timoshenko" in text and "compare.png" in text


@pytest.mark.parametrize("beams", ["0", "1,-2", "2,x", ""])
def test_bad_number_of_beams_one_error_line_no_output(beams, tmp_path, cache):
    """N <= 0 (or not a number): exit 2, one `error:` line on stderr, the output folder not created."""
    out = tmp_path / "o"
    r = CliRunner().invoke(app, ["compare", "bar", "--beams", beams, "--out", str(out)],
                           env={"LINKFEA_CACHE_DIR": cache})
    assert r.exit_code == 2
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: --beams"), r.stderr
    assert not out.exists()


@pytest.mark.parametrize("args", [
    ["--param", "colour=red"],
    ["--param", "length"],
    ["--mode", "elastic"],
    ["--mesh-size", "-1"],
])
def test_bad_input_one_error_line_no_output(args, tmp_path, cache):
    out = tmp_path / "o"
    r = CliRunner().invoke(app, ["compare", "bar", *args, "--out", str(out)], env={"LINKFEA_CACHE_DIR": cache})
    assert r.exit_code == 2
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), r.stderr
    assert not out.exists()


def test_out_is_a_file_leaves_it_alone(tmp_path, cache):
    """--out naming an existing file: error before the computation, the file untouched, nothing else written."""
    out = tmp_path / "taken"
    out.write_text("keep")
    r = CliRunner().invoke(app, ["compare", "bar", "--out", str(out)], env={"LINKFEA_CACHE_DIR": cache})
    assert r.exit_code == 2 and "not a directory" in r.stderr
    assert out.read_text() == "keep" and sorted(p.name for p in tmp_path.iterdir()) == ["taken"]
