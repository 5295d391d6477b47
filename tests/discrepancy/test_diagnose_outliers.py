"""Gross outliers in the measurements (`vjm diagnose`, stages/outliers.py), on data from tests/truth.py.

The outliers are made in the truth (``truth.with_outliers``: one measured component of a row off by
20-60 sigma), never with the diagnosis' code.  A hidden 3 um actuator clearance on 16 postures x 12
loads: with 3 % such rows the clearance alone is named and exactly the corrupted file rows are set
aside; the same data diagnosed with every row (``--no-outliers``) is not explained; a clean set gives
the report of the plain diagnosis; 15 % such rows: ``untrusted_data``; an out-of-library contact is
still ``unexplained``, its worst rows not taken for outliers.  The rate over many sets:
benchmarks/bench_diagnose_outliers.py.
"""
import json

import numpy as np
import pytest
import truth as tr
from assembly import Count
from typer.testing import CliRunner

import vjm
from vjm.cli import app

ALPHA = 0.01


@pytest.fixture(scope="module")
def case(tmp_path_factory):
    """(folder, model path, clean measurements) of the hidden clearance."""
    d = tmp_path_factory.mktemp("outliers")
    given, truth = tr.hide(("clearance", 3e-3))
    P, W = tr.design(12, 12, seed=11)
    return d, tr.write_model(given, d / "model.yaml"), tr.measure(truth, P, W, seed=5)


def write_with_comment(m: tr.Measurements, path) -> str:
    """The file with a comment line on top: file row = position + 3 (header on row 2)."""
    m.write(path)
    text = open(path, encoding="utf-8").read()
    with open(path, "w", encoding="utf-8") as fh:
        fh.write("# measured on the test rig\n" + text)
    return str(path)


def cli_report(model, data, out, *args) -> dict:
    res = CliRunner().invoke(app, ["diagnose", model, data, "--out", str(out), "--alpha", str(ALPHA), *args])
    assert res.exit_code == 0, res.output
    with open(out / "report.json", encoding="utf-8") as fh:
        return json.load(fh)


@pytest.fixture(scope="module")
def three_percent(case):
    d, model, clean = case
    m, rows = tr.with_outliers(clean, 0.03, np.random.default_rng(1))
    data = write_with_comment(m, d / "three.csv")
    with Count() as built:  # the reports built in the robust diagnosis, its reruns included
        robust = cli_report(model, data, d / "robust")
    return robust, cli_report(model, data, d / "plain", "--no-outliers"), (rows + 3).tolist(), d, built.n


def test_three_percent_outliers_set_aside_and_the_clearance_named(three_percent):
    rep, _, corrupted, d, _ = three_percent
    assert rep["verdict"] == "explained", rep["summary"]
    assert tr.names_exactly(rep, ["clearance"]), rep["summary"]
    o = rep["outliers"]
    assert o["rows"] == corrupted  # file row numbers, the comment line counted
    assert o["n_rows"] == len(corrupted) and o["n_rows_total"] == 144
    assert all(abs(e["z"]) > 15 for e in o["observations"])  # 20-60 sigma, standardized by the model without them
    assert rep["n_observations"] == 6 * (144 - len(corrupted))  # the verdict is computed without them
    assert f"{len(corrupted)} of 144 rows" in rep["summary"].split(". ")[0]  # the verdict sentence says so
    assert any("gross outliers" in f for f in rep["flags"])
    html = (d / "robust" / "report.html").read_text(encoding="utf-8")
    assert "Rows set aside as gross outliers" in html and f"<td>{corrupted[0]}</td>" in html


def test_the_reruns_build_no_report(three_percent):
    """The workflow reruns the stages without the rows set aside; the report is assembled once, at the end."""
    rep, _, _, _, built = three_percent
    assert rep["outliers"]["passes"] >= 2 and built == 1


def test_the_same_data_with_every_row_is_not_explained(three_percent):
    """The defect is real: with the outliers in, the clearance alone does not explain the data."""
    _, plain, _, _, _ = three_percent
    assert plain["outliers"] is None
    assert not (plain["verdict"] == "explained" and tr.names_exactly(plain, ["clearance"])), plain["summary"]


def test_clean_set_gives_the_plain_report(case):
    d, model, clean = case
    data = clean.write(d / "clean.csv")
    robust = vjm.diagnose(model, data, alpha=ALPHA).report.to_dict()
    plain = vjm.diagnose(model, data, alpha=ALPHA, outliers=False).report.to_dict()
    assert robust["outliers"] is None
    assert repr(robust) == repr(plain)  # every value, NaNs (candidates without a cv_error) included
    assert robust["verdict"] == "explained" and robust["named_effects"] == ["clearance"]


def test_fifteen_percent_outliers_data_not_trusted(case):
    d, model, clean = case
    m, rows = tr.with_outliers(clean, 0.15, np.random.default_rng(2))
    dg = vjm.diagnose(model, m.write(d / "fifteen.csv"), alpha=ALPHA)
    rep = dg.report
    assert rep.verdict == "untrusted_data" and dg.verdict == "untrusted_data"
    assert dg.named == [] and not dg.updated_model.effects
    assert set(rep.outliers["rows"]) >= set((rows + 2).tolist())
    assert rep.outliers["fraction"] > 0.10
    assert "cannot be trusted" in rep.summary.split(". ")[0]
    assert list(rep.final_params) == ["calibration"]


def test_out_of_library_contact_is_not_turned_into_outliers(case):
    """A Hertz-like contact at the tool (deflection ~ |F|^(2/3) along the force), known sigmas: its largest
    residuals lie beyond the outlier threshold, but setting them aside leaves a gap: `unexplained`."""
    d, model, _ = case
    P, W = tr.design(12, 12, seed=11)
    m = tr.measure(tr.Truth(tr.variant(tr.NOMINAL), contact=1.5e-3), P, W, seed=305)
    rep = vjm.diagnose(tr.write_model(tr.NOMINAL, d / "nominal.yaml"), m.write(d / "contact.csv"), alpha=ALPHA).report
    assert rep.verdict == "unexplained", rep.summary
    assert rep.outliers is None


def test_without_sigmas_or_repeats_rows_are_flagged_but_kept(case):
    """No sigma columns and no repeated rows: the lack of fit cannot be judged, so a row beyond the threshold
    cannot be told from the worst part of a missing effect; it is reported, never set aside."""
    d, model, clean = case
    bare = tr.Measurements(clean.P, clean.W, clean.T, None, None)
    m, rows = tr.with_outliers(bare, 0.15, np.random.default_rng(2), sigma_t=1e-3, sigma_r=1e-5)
    rep = vjm.diagnose(model, m.write(d / "bare.csv"), alpha=ALPHA).report
    assert rep.verdict != "untrusted_data" and rep.outliers is None
    assert any("cannot be judged" in f and "every row is kept" in f for f in rep.flags), rep.flags
