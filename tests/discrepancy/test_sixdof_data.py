"""Platform orientations in measurement files (ox,oy,oz), `vjm simulate` at tilt, and the gravity effect
of a 6-dof platform against the statics of an offset weight.

The references: the model's own stiffness at the tilted pose (``C w``, independent of the
discrepancy code), scipy's rotation of a rotation vector, and the moment of a weight at its
centre of mass about the end-effector point.
"""
import csv

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import vjm
from vjm import effects as fx
from vjm.discrepancy.data import read_csv, write_design
from vjm.discrepancy.simulate import run
from vjm.effects.context import Context, unique_postures
from vjm.errors import VjmError
from vjm.resources import data_file

HEXAPOD = str(data_file("machines/hexapod_6ups.yaml"))
PUU = str(data_file("orthoglide/puu.yaml"))
TILT = 0.08


@pytest.fixture(scope="module")
def hexapod():
    return vjm.load_model(HEXAPOD)


@pytest.fixture(scope="module")
def simulated(tmp_path_factory):
    out = tmp_path_factory.mktemp("sim") / "s.csv"
    data = run(HEXAPOD, [], "random:4", "axes:1000:100000", 0.0, 0.0, 7, out, tilt=TILT)
    return data, out


def test_simulate_writes_orientations_it_used(simulated, hexapod):
    data, out = simulated
    with open(out, newline="", encoding="utf-8") as fh:
        header = next(r for r in csv.reader(fh) if r and not r[0].startswith("#"))
    assert header[:6] == ["x", "y", "z", "ox", "oy", "oz"]
    back = read_csv(out)
    assert back.has_orientation and back.P.shape == (data.n, 6)
    np.testing.assert_array_equal(back.P, data.P)
    O = back.P[:, 3:]
    assert np.all(np.abs(O) <= TILT) and np.abs(O).max() > 0.2 * TILT
    # the deflections are the model's at the tilted poses, not at level ones
    t = np.einsum("nij,nj->ni", hexapod.stiffness_map(back.P).C, back.W)
    np.testing.assert_allclose(back.T, t, rtol=1e-9, atol=1e-15)
    level = np.einsum("nij,nj->ni", hexapod.stiffness_map(back.P[:, :3]).C, back.W)
    assert np.abs(level - t).max() > 1e-3 * np.abs(t).max()


def test_paired_rows_with_orientations_round_trip(simulated, tmp_path):
    data, _ = simulated
    rows = np.hstack([data.P[:3], data.W[:3]])
    f = tmp_path / "next.csv"
    write_design(f, rows)
    again = run(HEXAPOD, [], str(f), str(f), 0.0, None, 1, tmp_path / "again.csv")
    np.testing.assert_array_equal(again.P, data.P[:3])
    np.testing.assert_array_equal(again.W, data.W[:3])


def test_orientations_refused_for_a_translating_platform(tmp_path):
    f = tmp_path / "m.csv"
    f.write_text("x,y,z,ox,oy,oz,Fx,Fy,Fz,Mx,My,Mz,dx,dy,dz,rx,ry,rz\n0,0,0,0,0,0.05,100,0,0,0,0,0,0.03,0,0,,,\n"
                 "0,0,0,0,0,0.05,0,100,0,0,0,0,0,0.03,0,,,\n")
    with pytest.raises(VjmError, match=r"m.csv: column 'ox': .* only translates \(3 dof\)"):
        vjm.diagnose(PUU, f)


def test_gravity_on_a_tilted_platform_is_the_statics_of_an_offset_weight(hexapod):
    rng = np.random.default_rng(4)
    P = np.array([[10.0, -20.0, 560.0, 0.05, -0.07, 0.02], [0.0, 0.0, 550.0, 0.0, 0.0, 0.0],
                  [-30.0, 15.0, 600.0, -0.09, 0.01, 0.06]])
    U, idx = unique_postures(P)
    C = hexapod.stiffness_map(U).C[idx]
    ctx = Context(hexapod, U, idx, rng.standard_normal((3, 6)))
    weight, lever = 2500.0, np.array([12.0, -7.0, 180.0])  # N; mm, platform axes
    g = np.array([0.0, 0.0, -1.0])
    eff = fx.get("gravity")
    assert [p.name for p in eff.param_specs(hexapod)] == ["weight", "first_moment_x", "first_moment_y",
                                                         "first_moment_z"]
    got = eff.extra(ctx, np.r_[weight, weight * lever], C)
    R = Rotation.from_rotvec(P[:, 3:]).as_matrix()
    F = weight * g
    wrench = np.hstack([np.broadcast_to(F, (3, 3)), np.cross(R @ lever, F)])
    np.testing.assert_allclose(got, np.einsum("nij,nj->ni", C, wrench), rtol=1e-12, atol=1e-18)
    # level, a lever along the platform's z axis (along g) has no moment: only a tilt shows it
    up = eff.extra(ctx, np.r_[weight, 0.0, 0.0, weight * 180.0], C)
    at_point = eff.extra(ctx, np.r_[weight, 0.0, 0.0, 0.0], C)
    np.testing.assert_allclose(up[1], at_point[1], rtol=1e-13)
    assert np.abs(up[0] - at_point[0]).max() > 1e-3 * np.abs(at_point[0]).max()
    # a platform that only translates keeps its one-parameter weight
    assert [p.name for p in eff.param_specs(vjm.load_model(PUU))] == ["weight"]


def test_vjm_path_applies_the_first_moment_of_a_saved_gravity(hexapod):
    """model_updated.yaml's gravity entry on a 6-dof platform: vjm path puts the weight's moment
    (R m) x g on the platform point, as a process wrench of that size would."""
    from vjm.toolpath.deflect import tcp_deflection

    poses = np.array([[10.0, -20.0, 560.0, 0.05, -0.07, 0.02], [-30.0, 15.0, 600.0, -0.09, 0.01, 0.06]])
    W = np.array([[200.0, 0.0, -100.0, 0.0, 0.0, 0.0]] * 2)
    weight, lever = 2500.0, np.array([0.0, 0.0, 180.0])
    m = hexapod.replace(effects={"gravity": {"weight": weight, **{f"first_moment_{a}": weight * c
                                                               for a, c in zip("xyz", lever)}}})
    F = weight * np.array([0.0, 0.0, -1.0])
    Wg = W + np.hstack([np.broadcast_to(F, (2, 3)), np.cross(Rotation.from_rotvec(poses[:, 3:]).as_matrix() @ lever, F)])
    got = tcp_deflection(m, poses, W, np.zeros(3))
    ref = tcp_deflection(hexapod, poses, Wg, np.zeros(3))
    np.testing.assert_allclose(got, ref, rtol=1e-9, atol=1e-14)
