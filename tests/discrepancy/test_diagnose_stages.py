"""The diagnosis as stages: the typed report is what report.json holds, and the data kinds' strategies.

The reference for the report is the file the workflow writes (read back with
the json module), not the report object itself.
"""
import dataclasses
import json

import pytest

import vjm
from linkfea.files.atomic import plain
from vjm.cli.diagnose import run
from vjm.discrepancy.data import Deflections, StiffnessObs, read_csv
from vjm.discrepancy.stages.kinds import DeflectionKind, StiffnessKind, kind_of
from vjm.discrepancy.stages.record import Report

PUU = "data/orthoglide/puu.yaml"
TABLE1 = "data/seed_table1.csv"


def test_report_is_what_report_json_holds(tmp_path):
    dg = run(PUU, TABLE1, tmp_path / "t1")
    text = (tmp_path / "t1" / "report.json").read_text()
    on_disk = json.loads(text)
    rep = dg.report
    assert isinstance(rep, Report)
    # one typed field per key, in the file's order (no suggestion asked: no "suggest" key)
    assert list(on_disk) == [f.name for f in dataclasses.fields(Report) if f.name != "suggest"]
    assert list(rep) == list(on_disk) and len(rep) == len(on_disk)
    # the object reads like the file: same values through [] and through the typed fields
    assert json.dumps(plain(dict(rep)), indent=2) == text
    assert rep["verdict"] == rep.verdict == dg.verdict == on_disk["verdict"]
    assert rep.get("suggest") is None and rep.get("summary") == on_disk["summary"]
    # and it can be rebuilt from the file
    assert Report(**on_disk).to_dict() == on_disk


def test_data_kinds_are_strategies():
    d = read_csv(TABLE1)
    assert isinstance(d, StiffnessObs) and isinstance(kind_of(d), StiffnessKind)
    assert kind_of(d).name == "stiffness"
    defl = Deflections(d.P[:1], d.P[:1].repeat(2, axis=1), d.P[:1].repeat(2, axis=1))
    assert isinstance(kind_of(defl), DeflectionKind) and kind_of(defl).name == "deflection"


def test_stiffness_observations_have_no_loads_to_design():
    with pytest.raises(vjm.VjmError, match="--suggest needs deflection data"):
        vjm.diagnose(PUU, TABLE1, suggest=3)
