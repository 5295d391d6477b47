"""The pytetwild mesh cache: one mesh per key under concurrent runs, stale locks, damaged entries.

pytetwild is not deterministic: three runs that each mesh give three different meshes (and
compliances that differ in the 4th digit; at --mesh-size 8 three unlocked runs gave 707, 843
and 695 tets).  So identical results of three concurrent cold-cache runs show that only one of
them meshed.
"""
import json
import os
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from linkfea.mesh.cache import DamagedEntry, cache_dir_default, cached_mesh, key_lock, read_entry, write_entry

COMPUTE = ["compute", "bar", "--mesher", "pytetwild", "--mesh-size", "8", "--no-picture", "-q"]


def _start(args, env, cwd):
    return subprocess.Popen([sys.executable, "-m", "linkfea", *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=env, cwd=cwd)


@pytest.fixture(scope="module")
def three_runs(tmp_path_factory):
    """Three concurrent `linkfea compute bar --mesher pytetwild` on one cold cache."""
    root = tmp_path_factory.mktemp("concurrent")
    env = {**os.environ, "LINKFEA_CACHE_DIR": str(root / "cache")}
    procs = [_start([*COMPUTE, "--out", str(root / f"r{i}.json")], env, root) for i in range(3)]
    outs = [p.communicate(timeout=600) for p in procs]
    for p, (_, err) in zip(procs, outs):
        assert p.returncode == 0, err
    docs = [json.loads((root / f"r{i}.json").read_text()) for i in range(3)]
    return root, docs


def test_concurrent_cold_cache_runs_produce_one_mesh(three_runs):
    root, docs = three_runs
    entries = sorted(p.name for p in (root / "cache").glob("*.npz"))
    assert len(entries) == 1, entries
    key = entries[0][:-4]
    for d in docs:
        assert d["mesh"]["cache_key"] == key
        assert d["mesh"]["n_tets"] == docs[0]["mesh"]["n_tets"]
        assert d["compliance"] == docs[0]["compliance"]  # bit for bit: one mesh
    points, tets = read_entry(root / "cache" / entries[0])
    assert len(tets) == docs[0]["mesh"]["n_tets"] and len(points) == docs[0]["mesh"]["n_nodes"]
    # nothing but the entry and its (empty) lock file
    assert sorted(p.name for p in (root / "cache").iterdir()) == [entries[0], entries[0] + ".lock"]


def _run_here(folder):
    """`linkfea compute` of COMPUTE in process in ``folder``, as the bad-input table runs its cases: the
    concurrency of :func:`three_runs` needs processes, a single run does not (its stderr and status are main's)."""
    from bad_inputs import Case, run

    return run(Case("", " ".join(["linkfea", *COMPUTE, "--out", "r.json"]), ""), folder)


def test_truncated_entry_is_a_miss_warned_once_and_replaced(three_runs, tmp_path, monkeypatch):
    root, docs = three_runs
    cache = tmp_path / "cache"
    cache.mkdir()
    (entry,) = (root / "cache").glob("*.npz")
    data = entry.read_bytes()
    (cache / entry.name).write_bytes(data[: len(data) // 2])  # a run killed by a full disk, say
    monkeypatch.setenv("LINKFEA_CACHE_DIR", str(cache))
    work = tmp_path / "work"
    work.mkdir()
    res = _run_here(work)
    err = res.stderr
    assert res.status == 0, err
    assert "Traceback" not in err
    warn = [ln for ln in err.splitlines() if ln.startswith("warning:")]
    assert len(warn) == 1 and "damaged" in warn[0] and entry.name in warn[0], err
    doc = json.loads((work / "r.json").read_text())
    # a fresh mesh of the same key: the compliance agrees with the other mesh to the mesh error
    # (entries scaled by sqrt(C_ii C_jj), so the near-zero couplings are judged by the diagonal)
    new, old = np.array(doc["compliance"]), np.array(docs[0]["compliance"])
    s = np.sqrt(np.outer(np.diag(old), np.diag(old)))
    np.testing.assert_allclose(new / s, old / s, atol=2e-2)
    assert doc["mesh"]["cache_key"] == entry.name[:-4]
    # the entry was replaced by the new, complete mesh (and no temporary is left)
    points, tets = read_entry(cache / entry.name)
    assert len(tets) == doc["mesh"]["n_tets"]
    assert sorted(q.name for q in cache.iterdir()) == [entry.name, entry.name + ".lock"]


def test_default_folder_is_the_platform_cache(monkeypatch, tmp_path):
    """Without $LINKFEA_CACHE_DIR (or with it empty) the cache is the platform's, not the current folder's."""
    from platformdirs import user_cache_path

    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("LINKFEA_CACHE_DIR", raising=False)
    assert cache_dir_default() == user_cache_path("linkfea", appauthor=False) / "meshes"
    assert cache_dir_default().is_absolute()
    monkeypatch.setenv("LINKFEA_CACHE_DIR", "")
    assert cache_dir_default() == user_cache_path("linkfea", appauthor=False) / "meshes"
    monkeypatch.setenv("LINKFEA_CACHE_DIR", str(tmp_path / "mine"))
    assert cache_dir_default() == tmp_path / "mine"


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="XDG_CACHE_HOME places the cache on Linux only")
def test_a_run_from_any_folder_reads_the_platform_cache(three_runs, tmp_path, monkeypatch):
    """The entry of a key, placed in the platform's cache folder, is what a run without $LINKFEA_CACHE_DIR
    reads (same key, same matrix bit for bit: pytetwild would give another mesh), and the folder the run
    starts from gets the result only."""
    root, docs = three_runs
    (entry,) = (root / "cache").glob("*.npz")
    platform = tmp_path / "xdg" / "linkfea" / "meshes"
    platform.mkdir(parents=True)
    (platform / entry.name).write_bytes(entry.read_bytes())
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.delenv("LINKFEA_CACHE_DIR", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    res = _run_here(work)
    assert res.status == 0, res.stderr
    doc = json.loads((work / "r.json").read_text())
    assert doc["mesh"]["cache_key"] == entry.name[:-4]
    assert doc["compliance"] == docs[0]["compliance"]
    assert sorted(q.name for q in platform.iterdir()) == [entry.name]  # a hit: no lock was needed
    assert sorted(q.name for q in work.iterdir() if not q.name.startswith(".linkfea-outputs")) == ["r.json"]


def test_read_entry_tells_missing_from_damaged(tmp_path):
    assert read_entry(tmp_path / "none.npz") is None
    pts, tets = np.random.default_rng(0).random((5, 3)), np.array([[0, 1, 2, 3], [1, 2, 3, 4]])
    write_entry(tmp_path / "ok.npz", pts, tets)
    p, t = read_entry(tmp_path / "ok.npz")
    assert np.array_equal(p, pts) and np.array_equal(t, tets)
    (tmp_path / "zero.npz").write_bytes(b"")
    (tmp_path / "text.npz").write_text("not a zip")
    good = (tmp_path / "ok.npz").read_bytes()
    (tmp_path / "cut.npz").write_bytes(good[:-40])
    write_entry(tmp_path / "index.npz", pts, tets + 10)  # a tet refers to a missing point
    np.savez(tmp_path / "keys.npz", points=pts)  # no tets
    for name in ("zero", "text", "cut", "index", "keys"):
        with pytest.raises(DamagedEntry):
            read_entry(tmp_path / f"{name}.npz")


def test_damaged_entry_in_process_warns_and_remeshes(tmp_path):
    from linkfea.runtime.errors import LinkFeaWarning

    pts, tets = np.random.default_rng(1).random((4, 3)), np.array([[0, 1, 2, 3]])
    (tmp_path / "k.npz").write_bytes(b"PK\x03\x04 truncated")
    calls = []

    def make():
        calls.append(1)
        return pts, tets

    with pytest.warns(LinkFeaWarning, match="damaged"):
        p, t = cached_mesh(tmp_path, "k", make, lambda m: None)
    assert calls == [1] and np.array_equal(p, pts)
    p2, _ = cached_mesh(tmp_path, "k", make, lambda m: None)  # now a hit
    assert calls == [1] and np.array_equal(p2, pts)


_HOLDER = """
import sys, time
from pathlib import Path
from linkfea.mesh.cache import key_lock
with key_lock(Path(sys.argv[1])):
    print("locked", flush=True)
    time.sleep(600)
"""


def test_lock_of_a_killed_run_does_not_block(tmp_path):
    lock = tmp_path / "k.npz.lock"
    holder = subprocess.Popen([sys.executable, "-c", _HOLDER, str(lock)], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "locked"
        got = threading.Event()
        waited = []

        def take():
            with key_lock(lock, on_wait=lambda: waited.append(1)):
                got.set()

        t = threading.Thread(target=take, daemon=True)
        t.start()
        time.sleep(0.5)
        assert not got.is_set() and waited == [1]  # the live holder blocks
        os.kill(holder.pid, signal.SIGKILL)
        assert got.wait(10), "the lock of a killed process still blocks"
    finally:
        holder.kill()
        holder.wait()
