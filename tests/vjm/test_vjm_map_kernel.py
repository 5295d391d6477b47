"""The compiled stiffness map (vjm.maps.map_kernel) against the batched numpy path, the reference."""
import os
import subprocess
import sys

import numpy as np
import pytest

import vjm
from vjm.stiffness import linear as stiffness

PUU = "data/orthoglide/puu.yaml"
HEXAPOD = "data/machines/hexapod_6ups.yaml"


def _rel(a, b):
    """Largest difference per pose relative to the pose's largest entry of the reference."""
    a, b = np.asarray(a), np.asarray(b)
    scale = np.max(np.abs(b).reshape(len(b), -1), axis=1)
    return float(np.max(np.abs(a - b).reshape(len(b), -1) / scale[:, None]))


def _both(m, P):
    return m.stiffness_map(P, kernel="numba"), m.stiffness_map(P, kernel="numpy")


def _same_decisions(a, b):
    assert a.rank.tolist() == b.rank.tolist()
    assert a.invertible.tolist() == b.invertible.tolist()
    assert a.chain_rank.tolist() == b.chain_rank.tolist()


@pytest.mark.parametrize("path", [PUU, HEXAPOD])
def test_kernel_agrees_with_numpy_at_random_poses(path):
    """Random poses over the workspace (the hexapod also rotated): K, C, k_tran, k_rot to 1e-12
    relative, and the same ranks; a block size that is not a multiple of the kernel's lanes."""
    m = vjm.load_model(path)
    rng = np.random.default_rng(29)
    if m.dof == 6:
        lo, hi = m.arch.workspace
        P = np.hstack([rng.uniform(lo, hi, (301, 3)), rng.uniform(-0.05, 0.05, (301, 3))])
    else:
        P = rng.uniform(-73.65, 126.35, (400, 3))
        P = P[m.reachable(P)][:301]
    a, b = _both(m, P)
    assert len(P) == 301 and b.invertible.all()
    for name in ("K", "C", "k_tran", "k_rot"):
        assert _rel(getattr(a, name), getattr(b, name)) < 1e-12, name
    _same_decisions(a, b)


def _min_pivot(K):
    """Smallest pivot of the unpivoted LDL^T of the Jacobi-scaled K, from leading minors."""
    d = np.sqrt(np.clip(np.diagonal(K), 1e-300, None))
    A = K / d[:, None] / d[None, :]
    dets = [1.0] + [np.linalg.det(A[:j, :j]) for j in range(1, 7)]
    return min(dets[j + 1] / dets[j] for j in range(6))


def test_kernel_same_rank_near_a_singularity():
    """Towards (0, 0, -L), where the x leg loses a rank and K a direction (as
    test_vjm_inputs.test_singular_postures_finite_with_rank): the same chain ranks, machine
    ranks and invertibility mask on both paths, non-invertible poses among them, and K to 1e-12.
    The poses sit clearly off the invertibility threshold (no decision on a tie)."""
    m = vjm.load_model(PUU)
    L = m.geometry["L"]
    eps = np.array([0.0, 1e-8, 1e-7, 1e-4, 1e-2, 1.0, 10.0])
    P = np.stack([np.zeros_like(eps), 0.3 * eps, -L + eps], axis=1)
    P = np.repeat(P, 40, axis=0)  # a block the kernels take (auto would too: 280 poses)
    a, b = _both(m, P)
    for K in b.K[::40][1:]:
        piv = _min_pivot(K)
        assert piv < 1e-10 / 3 or piv > 3e-10
    _same_decisions(a, b)
    assert not b.invertible.all() and b.invertible.any()
    assert (b.chain_rank[0] == [3, 4, 4]).all()
    assert _rel(a.K, b.K) < 1e-12
    # C = K^-1 agrees to round-off times the conditioning of the (Jacobi-scaled) K
    for i in np.flatnonzero(b.invertible):
        d = np.sqrt(np.diagonal(b.K[i]))
        lo = np.linalg.eigvalsh(b.K[i] / d[:, None] / d[None, :])[0]
        assert _rel(a.C[i:i + 1], b.C[i:i + 1]) < 1e-14 / lo
    assert np.isinf(a.k_tran[~a.invertible]).all()


def test_kernel_choice(monkeypatch):
    """auto: the kernels from KERNEL_FROM poses; the environment switch and the argument."""
    monkeypatch.delenv(stiffness.KERNEL_ENV, raising=False)
    assert not stiffness.use_kernel(stiffness.KERNEL_FROM - 1)
    assert stiffness.use_kernel(stiffness.KERNEL_FROM)
    assert stiffness.use_kernel(1, "numba") and not stiffness.use_kernel(10 ** 6, "numpy")
    monkeypatch.setenv(stiffness.KERNEL_ENV, "numpy")
    assert not stiffness.use_kernel(10 ** 6)
    assert stiffness.use_kernel(10 ** 6, "auto")
    monkeypatch.setenv(stiffness.KERNEL_ENV, "fast")
    with pytest.raises(ValueError, match=stiffness.KERNEL_ENV):
        stiffness.use_kernel(10)


def test_single_pose_does_not_load_the_kernel(tmp_path):
    """`vjm stiffness --at` (and Model.stiffness) stay on the numpy path: vjm.maps.map_kernel is not
    imported, so no compile or cache load is paid; a large map does import it."""
    code = (
        "import sys\n"
        "from typer.testing import CliRunner\n"
        "from vjm.cli import app\n"
        f"r = CliRunner().invoke(app, ['stiffness', {PUU!r}, '--at', '0,0,0'])\n"
        "assert r.exit_code == 0, r.output\n"
        "assert 'vjm.maps.map_kernel' not in sys.modules\n"
        "import numpy as np, vjm\n"
        f"m = vjm.load_model({PUU!r})\n"
        "m.stiffness(np.zeros(3))\n"
        "assert 'vjm.maps.map_kernel' not in sys.modules\n"
        "m.stiffness_map(np.zeros((300, 3)))\n"
        "print('vjm.maps.map_kernel' in sys.modules)\n"
    )
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    env.pop(stiffness.KERNEL_ENV, None)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().splitlines()[-1] == "True"


def test_kernel_per_pose_compliances():
    """Springs whose compliance changes per pose, (n, 6, 6) and (n, 1, 1), beside constant ones:
    the packing of the kernels' compliance buffer against chain_stiffness_frames and assemble_soa."""
    m = vjm.load_model(PUU)
    rng = np.random.default_rng(7)
    P = rng.uniform(-40.0, 40.0, (203, 3))
    kin = m.kinematics(P)
    comps = []
    for c in m.compliances(kin):
        c = dict(c)
        B = rng.normal(size=(len(P), 6, 6))
        c["leg"] = np.asarray(c["leg"]) * (1.0 + 0.1 * rng.random((len(P), 1, 1))) + 1e-8 * B @ B.transpose(0, 2, 1)
        c["actuator"] = np.full((len(P), 1, 1), 1e-4) * (1.0 + rng.random((len(P), 1, 1)))
        comps.append(c)
    n = len(P)
    out = (np.empty((n, 6, 6)), np.empty((n, 6, 6)), np.empty(n), np.empty(n), np.empty(n, dtype=int),
           np.empty(n, dtype=bool), np.empty((n, 3), dtype=int))
    gaps = []
    stiffness.machine_block_compiled(kin.chains, kin.values, comps, kin.points, out, lambda k, g: gaps.append(g))
    Ks = sum(stiffness.chain_stiffness_frames(ch, np.ascontiguousarray(v.T), c)[0]
             for ch, v, c in zip(kin.chains, kin.values, comps))
    C, rank, inv, kt, kr = stiffness.assemble_soa(Ks)
    assert _rel(out[0], Ks.transpose(2, 0, 1)) < 1e-12
    assert _rel(out[1], C.transpose(2, 0, 1)) < 1e-12
    assert _rel(out[2], kt) < 1e-12 and _rel(out[3], kr) < 1e-12
    assert out[4].tolist() == rank.tolist() and out[5].all() and inv.all()
    assert len(gaps) == 3 and max(gaps) < 1e-9


def test_kernel_chains_of_different_structure():
    """One block kernel call over chains of different shapes (the 3-PUU's, 17 variables and 4 passive
    joints, beside the 3-PRPaR's, 16 and 3 with a per-pose parallelogram spring), at the same
    points: the concatenated chain, spring and compliance arrays against chain_stiffness_frames and
    assemble_soa chain by chain."""
    a, b = vjm.load_model(PUU), vjm.load_model("data/orthoglide/prpar.yaml")
    P = np.random.default_rng(11).uniform(-40.0, 40.0, (37, 3))
    ka, kb = a.kinematics(P), b.kinematics(P)
    chains = (kb.chains[0],) + ka.chains + kb.chains[1:]
    values = (kb.values[0],) + ka.values + kb.values[1:]
    ca, cb = a.compliances(ka), b.compliances(kb)
    comps = [cb[0]] + ca + cb[1:]
    n = len(P)
    out = (np.empty((n, 6, 6)), np.empty((n, 6, 6)), np.empty(n), np.empty(n), np.empty(n, dtype=int),
           np.empty(n, dtype=bool), np.empty((n, len(chains)), dtype=int))
    gaps = []
    stiffness.machine_block_compiled(chains, values, comps, P, out, lambda k, g: gaps.append(g))
    Ks = sum(stiffness.chain_stiffness_frames(ch, np.ascontiguousarray(v.T), c)[0]
             for ch, v, c in zip(chains, values, comps))
    C, rank, inv, kt, kr = stiffness.assemble_soa(Ks)
    assert _rel(out[0], Ks.transpose(2, 0, 1)) < 1e-12
    assert _rel(out[1], C.transpose(2, 0, 1)) < 1e-12
    assert _rel(out[2], kt) < 1e-12 and _rel(out[3], kr) < 1e-12
    assert out[4].tolist() == rank.tolist() and out[5].tolist() == inv.tolist()
    assert out[6][0].tolist() == [3, 4, 4, 4, 3, 3]
    assert len(gaps) == 6 and max(gaps) < 1e-9
