"""The ``calibration:`` block of model_updated.yaml: what the deflection diagnosis fitted is written once and read
back by ``vjm path`` as the same :class:`vjm.calibration.result.Calibration`, and the path's band is the first-order
closed form ``z sqrt(g^T Sigma g)`` of that covariance."""
import numpy as np
import pytest

import vjm
from vjm.calibration.result import Calibration, from_mapping, to_mapping, with_covariance
from vjm.discrepancy.diagnosis import write_diagnosis
from vjm.discrepancy.simulate import simulate
from vjm.discrepancy.workflow import diagnose
from vjm.effects import modelops as mo
from vjm.errors import VjmError
from vjm.stiffness import nonlinear
from vjm.toolpath import uncertainty as unc

PUU = "data/orthoglide/puu.yaml"
Z95 = 1.959963984540054  # the two-sided 95 % normal quantile


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """A diagnosis of simulated deflections (a platform weight of 300 N hidden) and its output folder."""
    m = vjm.load_model(PUU)
    rng = np.random.default_rng(7)
    P = np.repeat(rng.uniform(-50, 100, (12, 3)), 3, axis=0)
    W = np.tile(np.array([[100.0, 0, 0, 0, 0, 0], [0, 100.0, 0, 0, 0, 0], [0, 0, 100.0, 0, 0, 0]]), (12, 1))
    dg = diagnose(m, simulate(m, [("gravity", {"weight": 300.0})], P, W, 1e-4, None, 1), effects=["gravity"])
    out = tmp_path_factory.mktemp("diag") / "rep"
    write_diagnosis(dg, out)
    return dg, out / "model_updated.yaml"


def test_the_block_reads_back_to_the_calibration_the_diagnosis_holds(written):
    dg, path = written
    cal = dg.covariance
    assert isinstance(cal, Calibration) and "gravity.weight" in cal.names
    back = unc.read(vjm.load_model(path))
    assert back.names == cal.names
    assert [back.values[n] for n in back.names] == [cal.values[n] for n in cal.names]   # exactly
    assert np.array_equal(back.cov, cal.cov) and back.terms == cal.terms
    # the standard deviations are the covariance's diagonal, and the report's standard errors
    fp = dg.report["final_params"]
    for i, nm in enumerate(back.names):
        term, p = nm.split(".")
        assert back.std[nm] == np.sqrt(back.cov[i, i])
        assert back.std[nm] == pytest.approx(fp[term][p]["se"], rel=1e-9)
        assert back.values[nm] == pytest.approx(fp[term][p]["value"], rel=1e-12)
    # and the block written again from what was read is the block in the file
    assert to_mapping(back, "s") == to_mapping(cal, "s")
    assert from_mapping(to_mapping(back, "s")).names == back.names


def _deflection(model, cal, name, v, P, W):
    """The platform deflection (n, 6) of the updated model with parameter ``name`` of ``cal`` at ``v``, solved by
    vjm.stiffness.nonlinear: the calibration's scales multiply the model's (``v / v0``); the platform's weight
    (the only effect named) adds ``weight * (0, 0, -1)`` to the load."""
    weight = model.effects["gravity"]["weight"]
    model = model.replace(effects={})
    v0 = cal.values[name]
    if name == "calibration.actuator_scale":
        model = mo.with_actuator_scale(model, v / v0)
    elif name == "calibration.link_scale":
        model = mo.with_link_scale(model, v / v0)
    elif name == "gravity.weight":
        weight = v
    else:
        raise AssertionError(f"unexpected parameter {name}")
    return nonlinear.deflection_map(model, P, W + weight * np.array([0, 0, -1.0, 0, 0, 0]))


def test_the_band_of_a_path_is_the_closed_form_of_the_covariance_read_back(written, tmp_path):
    """var(d_i) = g_i^T Sigma g_i with g from central differences (a tenth of each standard deviation) of
    deflections solved here by vjm.stiffness.nonlinear, on the norm and on each translation."""
    _, path = written
    m = vjm.load_model(path)
    cal = unc.read(m)
    P = np.array([[0.0, 0, 0], [50.0, 20.0, -10.0], [-30.0, 60.0, 20.0]])
    W = np.array([[50.0, -30.0, 80.0, 0, 0, 0]] * len(P))
    f = tmp_path / "p.csv"
    f.write_text("x,y,z,Fx,Fy,Fz,Mx,My,Mz\n" + "\n".join(",".join(repr(float(v)) for v in r)
                                                       for r in np.hstack([P, W])) + "\n")
    res = vjm.path(str(path), f, compensate=False)
    assert list(m.effects) == ["gravity"]
    d = _deflection(m, cal, "gravity.weight", m.effects["gravity"]["weight"], P, W)
    np.testing.assert_allclose(res.deflection, d, rtol=1e-8, atol=1e-12)
    G = np.stack([(_deflection(m, cal, n, cal.values[n] + 0.1 * cal.std[n], P, W)
                   - _deflection(m, cal, n, cal.values[n] - 0.1 * cal.std[n], P, W)) / (0.2 * cal.std[n])
                  for n in cal.names], axis=-1)[:, :3]   # (n, 3, k)
    S = cal.cov
    comp = Z95 * np.sqrt(np.einsum("nik,kl,nil->ni", G, S, G))
    u = d[:, :3] / np.linalg.norm(d[:, :3], axis=1, keepdims=True)
    g = np.einsum("ni,nik->nk", u, G)
    norm = Z95 * np.sqrt(np.einsum("nk,kl,nl->n", g, S, g))
    assert np.all(norm > 0)
    np.testing.assert_allclose(res.band.components, comp, rtol=1e-6, atol=1e-9 * comp.max())
    np.testing.assert_allclose(res.band.norm, norm, rtol=1e-6)


def test_a_block_naming_a_parameter_twice_is_refused():
    d = {"parameters": ["gravity.weight", "gravity.weight"], "values": [1.0, 1.0], "covariance": np.eye(2).tolist()}
    with pytest.raises(VjmError, match="named once"):
        from_mapping(d, "m.yaml")
    assert with_covariance(["a.b"], [2.0], [[4.0]]).std == {"a.b": 2.0}
