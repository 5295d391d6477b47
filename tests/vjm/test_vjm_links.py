"""linkfea and vjm meet in memory: one Compliance value across packages, named links, the frame kept.

The notebook path: compute the foot and the leg with linkfea, put them into a machine without
writing a file, and get the same Cartesian stiffness as through the result JSON files (the
command-line path), to round-off.
"""

import numpy as np
import pytest

import linkfea
import vjm
from linkfea.mechanics.compliance import Compliance
from vjm import LinkSpring, VjmError

H = 12.0  # mm: coarse P2 meshes (a few thousand DOF each); the comparison is between two routes
POSES = np.array([[0.0, 0.0, 0.0], [40.0, -20.0, 10.0], [-50.0, 60.0, 90.0]])


@pytest.fixture(scope="module")
def links(tmp_path_factory):
    cache = tmp_path_factory.mktemp("meshes")
    foot = linkfea.compute("orthoglide_foot", linkfea.ComputeOptions(mesh_size=H), cache_dir=cache)
    leg = linkfea.compute("parallelogram_bar", linkfea.ComputeOptions(mesh_size=H), params={"height": 16, "boss_height": 20}, cache_dir=cache)
    return foot, leg


def test_in_memory_links_give_the_file_route_stiffness(links, tmp_path):
    """load_model(foot=LinkResult) == load_model(foot=path of the saved JSON), K to round-off,
    and the link keeps linkfea's frame on both routes."""
    foot, leg = links
    mem = vjm.load_model("puu", foot=foot, leg=leg)
    pf, pl = foot.save(tmp_path / "foot.json", vtu=False), leg.save(tmp_path / "leg.json", vtu=False)
    disk = vjm.load_model("puu", foot=pf, leg=pl)
    Km, Kd = mem.stiffness_map(POSES).K, disk.stiffness_map(POSES).K
    assert np.allclose(Km, Kd, rtol=1e-12, atol=0)
    # the frame is the link result's, not dropped on the way in
    for m in (mem, disk):
        assert m.foot.frame is not None
        assert np.allclose(m.foot.frame.origin, foot.frame.origin) and np.allclose(m.foot.frame.axes, foot.frame.axes)
    assert mem.foot.value is foot.value  # the very Compliance linkfea returned
    # the same through Model.replace with a Compliance, and through with_links (file written, read back)
    rep = vjm.load_model("puu").replace(foot=foot.value, leg=leg)
    assert np.allclose(rep.stiffness_map(POSES).K, Kd, rtol=1e-12, atol=0)
    wl = vjm.with_links("puu", tmp_path / "puu_links.yaml", foot=foot, leg=leg)
    assert np.allclose(wl.stiffness_map(POSES).K, Kd, rtol=1e-12, atol=0)
    assert wl.foot.frame is not None and np.allclose(wl.foot.frame.origin, foot.frame.origin)


def test_in_memory_link_differs_from_the_bundled_beam(links):
    """Replacing a link changes the machine (the test above could not pass with links ignored)."""
    foot, leg = links
    base = vjm.load_model("puu")
    new = base.replace(foot=foot, leg=leg)
    assert not np.allclose(new.stiffness(POSES[1]).K, base.stiffness(POSES[1]).K, rtol=1e-3)


def test_links_mapping_is_what_foot_and_leg_read():
    m = vjm.load_model("puu")
    assert list(m.links) == ["foot", "leg"]
    assert m.foot is m.links["foot"] and m.link("leg") is m.links["leg"]
    C = np.diag([1e-4, 2e-3, 2e-3, 1e-6, 3e-6, 3e-6])
    a = m.replace(links={"foot": C})
    b = m.replace(foot=Compliance(C))
    assert np.array_equal(a.foot.compliance, C) and np.array_equal(b.foot.compliance, C)
    assert a.leg is m.leg  # the other link untouched
    with pytest.raises(VjmError, match="foot and leg only"):
        m.replace(links={"arm": C})
    with pytest.raises(VjmError, match="expected a linkfea LinkResult"):
        m.replace(foot=3.5)


def test_links_key_in_a_model_file_loads_like_the_top_level(tmp_path):
    """``links: {foot: ..., leg: ...}`` and the older top-level ``foot``/``leg`` give one model."""
    import yaml

    from vjm.resources import data_file

    d = yaml.safe_load(data_file("puu").read_text())
    (tmp_path / "old.yaml").write_text(yaml.safe_dump(d))
    d["links"] = {"foot": d.pop("foot"), "leg": d.pop("leg")}
    (tmp_path / "new.yaml").write_text(yaml.safe_dump(d))
    old, new = vjm.load_model(tmp_path / "old.yaml"), vjm.load_model(tmp_path / "new.yaml")
    assert np.array_equal(old.stiffness_map(POSES).K, new.stiffness_map(POSES).K)
    d["foot"] = {"rigid": True}
    (tmp_path / "both.yaml").write_text(yaml.safe_dump(d))
    with pytest.raises(VjmError, match="foot: given twice"):
        vjm.load_model(tmp_path / "both.yaml")


def test_inline_compliance_keeps_its_frame_through_a_file(links, tmp_path):
    foot, _ = links
    m = vjm.load_model("puu").replace(foot=LinkSpring(foot.value, None))
    vjm.save_model(m, tmp_path / "m.yaml")
    assert "frame:" in (tmp_path / "m.yaml").read_text()
    back = vjm.load_model(tmp_path / "m.yaml")
    assert np.array_equal(back.foot.compliance, foot.compliance)
    assert np.allclose(back.foot.frame.axes, foot.frame.axes, rtol=0, atol=1e-15)


def test_the_link_spring_has_one_name():
    """``vjm.Link`` (the CAD input's name, linkfea.cad.Link) is gone: the spring is vjm.LinkSpring."""
    from vjm.model import machine

    for mod in (vjm, machine):
        with pytest.raises(AttributeError):
            mod.Link  # noqa: B018
    assert "LinkSpring" in vjm.__all__ and vjm.LinkSpring is LinkSpring


def test_a_model_takes_keywords_only_and_shares_locked_kinematics():
    """No positional ``Model(...)``; a copy with other springs shares the kinematics cache, which
    threads may fill at once, and gives the same stiffness as a fresh model."""
    from concurrent.futures import ThreadPoolExecutor

    from vjm.model.machine import ParallelModel as Model

    m = vjm.load_model("puu")
    with pytest.raises(TypeError):
        Model(m.architecture, m.geometry, m.actuator)  # type: ignore[misc]
    soft = m.replace(actuator=type(m.actuator)(m.actuator.stiffness / 2))
    assert soft._kin_cache is m._kin_cache
    P = np.random.default_rng(1).uniform(-40.0, 40.0, (12, 3, 3))
    with ThreadPoolExecutor(4) as ex:
        got = list(ex.map(lambda p: soft.stiffness_map(p).C, P))
    fresh = Model(architecture=m.architecture, geometry=m.geometry, actuator=soft.actuator, links=m.links,
                  joints=m.joints)
    assert fresh._kin_cache is not m._kin_cache
    for p, C in zip(P, got):
        assert np.array_equal(C, fresh.stiffness_map(p).C)


def test_one_reader_for_result_files(links, tmp_path):
    """linkfea.load and vjm's link reader both go through linkfea.result.schema.read_result: a result whose
    compliance is not positive definite is refused by both, with linkfea's message."""
    import json

    foot, _ = links
    p = foot.save(tmp_path / "foot.json", vtu=False)
    doc = json.loads(p.read_text())
    doc["compliance"][0][0] = -1.0
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(doc))
    with pytest.raises(linkfea.LinkFeaError, match="not positive definite"):
        linkfea.load(bad)
    with pytest.raises(VjmError, match="not positive definite"):
        vjm.load_model("puu", foot=bad)
