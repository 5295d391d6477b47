"""Singular postures, linkfea JSON springs, bad input, and the extension points (a)(b)(d)(e)(f)."""
import json

import numpy as np
import pytest
import yaml

import vjm
from vjm import VjmError
from vjm.model.links import LinkSpring as Link
from vjm.model.machine import Actuator, Joints

PUU = "data/orthoglide/puu.yaml"
PRPAR = "data/orthoglide/prpar.yaml"


@pytest.fixture(scope="module")
def puu():
    return vjm.load_model(PUU)


def _write(tmp_path, d, name="m.yaml"):
    p = tmp_path / name
    p.write_text(yaml.safe_dump(d))
    return p


def _base():
    with open(PUU) as fh:
        return yaml.safe_load(fh)


def test_singular_postures_finite_with_rank(puu):
    """Issue 4 test 5.  At (0, 0, -L) every leg is parallel to z: the x leg is collinear with
    its first U joint's axis (J_q loses a rank: serial singularity) and the
    platform can translate in x and y with no resistance (K singular: parallel singularity).
    The solver must return finite K, the ranks, C as a pseudo-inverse with invertible False,
    and k = inf, without exception or NaN; 1e-6 mm and 1e-3 mm away the chains have full rank
    and K stays finite."""
    L = puu.geometry["L"]
    P = np.array([[0.0, 0.0, -L], [0.0, 0.0, -L + 1e-6], [0.0, 1e-3, -L + 1e-3], [0.0, 0.0, 0.0]])
    res = puu.stiffness_map(P)
    assert np.all(np.isfinite(res.K)) and np.all(np.isfinite(res.C))
    assert not np.any(np.isnan(res.k_tran)) and not np.any(np.isnan(res.k_rot))
    assert res.chain_rank[0].tolist() == [3, 4, 4]
    assert res.rank[0] < 6 and not res.invertible[0] and np.isinf(res.k_tran[0])
    assert np.all(res.chain_rank[1:] == 4)
    assert res.rank[3] == 6 and res.invertible[3]


def test_linkfea_json_same_as_inline(tmp_path, puu):
    """Issue 4 test 7: a leg read from a `linkfea compute` JSON gives the same K as the same
    matrix inline (bit-identical input, so 1e-14 relative)."""
    C = puu.leg.compliance
    res = {"schema": "linkfea.result/1", "compliance": C.tolist(), "frame": {"origin": [0, 0, 0], "x_axis": [1, 0, 0], "y_axis": [0, 1, 0],
                                               "z_axis": [0, 0, 1]}, "units": {"compliance": "mm/N, rad/(N mm)"}}
    (tmp_path / "leg.json").write_text(json.dumps(res))
    d = _base()
    d["leg"] = {"linkfea": "leg.json"}
    m1 = vjm.load_model(_write(tmp_path, d))
    d["leg"] = {"compliance": C.tolist()}
    m2 = vjm.load_model(_write(tmp_path, d, "m2.yaml"))
    p = [20.0, -40.0, 60.0]
    K1, K2 = m1.stiffness(p).K, m2.stiffness(p).K
    assert np.max(np.abs(K1 - K2)) <= 1e-14 * np.max(np.abs(K1))
    m3 = vjm.load_model(PUU, leg=tmp_path / "leg.json")
    assert np.max(np.abs(m3.stiffness(p).K - K1)) <= 1e-14 * np.max(np.abs(K1))


@pytest.mark.parametrize("change,words", [
    (lambda d: d.update(architecture="hexapod"), "architecture"),
    (lambda d: d.update(leg={"compliance": np.eye(5).tolist()}), "leg"),
    (lambda d: d.update(leg={"compliance": (np.eye(6) + np.triu(np.ones((6, 6)), 1)).tolist()}), "symmetric"),
    (lambda d: d.update(foot={"compliance": (-np.eye(6)).tolist()}), "positive definite"),
    (lambda d: d.update(foot={"linkfea": "missing.json"}), "not found"),
    (lambda d: d.update(foot={"rigid": True}, leg={"rigid": True}), "rigid"),
    (lambda d: d.update(geometry={"L": -3, "r": 50}), "geometry.L"),
    (lambda d: d.update(actuator={"stiffness": "stiff"}), "actuator.stiffness"),
    (lambda d: d.update(leg={"beam": {"section": "hexagon", "length": 3, "material": "steel"}}), "leg.beam.section"),
])
def test_bad_model_files(tmp_path, change, words):
    d = _base()
    change(d)
    with pytest.raises(VjmError, match=words):
        vjm.load_model(_write(tmp_path, d))


def test_missing_model_file_and_unreachable_pose(puu, tmp_path):
    with pytest.raises(VjmError, match="not found"):
        vjm.load_model(tmp_path / "nope.yaml")
    with pytest.raises(VjmError, match="unreachable"):
        puu.stiffness([0.0, 400.0, 0.0])
    with pytest.raises(VjmError, match="unreachable"):
        puu.inverse_kinematics([[0.0, 0.0, 0.0], [0.0, 0.0, 500.0]])


def test_cli_error_is_one_line_exit_2(tmp_path):
    from typer.testing import CliRunner

    from vjm.cli import app
    r = CliRunner().invoke(app, ["stiffness", PUU, "--at", "0,0,900"])
    assert r.exit_code == 2
    lines = r.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:") and "Traceback" not in r.output
    r2 = CliRunner().invoke(app, ["stiffness", PUU, "--at", "0,0,0", "--json"])
    assert r2.exit_code == 0 and json.loads(r2.output)["rank"] == 6


def test_actuator_slope_is_series_spring(puu):
    """Extension (a).  At Q0 only the x actuator carries an x force (legs y and z are free in
    x), so the x compliance grows by exactly the added actuator compliance slope*(q - q_ref)."""
    p = np.array([10.0, 0.0, 0.0])
    q = puu.inverse_kinematics(p)[0, 0]
    m2 = puu.replace(actuator=Actuator(puu.actuator.stiffness, compliance_slope=2e-7, q_ref=-50.0))
    dC = m2.stiffness(p).C[0, 0] - puu.stiffness(p).C[0, 0]
    assert np.isclose(dC, 2e-7 * (q + 50.0), rtol=1e-9)
    with pytest.raises(VjmError, match="compliance_slope"):
        puu.replace(actuator=Actuator(1000.0, compliance_slope=-1.0)).stiffness(p)


def test_passive_joint_stiffness_adds_series_compliance(puu):
    """Extension (b).  Ideal U joints are rigid about their constrained direction; elastic ones
    add a rotational spring 1/k there, in series with the leg.  At Q0 a platform rotation about
    a world axis is carried by one leg whose two U joints both have their constrained axis along
    it, so the rotational compliance grows by exactly 2/k and the translational one not at all;
    a very stiff joint gives back the ideal model."""
    p = [0.0, 0.0, 0.0]
    C0 = puu.stiffness(p).C
    k = 1e7
    C1 = puu.replace(joints=Joints(k)).stiffness(p).C
    Cs = puu.replace(joints=Joints(1e14)).stiffness(p).C
    assert np.allclose(C1[3:, 3:] - C0[3:, 3:], 2.0 / k * np.eye(3), rtol=1e-6, atol=1e-6 * 2 / k)
    assert np.allclose(C1[:3, :3], C0[:3, :3], rtol=1e-9, atol=1e-15)
    assert np.max(np.abs(Cs - C0)) < 1e-6 * np.max(np.abs(C0))


def test_effects_round_trip_and_replace(tmp_path, puu):
    """Extensions (c)(d)(e): effects (checked against the effect library) written back; save/load round-trips;
    a rigid foot is accepted; replace() gives a validated modified model."""
    d = _base()
    d["effects"] = {"clearance": {"backlash": 0.01}, "gravity": {"weight": 12.5}}
    d["joints"] = {"passive_stiffness": 5e6}
    m = vjm.load_model(_write(tmp_path, d))
    assert m.effects == d["effects"]
    vjm.save_model(m, tmp_path / "out.yaml")
    m2 = vjm.load_model(tmp_path / "out.yaml")
    assert m2.effects == d["effects"] and m2.joints.passive_stiffness == 5e6
    p = [5.0, 6.0, 7.0]
    assert np.allclose(m2.stiffness(p).K, m.stiffness(p).K, rtol=1e-12, atol=0)
    rig = puu.replace(foot=Link.rigid())
    assert rig.stiffness(p).k_tran < puu.stiffness(p).k_tran
    with pytest.raises(VjmError, match="foot"):
        puu.replace(foot=Link(np.ones((6, 6))))


def test_joint_forces_balance_the_load(puu):
    """Extension (f).  The chains' wrenches sum to the applied wrench (equilibrium, eq. 13);
    at Q0 an x force goes entirely through the x actuator (tau = +F)."""
    p, w = [20.0, -30.0, 10.0], np.array([30.0, -20.0, 50.0, 1e3, -2e3, 5e2])
    jf = puu.joint_forces(p, w)
    assert np.allclose(jf["chain_wrench"].sum(axis=0), w, rtol=1e-8, atol=1e-8)
    t = puu.joint_forces([0.0, 0.0, 0.0], [100.0, 0, 0, 0, 0, 0])["actuator"]
    assert np.allclose(t, [100.0, 0.0, 0.0], atol=1e-8)


@pytest.mark.parametrize("make_args", [
    # a YAML parse error carries newlines: still one line
    lambda d: (d / "broken.yaml").write_text("architecture: [\n  :\n") and ["stiffness", str(d / "broken.yaml"),
                                                                           "--at", "0,0,0"],
    # an output folder that is a file
    lambda d: (d / "afile").write_text("x") and ["map", PUU, "--grid", "3", "--out", str(d / "afile")],
    # no reachable grid point
    lambda d: ["map", PUU, "--grid", "3", "--slice", "z=900", "--out", str(d / "m")],
    # arguments swapped
    lambda d: ["table1", PRPAR, PUU],
    # NaN noise, NaN or zero loads
    lambda d: ["simulate", PUU, "--noise-t", "nan", "--out", str(d / "s.csv")],
    lambda d: ["simulate", PUU, "--loads", "axes:nan", "--out", str(d / "s.csv")],
    lambda d: ["simulate", PUU, "--loads", "axes:0", "--out", str(d / "s.csv")],
])
def test_cli_bad_input_one_line_and_nothing_written(tmp_path, make_args):
    """Each bad input: exit 2, one 'error:' line, no traceback, no new output file."""
    from typer.testing import CliRunner

    from vjm.cli import app
    args = make_args(tmp_path)
    before = set(tmp_path.rglob("*"))
    r = CliRunner().invoke(app, args)
    assert r.exit_code == 2, r.output
    lines = r.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:") and "Traceback" not in r.output, r.output
    assert set(tmp_path.rglob("*")) == before


def test_yaml_key_given_twice_is_refused_and_merge_overrides_are_not(tmp_path):
    """A key twice in one mapping (block or flow style, nested or not; 1 and 1.0 are one key) names both
    lines; a key that overrides one brought in by a ``<<`` merge is YAML's own rule and stays."""
    from vjm.modelio.yamldata import read_yaml

    for text, line, key, first in [("a: 1\nb: 2\na: 3\n", 3, "'a'", "first on line 1"),
                                   ("g:\n  L: 1\n  r: 2\n  L: 3\n", 4, "'L'", "first on line 2"),
                                   ("x: {a: 1, a: 2}\n", 1, "'a'", "both on this line"),
                                   ("1: a\n1.0: b\n", 2, "1.0", "first on line 1")]:
        p = tmp_path / "d.yaml"
        p.write_text(text)
        with pytest.raises(VjmError, match=rf"d.yaml, line {line}: the key {key} is given twice \({first}\)"):
            read_yaml(p)
    p.write_text("base: &b {x: 1, y: 2}\nd: &d\n  <<: *b\n  x: 5\no:\n  <<: *d\n  y: 7\nl: [{a: 1}, {a: 2}]\n")
    assert read_yaml(p) == {"base": {"x": 1, "y": 2}, "d": {"x": 5, "y": 2}, "o": {"x": 5, "y": 7},
                            "l": [{"a": 1}, {"a": 2}]}
    # the model file of the issue: a second geometry would have made k_tran 0.1125 instead of 0.006 mm/N
    text = open(PUU, encoding="utf-8").read().replace("actuator:", "geometry: {L: 200.0, r: 40.0}\nactuator:", 1)
    p.write_text(text)
    with pytest.raises(VjmError, match="the key 'geometry' is given twice"):
        vjm.load_model(p)


@pytest.mark.parametrize("expr, value", [("1000*200", 2e5), ("0*(-1)", 0.0), ("(-8)**2", 64.0),
                                         ("2**0.5", 2 ** 0.5), ("(-2)**-1", -0.5), ("7/0.5", 14.0)])
def test_expression_evaluates_only_the_operation_asked(expr, value):
    """A product is not also raised to a power on the side (1000.0 ** 200.0 overflows, 0.0 ** -1.0 divides
    by zero): each binary operation computes only itself."""
    from vjm.modelio.description import evaluate

    assert evaluate(expr, {}, "w") == value


@pytest.mark.parametrize("expr, words", [("(-8)**(1/3)", "has no real value ((-8) ** 0.333333: a negative"),
                                         ("0**-1", "has no value (0 ** -1 divides by zero)")])
def test_expression_without_a_real_value_is_refused(expr, words):
    from vjm.modelio.description import evaluate

    with pytest.raises(VjmError) as e:
        evaluate(expr, {}, "chain x, element 1")
    assert str(e.value).startswith(f"chain x, element 1: {expr!r} ") and words in str(e.value)


def test_map_orientation_on_a_3_dof_platform_is_refused(puu):
    """As vjm stiffness and vjm simulate --tilt: the 3-PUU's platform only translates, so a map at an
    orientation is refused (by its Python name here), not silently made at zero rotation."""
    from vjm.errors import ArgumentError

    with pytest.raises(ArgumentError, match=r"^orientation 0,0,0.1 rad: the machine's platform only translates"):
        puu.map(2, "z=0", orientation=[0.0, 0.0, 0.1])
    assert puu.map(2, "z=0", orientation=[0.0, 0.0, 0.0]).k_tran.shape == puu.map(2, "z=0").k_tran.shape
