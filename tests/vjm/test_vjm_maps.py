"""Stiffness-map pictures: log colour scale beyond a decade, labelled contours, the seed's named points."""
import csv

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pytest
from matplotlib.colors import LogNorm

import vjm
from vjm.maps.compute import compute_map, contour_levels, workspace_grid
from vjm.resources import seed_table


@pytest.fixture(scope="module")
def puu_map():
    m = vjm.load_model("data/orthoglide/puu.yaml")
    axes, G, fixed = workspace_grid(m, 9, "z=0")
    return compute_map(m, G.reshape(-1, 3), axes, fixed)


def _seed_points(arch):
    with open(seed_table(), encoding="utf-8") as fh:
        rows = csv.DictReader(line for line in fh if not line.startswith("#"))
        return {r["point"]: (float(r["x"]), float(r["y"]), float(r["z"])) for r in rows if r["architecture"] == arch}


def test_log_scale_only_beyond_a_decade(puu_map):
    """The 3-PUU's k_tran spans ~30x on z = 0 (log scale), its k_rot about 2x (linear)."""
    spans = {n: np.nanmax(getattr(puu_map, n)) / np.nanmin(getattr(puu_map, n)) for n in ("k_tran", "k_rot")}
    assert spans["k_tran"] > 10 > spans["k_rot"]
    for name in ("k_tran", "k_rot"):
        ax = puu_map.plot(name)
        assert isinstance(ax.images[0].norm, LogNorm) == (spans[name] > 10)
        # the colour scale covers the data exactly
        assert ax.images[0].norm.vmin == pytest.approx(np.nanmin(getattr(puu_map, name)))
        assert ax.images[0].norm.vmax == pytest.approx(np.nanmax(getattr(puu_map, name)))
        plt.close(ax.figure)


def test_contours_are_labelled_at_their_values(puu_map):
    ax = puu_map.plot("k_tran")
    lo, hi = np.nanmin(puu_map.k_tran), np.nanmax(puu_map.k_tran)
    labels = [float(t.get_text()) for t in ax.texts if t.get_text()[:1].isdigit()]
    assert len(labels) >= 3 and all(lo < v < hi for v in labels)
    # on a log scale the levels are 1, 2, 5 x 10^n
    mant = {round(v / 10 ** np.floor(np.log10(v)), 6) for v in labels}
    assert mant <= {1.0, 2.0, 5.0}
    plt.close(ax.figure)
    assert contour_levels(1.0, 1.0, True).size == 0  # a flat map has no contour


def test_isotropic_point_and_q1_q2_are_marked(puu_map):
    """Markers at the seed's Q0, Q1, Q2 (x, y), filled when in the plane z = 0, hollow when projected."""
    seed = _seed_points("orthoglide-3PUU")
    ax = puu_map.plot("k_tran")
    marks = {}
    for line in ax.lines:
        x, y = line.get_xdata(), line.get_ydata()
        if len(x) == 1:
            marks[(float(x[0]), float(y[0]))] = line.get_markerfacecolor()
    texts = " ".join(t.get_text() for t in ax.texts)
    for name, (x, y, z) in seed.items():
        assert (x, y) in marks, name
        assert name in texts
        filled = marks[(x, y)] != "none"
        assert filled == (z == 0.0)
    assert "isotropic" in texts
    plt.close(ax.figure)


def test_the_maps_landmarks_are_the_seed_tables_points():
    """The maps mark the Orthoglide's named points from its architecture (the core reads no paper
    study); they are the points of the seed's Table 1 that vjm table1 reads."""
    from vjm.architectures import ARCHITECTURES
    from vjm.studies.table1 import read_seed_table

    rows = read_seed_table()
    for name in ("orthoglide-3PUU", "orthoglide-3PRPaR"):
        seed = {r["point"] + (" isotropic" if r["point"] == "Q0" else ""): (float(r["x"]), float(r["y"]), float(r["z"]))
                for r in rows if r["architecture"] == name}
        assert ARCHITECTURES[name].landmarks == seed
    assert ARCHITECTURES["delta-3RRPaR"].landmarks == {}
