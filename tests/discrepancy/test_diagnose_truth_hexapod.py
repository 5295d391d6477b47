"""`vjm diagnose` on a 6-dof machine at tilted orientations, with data from the independent truth.

The true machine (tests/truth_platforms.py) is the 6-UPS hexapod description file
(data/machines/hexapod_6ups.yaml) solved by vjm, carrying a platform weight whose centre of mass
sits 200 mm above the end-effector point along the platform's z axis: written out there with
its own rotation (Rodrigues) and statics, not the library's gravity effect.  A level platform
feels no moment from it; tilted by up to 0.1 rad it does.  The measurement file carries the
orientation columns ox,oy,oz; the diagnosis must name ``gravity`` with the weight and its lever
arm (first moment / weight), and suggest next measurements that keep orientations.
"""
import csv

import numpy as np
import pytest
import truth_platforms as tp

import vjm

LOAD = tp.PlatformWeight(3000.0, (0.0, 0.0, 200.0))  # N; mm, platform axes
SIGMA_T, SIGMA_R = 1e-3, 2e-6  # laser tracker, electronic levels
TILT = 0.1


@pytest.fixture(scope="module")
def rows():
    return tp.tilted_design(12, 8, seed=3, tilt=TILT)


def test_the_lever_shows_only_at_tilt(rows):
    """The truth's claim: level, the offset weight deflects the machine as a weight at the point does;
    tilted, the difference is far above the noise."""
    P, W = rows
    level = np.hstack([P[:, :3], np.zeros((len(P), 3))])
    at_point = tp.PlatformWeight(LOAD.weight)
    d_level = tp.hexapod_deflections(level, W, LOAD) - tp.hexapod_deflections(level, W, at_point)
    assert np.abs(d_level).max() < 1e-12
    d_tilt = tp.hexapod_deflections(P, W, LOAD) - tp.hexapod_deflections(P, W, at_point)
    chi2 = np.sum((d_tilt[:, :3] / SIGMA_T) ** 2) + np.sum((d_tilt[:, 3:] / SIGMA_R) ** 2)
    assert chi2 > 100.0


@pytest.fixture(scope="module")
def diagnosis(rows, tmp_path_factory):
    P, W = rows
    T = tp.noisy(tp.hexapod_deflections(P, W, LOAD), 6, SIGMA_T, SIGMA_R)
    folder = tmp_path_factory.mktemp("hexapod")
    path = tp.write(folder / "hexapod.csv", P, W, T, SIGMA_T, SIGMA_R)
    dg = vjm.diagnose(tp.HEXAPOD, path, suggest=4)
    dg.save(folder / "rep")
    return dg, folder / "rep"


def test_tilted_hexapod_names_the_weight_and_its_lever_arm(diagnosis):
    dg, _ = diagnosis
    assert dg.verdict == "explained"
    assert dg.named == ["gravity"]
    g = dg.report["final_params"]["gravity"]
    lo, hi = g["weight"]["ci95"]
    assert lo <= LOAD.weight <= hi
    lo, hi = g["first_moment_z"]["ci95"]
    assert lo <= LOAD.weight * LOAD.lever[2] <= hi
    assert g["first_moment_z"]["value"] / g["weight"]["value"] == pytest.approx(LOAD.lever[2], rel=0.1)
    for a in "xy":  # no lever across the platform
        lo, hi = g[f"first_moment_{a}"]["ci95"]
        assert lo <= 0.0 <= hi
    # the report's postures carry their orientation
    worst = dg.report["localization"]["worst_postures"][0]
    assert {"ox", "oy", "oz"} <= set(worst)


def test_next_measurements_keep_orientations(diagnosis, rows):
    _, folder = diagnosis
    with open(folder / "next_measurements.csv", newline="", encoding="utf-8") as fh:
        recs = [r for r in csv.reader(fh) if r and not r[0].startswith("#")]
    assert recs[0][:6] == ["x", "y", "z", "ox", "oy", "oz"]
    A = np.array(recs[1:], float)
    assert len(A) == 4
    P, _ = rows
    assert np.all(np.abs(A[:, 3:6]) <= np.abs(P[:, 3:]).max(axis=0) + 1e-12)  # within the data's tilt
    assert vjm.load_model(tp.HEXAPOD).reachable(A[:, :6]).all()


def test_updated_model_carries_the_first_moment(diagnosis):
    dg, folder = diagnosis
    m = vjm.load_model(folder / "model_updated.yaml")
    g = m.effects["gravity"]
    assert g["first_moment_z"] == pytest.approx(dg.report["final_params"]["gravity"]["first_moment_z"]["value"])


def test_level_data_cannot_see_the_lever(rows, tmp_path):
    """The same machine measured level: the weight is named, its lever along the platform's z axis is
    not fitted (the data cannot see it), as the truth says."""
    P, W = rows
    level = np.hstack([P[:, :3], np.zeros((len(P), 3))])
    T = tp.noisy(tp.hexapod_deflections(level, W, LOAD), 8, SIGMA_T, SIGMA_R)
    dg = vjm.diagnose(tp.HEXAPOD, tp.write(tmp_path / "level.csv", level, W, T, SIGMA_T, SIGMA_R))
    assert dg.named == ["gravity"]
    g = dg.report["final_params"]["gravity"]
    assert abs(g["weight"]["value"] - LOAD.weight) < 3.0 * g["weight"]["se"]  # 99.7 %: one data set
    assert "first_moment_z" not in g
