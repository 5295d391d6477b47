"""A sweep's size before it starts: designs counted without listing them, refused beyond memory,
announced when long; no traceback for sizes the tool can check.

The count is checked against the listed grid itself (an independent enumeration); the refusal
against the arithmetic of the limit.
"""
import subprocess
import sys
import time

import pytest
from typer.testing import CliRunner

from linkfea.cli import app as linkfea_app
from linkfea.runtime.errors import LinkFeaError
from linkfea.sweep import budget as sweep_budget
from linkfea.sweep import make_sweep, parse_param_spec, run_sweep


@pytest.mark.parametrize("spec", ["h=10:30:5", "h=0.1:0.3:0.1", "h=1:2:0.3", "h=0:1:0.01", "h=5:5:1", "h=1,2,x"])
def test_counted_grid_equals_listed_grid(spec):
    p = parse_param_spec(spec)
    assert p.grid_count() == len(p.grid_values())


def test_huge_grid_is_refused_at_once_naming_estimate_and_limit(tmp_path):
    """10^8 designs: one line, exit 2, within seconds, nothing written (it used to take 20 GB)."""
    out = tmp_path / "o"
    t0 = time.perf_counter()
    p = subprocess.run([sys.executable, "-m", "linkfea", "sweep", "bar", "--param", "width=1:100000:0.001",
                        "--out", str(out)], capture_output=True, text=True, timeout=120)
    lines = [ln for ln in p.stderr.splitlines() if ln.strip()]
    assert p.returncode == 2 and len(lines) == 1, p.stderr
    assert lines[0].startswith("error: 99,999,001 designs are too many") and "limit" in lines[0], lines[0]
    assert " GB" in lines[0] or " TB" in lines[0]
    assert time.perf_counter() - t0 < 60
    assert not out.exists()


def test_refusal_follows_the_memory_limit(monkeypatch):
    # 4 x 5 = 20 designs; with 0.5 MB available (limit 250 kB) they need 20 x (16 kB + source) > limit
    monkeypatch.setattr(sweep_budget, "available_memory", lambda: 500_000)
    with pytest.raises(LinkFeaError, match=r"^20 designs are too many: .* \(limit 250 kB, half the memory"):
        make_sweep("bar", ["length=100,120,140,160", "width=10:14:1"])
    with pytest.raises(LinkFeaError, match="^40 designs are too many"):
        make_sweep("bar", ["length=100:200"], sample=40)
    monkeypatch.setattr(sweep_budget, "available_memory", lambda: 10_000_000)
    assert len(make_sweep("bar", ["length=100,120,140,160", "width=10:14:1"]).designs) == 20


@pytest.mark.parametrize("args", [["--param", "width=1:2:1e-320"], ["--param", "width=1:1e308:1e-300"],
                                  ["--param", "width=10:20", "--sample", "1000000000000"],
                                  ["--param", "width=1:10000:0.01", "--param", "length=1:10000:0.01"],
                                  ["--param", "width=10", "--memory-limit", "lots"],
                                  ["--param", "width=10", "--memory-limit", "-2GB"]])
def test_sizes_the_tool_can_check_get_one_line(args, tmp_path):
    out = tmp_path / "o"
    r = CliRunner().invoke(linkfea_app, ["sweep", "bar", *args, "--out", str(out), "-q"])
    assert r.exit_code == 2 and r.output.count("\n") == 1 and r.output.startswith("error: "), r.output
    assert not out.exists()


def test_announcement_arithmetic():
    assert sweep_budget.announcement(6, 2, None) is None  # 3 rounds of 10 s
    msg = sweep_budget.announcement(100, 2, None)
    assert "100 designs to compute on 2 workers" in msg and "about 8.3 min" in msg and "first guess" in msg
    msg = sweep_budget.announcement(10, 1, 7200.0)
    assert "about 20 h" in msg and "measured" in msg
    assert sweep_budget.human_duration(1e8 * 10 / 2) == "16 years"


def test_long_sweep_says_how_long_before_it_starts(tmp_path, capfd):
    """7 designs on 1 worker at the nominal 10 s: 70 s, so the run announces it (the designs
    themselves fail at once on a negative width, which keeps this test short)."""
    from distributed import Client

    sw = make_sweep("bar", ["width=-1,-2,-3,-4,-5,-6,-7"], {"mesh_size": 6.0})
    with Client(processes=False, n_workers=1, threads_per_worker=1, dashboard_address=":0") as c:
        rep = run_sweep(sw, tmp_path / "o", client=c, progress=True)
    assert len(rep.failed) == 7
    err = capfd.readouterr().err
    assert "7 designs to compute on 1 worker, about 10 s each (a first guess): about 1.2 min" in err, err
    # a rerun of the failed designs uses their measured time (well under a second each): no announcement
    with Client(processes=False, n_workers=1, threads_per_worker=1, dashboard_address=":0") as c:
        run_sweep(sw, tmp_path / "o", client=c, progress=True, retry_failed=True)
    assert "designs to compute" not in capfd.readouterr().err
