"""`vjm diagnose` on a machine given as a description file (data/machines/orthoglide_puu.yaml).

The measurements come from the independent truth generator (tests/truth.py: the 3-PUU model
file solved by vjm plus a backlash written out there), not from vjm.discrepancy.  The same
data diagnosed against the built-in 3-PUU module and against its description file must give
the same verdict, the same named effect and the same fitted figures: the two models have the
same K to round-off, so the statistics on top of them may differ only by round-off too.
"""
import numpy as np
import pytest
import truth as tr

import vjm
from vjm.resources import data_file

BACKLASH = 2e-3  # mm, hidden in the data (truth.LIBRARY["clearance"])


def _figures(rep: dict) -> dict:
    out = {"chi2_before": rep["chi2_before"], "chi2_after": rep["chi2_after"]}
    for group, params in rep["final_params"].items():
        for name, p in params.items():
            out[f"{group}.{name}"] = p["value"]
            out[f"{group}.{name}.se"] = p["se"]
    return out


@pytest.fixture(scope="module")
def data_path(tmp_path_factory):
    _, truth = tr.hide(("clearance", BACKLASH))
    P, W = tr.design(8, 6, seed=11)
    return tr.measure(truth, P, W, seed=101).write(tmp_path_factory.mktemp("desc") / "data.csv")


def test_description_file_diagnoses_like_the_builtin_module(tmp_path, data_path):
    builtin = tr.write_model(tr.MODELS["puu"], tmp_path / "puu.yaml")
    described = str(data_file("machines/orthoglide_puu.yaml"))
    a = vjm.diagnose(builtin, data_path, alpha=0.01)
    b = vjm.diagnose(described, data_path, alpha=0.01)
    assert a.verdict == b.verdict == "explained"
    assert a.named == b.named == ["clearance"]
    fa, fb = _figures(a.report), _figures(b.report)
    assert fa.keys() == fb.keys()
    for k in fa:
        assert fb[k] == pytest.approx(fa[k], rel=1e-6), k
    # and the figure is the hidden one, within its own 95% interval
    lo, hi = b.report["final_params"]["clearance"]["backlash"]["ci95"]
    assert lo <= BACKLASH <= hi
    assert np.isfinite(fb["chi2_after"]) and fb["chi2_after"] < fb["chi2_before"]
