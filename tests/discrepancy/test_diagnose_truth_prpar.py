"""Acceptance of `vjm diagnose` on the 3-PRPaR's parallelogram bar (tests/truth.py).

The true machines are richer model files of ``data/orthoglide/prpar.yaml``
(one deformation mode of the bar softened, its bending or extension-torsion
coupling changed, written into the bar's beam compliance) solved by vjm
(``C w``), measured on the 3-PRPaR's acceptance design (``truth.DESIGNS``:
12 postures x 12 loads, moments up to 20 N m) with 1 um / 10 urad noise.
Same rule as test_diagnose_truth.py (its ``check_effect``): the truth
decides whether the data can show the effect; seen, it is named with
verdict ``explained``; not seen (the bar's bending about the pivots' axis),
it is reported unobservable and nothing is named.  A separate file so that
the suite's workers run it beside the 3-PUU's.
"""
import pytest
from test_diagnose_truth import _cases, check_effect


@pytest.mark.parametrize("name", _cases("prpar"))
def test_each_bar_effect_is_named(tmp_path, name):
    check_effect(tmp_path, name)
