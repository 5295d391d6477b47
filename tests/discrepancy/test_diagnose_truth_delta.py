"""`vjm diagnose` on the Delta 3-RRPaR, with data from the independent truth generator.

The true machine (tests/truth_platforms.py) is data/orthoglide/delta.yaml solved by vjm plus a
backlash of the rotary actuators written out with the Delta's own closed-form kinematics and
virtual work (not vjm's chains, not vjm.discrepancy).  The truth's kinematics are first checked
against vjm's (same arm angles, same actuator torques: two independent derivations of one
machine), then the diagnosis must name the clearance, at the hidden size.
"""
import numpy as np
import pytest
import truth as tr
import truth_platforms as tp

import vjm

BACKLASH = 1e-5  # rad, each arm (2.5 um at the 250 mm arm's tip)
SIGMA_T, SIGMA_R = 1e-3, 1e-5


@pytest.fixture(scope="module")
def rows():
    return tp.delta_design(8, 8, seed=2)


def test_truth_kinematics_agree_with_vjm(rows):
    P, W = rows
    geo = tr.nominal(tp.DELTA)["geometry"]
    m = vjm.load_model(tp.DELTA)
    assert np.abs(tp.delta_actuators(P, geo) - m.inverse_kinematics(P)).max() < 1e-9
    _, tau = tp.delta_backlash_twist(P, W, BACKLASH, geo)
    ref = np.asarray(m.joint_forces(P, W)["actuator"])
    assert np.abs(tau - ref).max() < 1e-6 * np.abs(ref).max()
    # the slip is a rigid motion: no platform rotation, and it does positive work against the load
    t, _ = tp.delta_backlash_twist(P, W, BACKLASH, geo)
    assert np.all(t[:, 3:] == 0) and np.all(np.einsum("ni,ni->n", t[:, :3], W[:, :3]) >= 0)


@pytest.fixture(scope="module")
def diagnosis(rows, tmp_path_factory):
    P, W = rows
    T = tp.noisy(tp.delta_deflections(P, W, backlash=BACKLASH), 5, SIGMA_T, SIGMA_R)
    path = tp.write(tmp_path_factory.mktemp("delta") / "delta.csv", P, W, T, SIGMA_T, SIGMA_R)
    return vjm.diagnose(tp.DELTA, path)


def test_delta_backlash_is_named_at_its_size(diagnosis):
    assert diagnosis.verdict == "explained"
    assert diagnosis.named == ["clearance"]
    p = diagnosis.report["final_params"]["clearance"]["backlash"]
    assert p["unit"] == "rad"  # a rotary actuator slips by an angle
    lo, hi = p["ci95"]
    assert lo <= BACKLASH <= hi and hi - lo < 0.5 * BACKLASH


def test_clearance_of_turning_actuators_is_an_angle():
    from vjm import effects as fx
    from vjm.resources import data_file

    unit = {f: fx.get("clearance").param_specs(vjm.load_model(data_file(f)))[0].unit
            for f in ("orthoglide/delta.yaml", "machines/delta_rrpar.yaml", "orthoglide/puu.yaml",
                      "machines/linear_delta.yaml")}
    assert unit == {"orthoglide/delta.yaml": "rad", "machines/delta_rrpar.yaml": "rad",
                    "orthoglide/puu.yaml": "mm", "machines/linear_delta.yaml": "mm"}
