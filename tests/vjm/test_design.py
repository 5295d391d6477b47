"""vjm design: the search reaches a closed-form optimum, reports only verified designs, and is reproducible.

The truth is tests/truth_design.py (Timoshenko's cantilever written out, not linkfea's beam module);
the links here are closed-form beams, which go through the same spec, search and verification as
FEA links (tests/vjm/test_design_fea.py runs FEA links).
"""
import itertools
import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from truth_design import lightest_square, write_arm

import vjm
from linkfea.mechanics.materials import get_material
from vjm.synthesis.links import beam_sample
from vjm.synthesis.machine import load_machine
from vjm.synthesis.spec import parse_spec

PUU = Path(__file__).resolve().parents[2] / "data" / "orthoglide" / "puu.yaml"
L_ARM = 400.0
TARGET = 0.02  # mm/N


def _spec(tmp_path, doc, name="spec.yaml"):
    p = tmp_path / name
    p.write_text(yaml.safe_dump(doc))
    return p


@pytest.fixture(scope="module")
def arm(tmp_path_factory):
    d = tmp_path_factory.mktemp("arm")
    model = write_arm(d, L_ARM)
    doc = {"machine": model, "links": {"arm": {"beam": {"section": "rect", "length": L_ARM, "material": "aluminium"},
                                               "free": {"width": [5, 60], "height": [5, 60]}}},
           "constraints": {"k_tran_max": TARGET}, "joints": {"j1": [-1.0, 1.0]}, "joint_grid": 3,
           "budget": 30, "seed": 3}
    spec = _spec(d, doc)
    return spec, vjm.design(spec, d / "out")


def test_the_one_link_arm_reaches_the_closed_form_optimum(arm):
    spec, res = arm
    al = get_material("aluminium")
    s = lightest_square(L_ARM, al.E, al.nu, TARGET)
    m_true = al.density * s * s * L_ARM * 1000.0
    assert res.feasible
    assert res.moving_mass_kg == pytest.approx(m_true, rel=0.01)
    assert res.moving_mass_kg >= m_true * (1 - 1e-6)          # nothing feasible is lighter than the optimum
    assert res.k_tran_max <= TARGET
    p = res.parameters["arm"]
    assert p["width"] == pytest.approx(s, rel=0.03) and p["height"] == pytest.approx(s, rel=0.03)
    assert res.fea_runs <= 30


def test_the_reported_design_is_verified_and_nothing_evaluated_is_lighter(arm):
    spec, res = arm
    doc = json.loads((spec.parent / "out" / "design.json").read_text())
    assert doc["schema"] == "vjm.design/1" and doc["feasible"] and doc["fea_runs"] == len(doc["history"])
    s = parse_spec(yaml.safe_load(spec.read_text()), str(spec))
    machine = load_machine(s)
    link = s.links[0]
    lighter = []
    for h in doc["history"]:
        b = beam_sample(link, h["params"])   # every evaluated design, recomputed
        v = machine.values({"arm": b.compliance})
        if v["k_tran_max"] <= TARGET and b.mass < doc["moving_mass_kg"] * (1 - 1e-12):
            lighter.append(h)
    assert not lighter
    b = beam_sample(link, doc["parameters"]["arm"])
    assert b.mass == pytest.approx(doc["moving_mass_kg"], rel=1e-12)
    assert machine.values({"arm": b.compliance})["k_tran_max"] == pytest.approx(doc["k_tran_max"], rel=1e-12)
    c = doc["constraints"][0]
    assert c["slack"] == pytest.approx(TARGET - doc["k_tran_max"], rel=1e-9) and c["error_bar"] == 0.0
    for name in ("convergence.png", "report.html", "optimum_arm.json"):
        assert (spec.parent / "out" / name).is_file()


def test_the_same_spec_and_seed_give_the_same_answer(arm, tmp_path):
    spec, res = arm
    again = vjm.design(spec)
    assert again.parameters == res.parameters and again.history == res.history
    other = vjm.design(spec, seed=11)
    assert other.feasible and other.moving_mass_kg == pytest.approx(res.moving_mass_kg, rel=0.01)


def _puu_beams(tmp_path, budget=40, **extra):
    doc = {"machine": str(PUU),
           "links": {"foot": {"beam": {"section": "rect", "length": 50, "material": "aluminium"},
                              "free": {"width": [20, 100], "height": [4, 30]}},
                     "leg": {"beam": {"section": "rect", "length": 310, "material": "aluminium"},
                             "free": {"width": [8, 40], "height": [4, 20]}}},
           "constraints": {"k_tran_max": 0.015}, "grid": 5, "budget": budget, **extra}
    return _spec(tmp_path, doc)


@pytest.fixture(scope="module")
def front(tmp_path_factory):
    """Both links of the 3-PUU free (closed-form beams), three targets: the front, budget 24."""
    d = tmp_path_factory.mktemp("front")
    spec = _puu_beams(d, budget=24)
    return spec, vjm.design(spec, d / "out", targets=[0.03, 0.015, 0.01])


def test_a_parallel_machine_of_beams_beats_a_grid_of_its_closed_form(front):
    """Both links free: at each target of the front, the verified optimum (its k_tran_max recomputed from its
    parameters) is lighter than every feasible point of a 5^4 grid of the closed form."""
    spec, res = front
    assert res.feasible and res.k_tran_max <= 0.01 and res.fea_runs <= 24
    s = parse_spec(yaml.safe_load(spec.read_text()), str(spec))
    machine = load_machine(s)
    foot, leg = s.links
    axes = [np.geomspace(p.lo, p.hi, 5) for link in s.links for p in link.free]
    feet = [beam_sample(foot, {"width": a, "height": b}) for a in axes[0] for b in axes[1]]
    legs = [beam_sample(leg, {"width": a, "height": b}) for a in axes[2] for b in axes[3]]
    grid = sorted(itertools.product(feet, legs), key=lambda fg: 3 * fg[0].mass + 3 * fg[1].mass)
    k_tran = {}  # the grid's machines, lightest first, evaluated as far as a target needs

    def lightest_feasible(target):
        for i, (f, g) in enumerate(grid):
            if i not in k_tran:
                k_tran[i] = machine.values({"foot": f.compliance, "leg": g.compliance})["k_tran_max"]
            if k_tran[i] <= target:
                return 3 * f.mass + 3 * g.mass
        return np.inf

    assert len(res.front) == 3
    for r in res.front:
        f, g = beam_sample(foot, r["parameters"]["foot"]), beam_sample(leg, r["parameters"]["leg"])
        assert machine.values({"foot": f.compliance, "leg": g.compliance})["k_tran_max"] <= r["target"]
        assert 3 * f.mass + 3 * g.mass == pytest.approx(r["moving_mass_kg"], rel=1e-12)
        assert r["moving_mass_kg"] <= lightest_feasible(r["target"])


def test_an_unreachable_target_is_an_answer(tmp_path):
    spec = _puu_beams(tmp_path, budget=16)
    res = vjm.design(spec, tmp_path / "out", targets=[1e-4])
    assert not res.feasible
    assert res.message.startswith("no design within the bounds reaches k_tran_max <= 0.0001 mm/N; the stiffest found is")
    assert "(upper)" in res.message           # the stiffest design sits at upper bounds
    doc = json.loads((tmp_path / "out" / "design.json").read_text())
    assert doc["feasible"] is False and doc["front"][0]["feasible"] is False


def test_the_front_shares_its_designs_and_grows_heavier_as_the_target_tightens(front):
    spec, res = front
    masses = [r["moving_mass_kg"] for r in sorted(res.front, key=lambda r: -r["target"])]
    assert all(r["feasible"] and r["k_tran_max"] <= r["target"] for r in res.front)
    assert masses == sorted(masses) and masses[0] < masses[-1]
    assert res.fea_runs <= 24
    text = (spec.parent / "out" / "front.csv").read_text().splitlines()
    assert text[0].startswith("target,feasible,moving_mass_kg") and len(text) == 4


def test_a_robot_s_arm_tubes_under_a_sag_limit(tmp_path):
    """data/design/ur10_arms.yaml: the answer, written back into the UR10's model file as plain beams and read
    by the model reader, sags at most the limit over the joint grid; every lighter evaluated pair sags more."""
    root = Path(__file__).resolve().parents[2]
    res = vjm.design(root / "data" / "design" / "ur10_arms.yaml", budget=12)
    assert res.feasible and res.fea_runs <= 12

    src = yaml.safe_load((root / "data" / "robots" / "ur10" / "ur10.yaml").read_text())
    q = []
    for a in (-2.0, -1.3, -0.6):
        for b in (0.4, 1.3, 2.2):
            x = list(src["home"])
            x[1], x[2] = a, b
            q.append(x)

    def sag(params):
        doc = dict(src, urdf=str(root / "data" / "robots" / "ur10" / "ur10.urdf"))
        doc["links"] = {k: dict(v, beam={**v["beam"], **params[k]}) for k, v in src["links"].items()}
        p = tmp_path / "r.yaml"
        p.write_text(yaml.safe_dump(doc))
        return float(np.max(np.linalg.norm(np.asarray(vjm.load_model(p).self_weight(np.array(q)))[:, :3], axis=1)))

    assert sag(res.parameters) == pytest.approx(res.constraints[0].value, rel=1e-9)
    assert sag(res.parameters) <= 1.5
    by_link = {}
    for h in res.history:
        by_link.setdefault(h["link"], []).append(h)
    lighter = [(a, b) for a in by_link["upper_arm"] for b in by_link["forearm"]
               if a["mass_kg"] + b["mass_kg"] < res.moving_mass_kg * (1 - 1e-12)]
    assert lighter and all(sag({"upper_arm": a["params"], "forearm": b["params"]}) > 1.5 for a, b in lighter[:6])


def test_integer_and_choice_parameters_snap_to_what_a_script_takes():
    s = parse_spec({"machine": str(PUU), "constraints": {"k_tran_max": 0.02},
                    "links": {"leg": {"cad": "parallelogram_bar",
                                      "free": {"width": {"int": [8, 24]}, "material": {"choice": ["aluminium", "steel"]},
                                               "height": [8, 20]}}}}, str(PUU))
    width, material, height = s.links[0].free
    assert [width.kind, material.kind, height.kind] == ["int", "choice", "real"]
    for u in np.linspace(0, 1, 23):
        w, m, h = width.from_unit(u), material.from_unit(u), height.from_unit(u)
        assert isinstance(w, int) and 8 <= w <= 24 and m in ("aluminium", "steel") and 8 <= h <= 20
        assert width.from_unit(width.to_unit(w)) == w and material.from_unit(material.to_unit(m)) == m
        assert height.from_unit(height.to_unit(h)) == pytest.approx(h, rel=1e-12)
    # log coordinates: the geometric mean of the bounds sits in the middle
    assert height.from_unit(0.5) == pytest.approx(float(f"{np.sqrt(8 * 20):.4g}"))


def test_conservative_answers_hold_at_the_top_of_the_error_bar(tmp_path, monkeypatch):
    """Beams given a 5 % error bar on every diagonal entry (as an FEA result carries one): --conservative's
    answer meets the limit at the top of the bar, where the nominal answer does not, and every evaluated pair
    lighter than it exceeds the limit at the top of its bar."""
    import vjm.synthesis.links as links

    plain = links.beam_sample

    def with_bar(link, params):
        s = plain(link, params)
        return links.LinkSample(s.link, s.params, s.key, True, s.compliance, s.mass, np.full(6, 0.05))

    monkeypatch.setattr(links, "beam_sample", with_bar)
    spec = _puu_beams(tmp_path, budget=16)
    nominal = vjm.design(spec)
    safe = vjm.design(spec, conservative=True)
    c0, c1 = nominal.constraints[0], safe.constraints[0]
    assert c0.error_bar > 0 and c0.value <= 0.015 < c0.value + c0.error_bar
    assert safe.feasible and c1.value + c1.error_bar <= 0.015 and c1.slack >= 0
    s = parse_spec(yaml.safe_load(spec.read_text()), str(spec))
    machine = load_machine(s)
    feet = [h for h in safe.history if h["link"] == "foot"]
    legs = [h for h in safe.history if h["link"] == "leg"]
    lighter = [(f, g) for f in feet for g in legs if 3 * (f["mass_kg"] + g["mass_kg"]) < safe.moving_mass_kg * (1 - 1e-12)]
    assert lighter
    for f, g in lighter:
        comps = {"foot": plain(s.links[0], f["params"]).compliance, "leg": plain(s.links[1], g["params"]).compliance}
        assert machine.values(comps, {"foot": np.full(6, 0.05), "leg": np.full(6, 0.05)}, 1.0)["k_tran_max"] > 0.015
