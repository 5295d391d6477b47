"""Issue 4 test 2: the linear stiffness is the slope of an independent nonlinear equilibrium."""
import numpy as np
import pytest

import vjm
from vjm.nonlinear import deflection


@pytest.mark.parametrize("p", [(0.0, 0.0, 0.0), (30.0, -50.0, 80.0), (-73.65, -73.65, -73.65)])
def test_linear_compliance_is_slope_of_nonlinear_equilibrium(p):
    """3-PUU.  vjm.nonlinear minimises spring energy minus work over all joint coordinates of
    the three chains, with finite rotations and loop closure (complex-step constraint
    gradients, Newton on the KKT system): it shares neither the Jacobians nor the bordered
    solve with the linear model.  Central differences under +-10 N and +-100 N mm cancel the
    even (quadratic) nonlinear terms; the cubic ones are ~ (deflection / L)^2 < 1e-8, so each
    column of C = K^-1 must match to 1e-4 relative (observed ~1e-6, round-off of the solve)."""
    m = vjm.load_model("data/orthoglide/puu.yaml")
    C = m.stiffness(p).C
    for k, e in enumerate([10.0, 10.0, 10.0, 100.0, 100.0, 100.0]):
        w = np.zeros(6)
        w[k] = e
        fd = (deflection(m, p, w) - deflection(m, p, -w)) / (2 * e)
        assert np.linalg.norm(fd - C[:, k]) <= 1e-4 * np.linalg.norm(C[:, k])


def test_nonlinear_departs_from_linear_under_large_load():
    """Sanity of the nonlinear model: under a load giving ~0.3 mm deflections the equilibrium
    differs from C w by more than round-off but by less than the deflection itself."""
    m = vjm.load_model("data/orthoglide/puu.yaml")
    p, w = (30.0, -50.0, 80.0), np.array([500.0, -300.0, 200.0, 2e4, 0.0, 0.0])
    lin, nl = m.deflection(p, w), deflection(m, p, w)
    diff = np.linalg.norm(nl[:3] - lin[:3])
    assert 1e-4 * np.linalg.norm(lin[:3]) < diff < 0.5 * np.linalg.norm(lin[:3])
