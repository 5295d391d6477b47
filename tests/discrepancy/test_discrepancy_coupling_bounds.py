"""The coupling effects may span the whole range a link can physically have.

A bound inside the positive-definite range clips estimates a real link can
give: the foot's bending coupling of a beam (kappa = 1 on c35) estimated at
1.13 +- 0.06 on one data set was clipped at the old bound 1.1 and the effect
never entered (issue 8).  Closed forms: the 2x2 bending block
``[[c22, k c22^.5 c66^.5 sqrt3/2], [., c66]]`` is singular at ``k = 2/sqrt3``,
the extension-torsion block ``[[c11, k sqrt(c11 c44)], [., c44]]`` at ``k = 1``;
with a further coupling in the matrix the limit is where its smallest
eigenvalue (computed here directly) reaches zero.
"""
import numpy as np
import pytest

import vjm
from vjm import effects as fx
from vjm.effects import modelops as mo
from vjm.model.links import LinkSpring as Link

FULL = vjm.load_model("data/orthoglide/puu.yaml")


def _kappa_spec(model, name):
    (p,) = fx.get(name).param_specs(model)
    return p


@pytest.mark.parametrize("name, limit", [("foot_bending_coupling", 2.0 / np.sqrt(3.0)),
                                         ("leg_bending_coupling", 2.0 / np.sqrt(3.0)),
                                         ("foot_extension_torsion", 1.0),
                                         ("leg_extension_torsion", 1.0)])
def test_coupling_bounds_reach_the_positive_definite_limit(name, limit):
    p = _kappa_spec(FULL, name)
    assert p.upper == pytest.approx(mo.ADMISSIBLE * limit, rel=1e-9)
    assert p.lower == pytest.approx(-mo.ADMISSIBLE * limit, rel=1e-9)
    assert p.upper > 1.1 if "bending" in name else p.upper > 0.9  # the old bounds clipped inside


def _smallest_scaled_eigenvalue(C):
    d = np.sqrt(np.diag(C))
    return np.linalg.eigvalsh(C / np.outer(d, d))[0]


def test_coupling_bound_with_another_coupling_in_the_link():
    """A foot whose c16 couples the y bending block to the axial one: the bending kappa's
    limits shrink; the effect's compliance at them is positive definite, and at them / ADMISSIBLE
    (the couplings written out here) just singular."""
    C = mo.link_compliance(FULL, "foot").copy()
    C[0, 1] = C[1, 0] = 0.5 * np.sqrt(C[0, 0] * C[1, 1])
    model = FULL.replace(foot=Link(C, None))
    p = _kappa_spec(model, "foot_bending_coupling")
    for k in (p.lower, p.upper):
        inside = mo.link_compliance(fx.get("foot_bending_coupling").apply(model, [k]), "foot")
        assert _smallest_scaled_eigenvalue(inside) > 0.0
        Ck = C.copy()
        s = np.sqrt(3.0) / 2.0 * k / mo.ADMISSIBLE
        Ck[1, 5] = Ck[5, 1] = s * np.sqrt(C[1, 1] * C[5, 5])
        Ck[2, 4] = Ck[4, 2] = -s * np.sqrt(C[2, 2] * C[4, 4])
        assert abs(_smallest_scaled_eigenvalue(Ck)) < 1e-9
    assert p.upper < mo.ADMISSIBLE * 2.0 / np.sqrt(3.0)
