"""The user's files and the inputs that hang, exhaust or crash: an edited single-file output is the user's, an
output that would replace an input is refused, a user's file named like a temporary stays, a set that rewrites
another set's file replaces that set whole, a failed write leaves no folder behind; pose files, column maps and
URDFs are read only as bounded regular files, a URDF's chain depth is bounded before the parser, and the
estimates before the work count the process's own memory limit (RLIMIT_AS, cgroup) and cover compensate,
calibrate and a robot's path."""
import errno
import os
import subprocess
import sys
import textwrap
import threading
from pathlib import Path

import pytest
from bad_inputs import Case, run

from linkfea.files.atomic import write_text
from linkfea.files.outputs import (
    MANIFEST,
    OutputSet,
    check_file,
    check_folder,
    is_commands_csv,
    is_simulated_csv,
    recover,
)
from linkfea.runtime.errors import LinkFeaError
from vjm.errors import VjmError

ROOT = Path(__file__).resolve().parents[1]
UR10 = ROOT / "data" / "robots" / "ur10" / "ur10.yaml"
COMMANDS = "# commands by vjm compensate from ur10.yaml; targets t.csv\ntarget,q1,status\n1,0.5,ok\n"
SIMULATED = "# simulated by vjm simulate from ur10.yaml; poses random:1\nq1,tool0.x,tool0.y,tool0.z\n0.1,1,2,3\n"


# --------------------------------------------------------------------------- 1. the user's files
@pytest.mark.parametrize("text, owner", [(COMMANDS, is_commands_csv), (SIMULATED, is_simulated_csv)])
def test_an_edited_single_file_output_is_the_users(tmp_path, text, owner):
    """Recognised by its bytes, not its first line: as written it is the tool's (replaced on a rerun); a row
    appended, or a hand-made file with the same first line, is the user's (refused, one line)."""
    out = tmp_path / "c.csv"
    write_text(out, text)
    assert owner(out)
    check_file(out, owner, "a CSV of vjm")
    with open(out, "a", encoding="utf-8") as fh:
        fh.write("2,0.1,ok\n")
    assert not owner(out)
    with pytest.raises(LinkFeaError, match="changed since .* yours now"):
        check_file(out, owner, "a CSV of vjm")
    out.write_text(text, encoding="utf-8")  # the mark alone, no sha256 of its content: not the tool's
    assert not owner(out)


def test_an_edited_commands_csv_is_refused_by_vjm_compensate(tmp_path):
    """The issue's commands: a commands.csv edited after `vjm compensate` wrote it stops the rerun (exit 2),
    and keeps the user's row."""
    (tmp_path / "t.csv").write_text("x,y,z\n884,164,436\n")
    first = run(Case("40.1", f"vjm compensate {UR10} t.csv --out c.csv", ""), tmp_path)
    assert first.status == 0, first.stderr
    with open(tmp_path / "c.csv", "a", encoding="utf-8") as fh:
        fh.write("2,0.1,-1.2,1.5,-1.87,-1.57,0,0,1,ok,0,0\n")
    mine = (tmp_path / "c.csv").read_bytes()
    again = run(Case("40.1", f"vjm compensate {UR10} t.csv --out c.csv", ""), tmp_path)
    assert again.status == 2 and again.stderr.count("error:") == 1 and "yours now" in again.stderr
    assert (tmp_path / "c.csv").read_bytes() == mine


def test_an_output_that_would_replace_an_input_is_refused(tmp_path):
    """`vjm calibrate o/calibrated.yaml data.csv --out o --force`: the set would replace the model it reads."""
    from linkfea.files.outputs import refuse_inputs

    o = tmp_path / "o"
    with OutputSet(o, "vjm calibrate") as s:
        Path(s.path("calibrated.yaml")).write_text(f"urdf: {UR10.with_suffix('.urdf')}\n")
    (tmp_path / "data.csv").write_text("a,b\n1,2\n")
    model = (o / "calibrated.yaml").read_bytes()
    r = run(Case("40.1", "vjm calibrate o/calibrated.yaml data.csv --out o --force", ""), tmp_path)
    assert r.status == 2 and r.stderr.count("error:") == 1, r.stderr
    assert "would replace" in r.stderr and "calibrated.yaml" in r.stderr
    assert (o / "calibrated.yaml").read_bytes() == model
    # the same check for a single file, also through a second name (a link)
    (tmp_path / "sim.csv").write_text("x\n")
    os.symlink(tmp_path / "sim.csv", tmp_path / "alias.csv")
    with pytest.raises(LinkFeaError, match="would replace"):
        refuse_inputs(tmp_path / "sim.csv", (), [tmp_path / "alias.csv"])
    with pytest.raises(LinkFeaError, match="would replace"):
        check_folder(o, ["calibrated.yaml"], force=True, inputs=[o / "calibrated.yaml"])
    check_folder(o, ["calibrated.yaml"], force=True, inputs=[tmp_path / "data.csv", None])  # others: fine


@pytest.mark.parametrize("name", [".linkfea-tmp.notes.txt", f".linkfea-tmp.{2**31 - 2}.notes.txt",
                                  ".linkfea-tmp.x.abcd1234.notes.txt"])
def test_a_users_file_named_like_a_temporary_is_never_removed(tmp_path, name):
    """Only the tools' own temporaries go (prefix, a dead process's pid, mkstemp's 8 characters, the target);
    a user's file with the prefix stays and counts as the user's (the folder then needs --force)."""
    with OutputSet(tmp_path, "a") as s:
        Path(s.path("x.txt")).write_text("x")
    (tmp_path / name).write_text("my notes")
    stale = tmp_path / f".linkfea-tmp.{2**31 - 2}.k3j_9x0q.x.txt"   # a killed run's temporary
    stale.write_text("partial")
    recover(tmp_path)
    assert (tmp_path / name).read_text() == "my notes" and not stale.exists()
    with pytest.raises(LinkFeaError, match="linkfea-tmp"):
        check_folder(tmp_path, ["x.txt"])
    check_folder(tmp_path, ["x.txt"], force=True)
    assert (tmp_path / name).exists()


def test_a_set_that_rewrites_another_sets_file_replaces_that_set(tmp_path):
    """`vjm calibrate` into a `vjm diagnose` folder: the diagnosis's report.html does not stay beside the new
    set as if it were of it; a file of the old set the user edited stays (theirs), and so does a set that
    shares no file with the new one."""
    with OutputSet(tmp_path, "vjm diagnose") as s:
        for n in ("report.json", "report.html", "notes.png"):
            Path(s.path(n)).write_text(f"diagnose {n}")
    with OutputSet(tmp_path, "vjm map") as s:
        Path(s.path("map.npz")).write_text("map")
    (tmp_path / "notes.png").write_text("edited")
    with OutputSet(tmp_path, "vjm calibrate") as s:
        for n in ("report.json", "summary.txt"):
            Path(s.path(n)).write_text(f"calibrate {n}")
    assert sorted(os.listdir(tmp_path)) == [MANIFEST, "map.npz", "notes.png", "report.json", "summary.txt"]
    assert (tmp_path / "report.json").read_text() == "calibrate report.json"
    import json

    assert sorted(json.loads((tmp_path / MANIFEST).read_text())["sets"]) == ["vjm calibrate", "vjm map"]


def test_a_failed_write_leaves_no_folder_it_made(tmp_path):
    """A full disk: "nothing was written" leaves nothing, not even the empty folders the set created; a
    folder that existed before stays."""
    with pytest.raises(LinkFeaError, match="no space left"):
        with OutputSet(tmp_path / "new" / "out", "vjm calibrate") as s:
            Path(s.path("report.json")).write_text("{")
            raise OSError(errno.ENOSPC, "No space left on device", str(tmp_path / "new" / "out" / "report.json"))
    assert os.listdir(tmp_path) == []
    (tmp_path / "mine").mkdir()
    with pytest.raises(LinkFeaError):
        with OutputSet(tmp_path / "mine", "vjm calibrate") as s:
            Path(s.path("report.json")).write_text("{")
            raise OSError(errno.ENOSPC, "No space left on device")
    assert os.listdir(tmp_path) == ["mine"] and os.listdir(tmp_path / "mine") == []


# --------------------------------------------------------------------------- 2. inputs that hang or exhaust
def _in_thread(fn, seconds=20.0):
    """fn()'s exception (None if it returned); the test fails if fn does not finish (a read that blocks)."""
    box: list = []

    def target():
        try:
            fn()
            box.append(None)
        except BaseException as exc:
            box.append(exc)

    t = threading.Thread(target=target, daemon=True)
    t.start()
    t.join(seconds)
    assert box, "the read blocked"
    return box[0]


@pytest.mark.parametrize("what", ["poses", "columns"])
def test_a_named_pipe_is_refused_not_read(tmp_path, what):
    from vjm.calibration.poses import read_column_map, read_poses

    fifo = tmp_path / "p.csv"
    os.mkfifo(fifo)
    exc = _in_thread(lambda: read_poses(fifo) if what == "poses" else read_column_map(fifo))
    assert isinstance(exc, VjmError) and "not a regular file" in str(exc)


def test_a_link_to_a_device_and_a_huge_file_are_refused(tmp_path):
    from vjm.calibration.parallel_diagnosis import read
    from vjm.calibration.poses import read_poses

    os.symlink("/dev/zero", tmp_path / "zero.csv")
    with pytest.raises(VjmError, match="not a regular file"):
        read_poses(tmp_path / "zero.csv")
    big = tmp_path / "big.csv"
    with open(big, "wb") as fh:
        fh.truncate(225_000_000)   # sparse: no disk used
    with pytest.raises(VjmError, match="larger than 200 MB"):
        read_poses(big)
    with pytest.raises(VjmError, match="larger than 200 MB"):
        read(big, model=None)     # a parallel machine's poses, through the same reader


def _chain_urdf(n: int) -> str:
    links = "".join(f'<link name="l{i}"/>' for i in range(n + 1))
    joints = "".join(f'<joint name="j{i}" type="fixed"><parent link="l{i}"/><child link="l{i + 1}"/></joint>'
                     for i in range(n))
    return f'<?xml version="1.0"?><robot name="chain">{links}{joints}</robot>'


def test_a_urdf_chain_deeper_than_the_parser_takes_is_refused_before_it(tmp_path):
    """5,000 chained fixed joints (0.5 MB) crashed the URDF parser (SIGSEGV): refused first, in a child
    process so that a crash cannot take the test run with it."""
    f = tmp_path / "deep.urdf"
    f.write_text(_chain_urdf(5000))
    code = f"from vjm.modelio.urdf import read_urdf\nread_urdf({str(f)!r})"
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                       env={**os.environ, "PYTHONPATH": str(ROOT / "src")})
    assert r.returncode == 1 and "VjmError" in r.stderr and "chain of more than 1,000 joints" in r.stderr, r.stderr
    from vjm.modelio import urdf

    big = tmp_path / "big.urdf"
    with open(big, "wb") as fh:
        fh.truncate(urdf.URDF_MAX_BYTES + 1)
    with pytest.raises(VjmError, match="larger than"):
        urdf.read_urdf(big)


# --------------------------------------------------------------------------- 2. estimates
def test_the_estimate_counts_the_address_space_limit():
    """Under `ulimit -v` (RLIMIT_AS) of 1 GB beyond what the process maps, a 2 GB run is refused by the plan
    (the machine's free memory alone would let it start and end in a MemoryError)."""
    code = textwrap.dedent("""
        import resource
        from vjm.maps.grid import plan
        from vjm.errors import VjmError
        vm = next(int(l.split()[1]) * 1024 for l in open("/proc/self/status") if l.startswith("VmSize:"))
        resource.setrlimit(resource.RLIMIT_AS, (vm + (1 << 30), resource.getrlimit(resource.RLIMIT_AS)[1]))
        plan("a run", 1e6, 1e3)              # 1 GB: not refused with 0.8 GB?  it must be
    """)
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                       env={**os.environ, "PYTHONPATH": str(ROOT / "src")})
    assert r.returncode == 1 and "VjmError: a run would need about 1 GB" in r.stderr, r.stderr


def test_the_estimate_counts_the_cgroup_limit(tmp_path, monkeypatch):
    from vjm.maps import grid

    (tmp_path / "cgroup").write_text("0::/job\n")
    (tmp_path / "job").mkdir()
    (tmp_path / "job" / "memory.max").write_text("2000000000\n")
    (tmp_path / "job" / "memory.current").write_text("500000000\n")
    monkeypatch.setattr(grid, "CGROUP_ROOT", str(tmp_path))
    monkeypatch.setattr(grid, "CGROUP_OF_PROCESS", str(tmp_path / "cgroup"))
    assert grid.memory_limit() <= 1.5e9
    with pytest.raises(VjmError, match="1.5 GB"):
        grid.plan("a run", 1.5e6, 1e3)
    (tmp_path / "job" / "memory.max").write_text("max\n")   # no limit: the machine's memory decides
    assert grid.memory_limit() > 0 and grid._cgroup_room() is None


def test_targets_beyond_the_memory_are_refused_before_the_work(tmp_path, monkeypatch):
    """vjm compensate: the estimate (8 kB a target) against what the process can get, before the solver
    runs (it ended in a MemoryError traceback); a long run says how long first."""
    import vjm
    from vjm.maps import grid
    from vjm.robot.compensate import compensate_file

    t = tmp_path / "t.csv"
    # the 2 million targets against 8 GB, scaled down tenfold (200,000 against 0.8 GB): the same
    # refusal, with a tenth of the file to write and read
    t.write_text("x,y,z\n" + "884,164,436\n" * 200_000)
    m = vjm.load_model(UR10)
    monkeypatch.setattr(type(m), "compensate", lambda *a, **k: pytest.fail("the work started"))
    monkeypatch.setattr(grid, "memory_limit", lambda: 8e8)
    with pytest.raises(VjmError, match="vjm compensate would need about 1.6 GB .* 2e\\+05 targets"):
        compensate_file(m, t, m.home, m.tools[0])


def test_long_runs_say_so_before_the_work(capsys):
    """calibrate (200,000 rows) and a robot's path (388,000 points, 1.2 ms a point) announce their time: the
    estimate's line, printed before the work (the path's estimate was the 3-PUU's 0.1 ms a point, so silent)."""
    from vjm.calibration.diagnosis import ROW_COST
    from vjm.maps.grid import plan
    from vjm.toolpath.points import ROBOT_PATH_SECONDS, path_plan

    said: list = []
    p = plan("vjm calibrate", 200_000, *ROW_COST, unit="rows", progress=said.append)
    assert p.long and said and said[0].startswith("vjm calibrate: 200,000 points") and "min" in said[0]
    assert path_plan(388_000, ROBOT_PATH_SECONDS).long and not path_plan(388_000).long
    assert plan("short", 10, 1.0, progress=said.append) and len(said) == 1   # a short run stays quiet


def test_a_robot_path_announces_its_time_before_the_passes(tmp_path, monkeypatch):
    """vjm path on the UR10 over 388,000 points: the estimate line ("vjm path: ...", what turns the CLI's
    progress on) comes before the first pass (stubbed here: the test times nothing)."""
    import vjm
    from vjm.toolpath import Constant, robot

    prog = tmp_path / "p.nc"
    prog.write_text("G21 G90 G17\nG0 X780 Y120 Z260\nG1 Z250 F300\nG1 X830 F1200\n")

    class Stop(Exception):
        pass

    def passes(*a, **k):
        raise Stop

    monkeypatch.setattr(robot, "_passes", passes)
    said: list = []
    with pytest.raises(Stop):
        vjm.path(UR10, prog, wrench=Constant((10.0, 0, 0, 0, 0, 0)), step=60 / 388_000, progress=said.append)
    assert said and said[0].startswith("vjm path: 388,002 points") and "7.8 min" in said[0], said
