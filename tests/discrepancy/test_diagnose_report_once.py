"""The diagnosis report is assembled once, from the stages' values, and cannot be changed afterwards.

A hidden 3 um clearance (tests/truth.py) on 8 postures at two load levels, with suggested measurements:
the load-level test, the noise check and the suggestions all reach the report, yet exactly one
:class:`~vjm.discrepancy.stages.record.Report` is built in the whole diagnosis (``dataclasses.replace``
builds a new one, so a stage patching the report after assembly is counted), and each of its members
is frozen all the way down.  The outlier reruns are counted in tests/discrepancy/test_diagnose_outliers.py.
"""
import dataclasses
import json
from types import MappingProxyType

import numpy as np
import pytest
import truth as tr
from assembly import Count

import vjm
from vjm.discrepancy.summary import summary


def mutable_members(x, path="report") -> list:
    """Paths of the members of ``x`` that can be changed in place."""
    if isinstance(x, (dict, list, set)):
        return [path]
    if isinstance(x, np.ndarray):
        return [path] if x.flags.writeable else []
    if isinstance(x, MappingProxyType):
        return [p for k, v in x.items() for p in mutable_members(v, f"{path}[{k!r}]")]
    if isinstance(x, tuple):
        return [p for i, v in enumerate(x) for p in mutable_members(v, f"{path}[{i}]")]
    if dataclasses.is_dataclass(x) and not isinstance(x, type):
        return [p for f in dataclasses.fields(x) for p in mutable_members(getattr(x, f.name), f"{path}.{f.name}")]
    return []


@pytest.fixture(scope="module")
def diagnosed(tmp_path_factory):
    d = tmp_path_factory.mktemp("once")
    given, truth = tr.hide(("clearance", 3e-3))
    P, W = tr.level_design(8, 4, seed=3)
    data = tr.measure(truth, P, W, seed=7).write(d / "levels.csv")
    with Count() as c:
        dg = vjm.diagnose(tr.write_model(given, d / "model.yaml"), data, alpha=0.01, suggest=2)
    return dg, c.n


def test_the_report_is_built_once(diagnosed):
    dg, built = diagnosed
    rep = dg.report
    # every value that used to be patched in after the report was built is there
    assert len(rep.lack_of_fit["load_levels"]["levels_N"]) >= 2  # 0.5 and 1 x 100 N and 5000 N mm
    assert rep.suggest["n"] == 2 and dg.next_measurements.shape == (2, 9)
    assert set(rep.noise["groups"]) == {"t", "r"}
    assert rep.summary == summary(rep.to_dict())  # written from the same values
    assert built == 1


def test_the_report_cannot_be_changed(diagnosed):
    dg, _ = diagnosed
    rep = dg.report
    before = json.dumps(rep.to_dict(), sort_keys=True, default=str)
    assert mutable_members(rep) == []
    with pytest.raises(dataclasses.FrozenInstanceError):
        rep.verdict = "explained"  # type: ignore[misc]
    with pytest.raises(TypeError):
        rep.lack_of_fit["load_levels"] = None  # type: ignore[index]
    with pytest.raises(AttributeError):
        rep.flags.append("patched")  # type: ignore[attr-defined]
    # the dictionary views are copies: changing them leaves the report as it was
    d = rep.to_dict()
    d["candidates"].clear()
    d["lack_of_fit"]["alpha"] = 1.0
    rep["flags"].append("patched")
    assert json.dumps(rep.to_dict(), sort_keys=True, default=str) == before


def test_the_stages_are_listed_once_in_run_order():
    """The run order lives in vjm.discrepancy.stages' docstring; the docs' table follows it, and every stage
    module is in it (the helpers: data kinds, levels, norms, rivals)."""
    import pathlib
    import re

    import vjm.discrepancy.stages as st

    order = re.findall(r"^\s*\d+\. ``(\w+)``", st.__doc__, re.M)
    here = pathlib.Path(st.__file__).parent
    helpers = {"__init__", "kinds", "thresholds", "norms", "rivals"}
    assert sorted(order) == sorted(p.stem for p in here.glob("*.py") if p.stem not in helpers)
    docs = pathlib.Path(__file__).parents[2] / "docs" / "discrepancy.md"
    rows = [ln for ln in docs.read_text(encoding="utf-8").splitlines() if re.match(r"\|.*\| `stages/\w+\.py` \|", ln)]
    assert [re.search(r"\| `stages/(\w+)\.py` \|", r).group(1) for r in rows] == order
