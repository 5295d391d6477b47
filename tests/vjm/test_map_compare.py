"""Comparable maps: titles that name the model and its links, and ``vjm map --compare OTHER``.

The ratio is checked against the two maps' own saved values (their map.npz, read here with numpy, no vjm
code), point by point; the other folder is only read; a grid that differs is refused before anything is
written.
"""
import hashlib
import json

import numpy as np
import pytest
from typer.testing import CliRunner

import vjm
from linkfea.mechanics.compliance import UNITS
from linkfea.mechanics.frames import Frame
from vjm.cli import app

PUU = "data/orthoglide/puu.yaml"
GRID = ["--grid", "7", "--slice", "z=0"]


def _leg(path, scale):
    """A linkfea result JSON of the 3-PUU's leg, its compliance ``scale`` times the bundled beam's."""
    m = vjm.load_model("puu")
    doc = {"schema": "linkfea.result/1", "compliance": (scale * np.asarray(m.leg.compliance)).tolist(),
           "frame": Frame(np.zeros(3), np.eye(3)).to_dict(), "units": UNITS}
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(doc))
    return path


def _digests(folder):
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.iterdir())}


@pytest.fixture(scope="module")
def two_maps(tmp_path_factory):
    """Map A with the leg as computed, map B with a leg 3 times as compliant, B compared with A."""
    d = tmp_path_factory.mktemp("maps")
    stiff, soft = _leg(d / "stiff" / "result.json", 1.0), _leg(d / "soft" / "result.json", 3.0)
    runner = CliRunner()
    r = runner.invoke(app, ["map", PUU, *GRID, "--leg", str(stiff), "--out", str(d / "a")])
    assert r.exit_code == 0, r.output
    before = _digests(d / "a")
    r = runner.invoke(app, ["map", PUU, *GRID, "--leg", str(soft), "--out", str(d / "b"), "--compare", str(d / "a")])
    assert r.exit_code == 0, r.output
    return d, before, r.output


def test_the_ratio_map_is_the_ratio_of_the_two_saved_maps(two_maps):
    d, before, output = two_maps
    a, b, ratio = (np.load(d / n) for n in ("a/map.npz", "b/map.npz", "b/ratio.npz"))
    assert np.array_equal(ratio["points"], a["points"]) and np.array_equal(ratio["points"], b["points"])
    for name in ("k_tran", "k_rot"):
        expected = b[name] / a[name]
        got = ratio[f"{name}_ratio"]
        assert np.array_equal(np.isnan(got), np.isnan(expected))
        assert np.allclose(got[~np.isnan(got)], expected[~np.isnan(expected)], rtol=1e-14, atol=0)
        # the softer leg makes the machine more compliant everywhere, and not uniformly (other springs)
        ok = ~np.isnan(got)
        assert np.all(got[ok] > 1.0) and np.ptp(got[ok]) > 1e-3, name
    assert "k_tran x" in output
    for png in ("k_tran_ratio.png", "k_rot_ratio.png"):
        assert (d / "b" / png).stat().st_size > 10_000
    assert _digests(d / "a") == before  # the other folder is only read


def test_titles_name_the_model_and_the_links(two_maps, tmp_path):
    d, _, _ = two_maps
    a, ratio = np.load(d / "a/map.npz"), np.load(d / "b/ratio.npz")
    assert str(a["label"]) == "puu.yaml (orthoglide-3PUU); foot: beam, leg: FEA stiff/result.json"
    assert "leg: FEA soft/result.json" in str(ratio["this"]) and "leg: FEA stiff/result.json" in str(ratio["other"])
    m = vjm.load_model("puu", leg=d / "soft" / "result.json")
    title = m.map(grid=3, slice="z=0").plot("k_rot").get_title()
    assert title.splitlines() == ["puu.yaml (orthoglide-3PUU); foot: beam, leg: FEA soft/result.json",
                                  "k_rot, z = 0 mm"]


def test_a_grid_that_differs_is_refused_before_writing(two_maps, tmp_path):
    d, before, _ = two_maps
    for grid in (["--grid", "6", "--slice", "z=0"], ["--grid", "7", "--slice", "z=10"]):
        r = CliRunner().invoke(app, ["map", PUU, *grid, "--out", str(tmp_path / "c"), "--compare", str(d / "a")])
        assert r.exit_code == 2
        lines = r.stderr.strip().splitlines() if hasattr(r, "stderr") else r.output.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("error: --compare") and "grid" in lines[0], lines
        assert not (tmp_path / "c").exists() or not any((tmp_path / "c").iterdir())
    assert _digests(d / "a") == before


def test_comparing_with_the_out_folder_is_refused(two_maps):
    d, before, _ = two_maps
    r = CliRunner().invoke(app, ["map", PUU, *GRID, "--out", str(d / "a"), "--compare", str(d / "a"), "--force"])
    assert r.exit_code == 2 and "is the --out folder" in r.output
    assert _digests(d / "a") == before


def test_a_map_without_compare_drops_the_old_ratio(two_maps, tmp_path):
    d, _, _ = two_maps
    out = tmp_path / "b"
    runner = CliRunner()
    assert runner.invoke(app, ["map", PUU, *GRID, "--out", str(out), "--compare", str(d / "a")]).exit_code == 0
    assert (out / "ratio.npz").exists()
    assert runner.invoke(app, ["map", PUU, *GRID, "--out", str(out)]).exit_code == 0
    assert sorted(p.name for p in out.iterdir() if not p.name.startswith(".")) == ["k_rot.png", "k_tran.png",
                                                                                   "map.npz"]


def test_compare_refused_for_a_robot(two_maps, tmp_path):
    d, _, _ = two_maps
    r = CliRunner().invoke(app, ["map", "data/robots/ur10/ur10.yaml", "--grid", "3", "--joints",
                                 "shoulder_lift_joint=-2:0:3,elbow_joint=0:2:3", "--out", str(tmp_path / "r"),
                                 "--compare", str(d / "a")])
    assert r.exit_code == 2 and "--compare is for maps of parallel machines" in r.output


def test_a_robot_map_title_names_the_robot_file_and_the_tool():
    m = vjm.load_model("data/robots/ur10/ur10.yaml")
    jm = m.joint_map(m.home, ["shoulder_lift_joint", "elbow_joint"], [(-2.0, 0.0), (0.0, 2.0)], n=3)
    assert jm.plot("k_tran").get_title().splitlines()[0] == f"ur10.yaml; tool {jm.tool}"
