"""The notebook views of vjm's results: HTML tables, pictures on a given Axes, JSON and YAML files."""
import json
import os
import subprocess
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pytest

import vjm
from vjm.errors import VjmError

POSE = [10.0, -20.0, 15.0]


@pytest.fixture(scope="module")
def model():
    return vjm.load_model("puu")


@pytest.fixture(scope="module")
def result(model):
    return model.stiffness(POSE)


def test_stiffness_html_shows_k_c_and_the_k_values(result):
    h = result._repr_html_()
    for v in np.ravel(result.K):
        assert f"{v:.4e}" in h
    for v in np.ravel(result.C):
        assert f"{v:.4e}" in h
    assert f"k_tran = {float(result.k_tran):.4e} mm/N" in h
    assert f"k_rot = {float(result.k_rot):.4e} rad/(N mm)" in h
    assert f"rank {int(result.rank)}" in h
    assert "N/mm" in h and "mm/N" in h and "world axes" in h


def test_stiffness_html_of_several_poses_lists_each(model):
    P = np.array([[0.0, 0.0, 0.0], POSE, [-30.0, 5.0, 0.0]])
    r = model.stiffness_map(P)
    h = r._repr_html_()
    assert "3 poses" in h
    for i in range(3):
        assert f"{r.k_tran[i]:.4e}" in h and f"{r.k_rot[i]:.4e}" in h


def test_stiffness_plot_principal_bars_are_the_eigenvalues(result):
    fig, ax = plt.subplots()
    try:
        assert result.plot(ax=ax) is ax
        heights = sorted(p.get_height() for p in ax.patches)
        # independent: the eigenvalues of the inverse of K, against the model's own k_tran (largest)
        ev = np.linalg.eigvalsh(np.linalg.inv(result.K)[:3, :3])
        assert np.allclose(heights, np.sort(ev), rtol=1e-8)
        assert np.isclose(max(heights), float(result.k_tran), rtol=1e-8)
        rot = [p.get_height() for a in fig.axes if a is not ax for p in a.patches]
        assert np.isclose(max(rot), float(result.k_rot), rtol=1e-8)
    finally:
        plt.close(fig)


def test_stiffness_plot_matrix_draws_an_image(model, result):
    fig, ax = plt.subplots()
    try:
        assert result.plot(ax=ax, kind="matrix") is ax
        assert len(ax.images) == 1
        assert np.allclose(ax.images[0].get_array(), np.log10(np.abs(result.C)))
        r = model.stiffness_map(np.array([[0.0, 0.0, 0.0], POSE]))
        fig2, ax2 = plt.subplots()
        assert r.plot(ax=ax2, pose=1) is ax2 and len(ax2.patches) == 3
        plt.close(fig2)
        with pytest.raises(ValueError, match="kind"):
            result.plot(ax=ax, kind="pie")
    finally:
        plt.close(fig)


def test_stiffness_save_round_trips_with_frame_and_units(result, tmp_path):
    p = result.save(tmp_path / "K.json")
    d = json.loads(p.read_text())
    assert d["schema"] == "vjm.stiffness/1"
    assert np.allclose(np.array(d["K"]), result.K, rtol=1e-15, atol=0)
    assert np.allclose(np.array(d["C"]), result.C, rtol=1e-15, atol=0)
    assert np.allclose(d["point_mm"], POSE)
    assert "end-effector" in d["frame"] and "world" in d["frame"]
    assert d["units"]["K"].startswith("N/mm") and "mm/N" in d["units"]["C"]
    assert d["order"].startswith("dx dy dz rx ry rz")
    result.save(p)  # its own file: replaced
    assert [f.name for f in tmp_path.iterdir()] == ["K.json"]


def test_stiffness_save_refuses_a_file_it_did_not_write(result, tmp_path):
    p = tmp_path / "notes.json"
    p.write_text('{"mine": 1}\n')
    with pytest.raises(VjmError, match="not overwritten"):
        result.save(p)
    assert p.read_text() == '{"mine": 1}\n'


@pytest.fixture(scope="module")
def smap(model):
    return model.map(grid=5, slice="z=0")


def test_map_html_names_grid_extremes_and_where(smap):
    h = smap._repr_html_()
    assert "5 x 5 x 1" in h and "z = 0 mm" in h
    assert f"{int(smap.reachable.sum())} of 25" in h
    for name in ("k_tran", "k_rot"):
        v = getattr(smap, name)
        for i in (np.nanargmin(v), np.nanargmax(v)):
            assert f"{v[i]:.4e} at {np.round(smap.points[i], 4).tolist()} mm" in h


def test_map_plot_on_given_axes_has_image_and_colourbar(smap):
    fig, ax = plt.subplots()
    try:
        assert smap.plot(ax=ax) is ax
        assert len(ax.images) == 1
        img = np.ma.filled(ax.images[0].get_array(), np.nan)
        assert np.allclose(np.nanmax(img), np.nanmax(smap.k_tran))
        assert len(fig.axes) == 2  # the colourbar
    finally:
        plt.close(fig)


def test_model_html_shows_its_parts(model):
    h = model._repr_html_()
    assert model.architecture in h
    for k, v in model.geometry.items():
        assert f"{k} = {v}" in h
    for name in model.links:
        assert f"link {name}" in h
    assert f"stiffness {model.actuator.stiffness:g} N/mm" in h
    assert "joints" in h and "effects</th><td style='text-align:left'>none" in h
    h = model.replace(effects={"gravity": {"weight": 12.0}})._repr_html_()
    assert "gravity (weight = 12.0)" in h


def test_model_save_reads_back_to_the_same_stiffness(model, tmp_path):
    p = tmp_path / "m.yaml"
    model.save(p)
    back = vjm.load_model(p)
    assert back.geometry == model.geometry
    assert np.allclose(back.stiffness(POSE).K, model.stiffness(POSE).K, rtol=1e-12, atol=0)


def test_pictures_use_agg_when_no_backend_is_set():
    env = {k: v for k, v in os.environ.items() if k != "MPLBACKEND"}
    code = ("import vjm, matplotlib; vjm.load_model('puu').stiffness([0.0, 0.0, 0.0]).plot(); "
            "print(matplotlib.get_backend().lower())")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().endswith("agg")


def test_model_html_states_each_links_frame(model):
    from linkfea.mechanics.compliance import Compliance
    from linkfea.mechanics.frames import Frame

    R = np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    foot = Compliance(model.foot.compliance, Frame(np.array([1.5, 2.0, -3.0]), R))
    h = model.replace(foot=foot)._repr_html_()
    assert "CAD frame origin [1.5, 2.0, -3.0] mm, x axis [0.0, 1.0, 0.0]" in h
    assert h.count("no CAD frame stated") == 1  # the leg's
    for v in np.diag(model.leg.compliance):
        assert f"{v:.3e}" in h
