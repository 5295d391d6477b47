"""Independent check of a link compliance with CalculiX (ccx) on the same P2 mesh.

The P2 mesh of :mod:`linkfea.fem.problem` is written as C3D10 elements (the local
node order -- 4 vertices, then edges 1-2, 2-3, 3-1, 1-4, 2-4, 3-4 -- is the
one :func:`linkfea.fem.p2.p2_mesh` uses, so connectivity is copied as is, 1-based).
The same nodes are clamped and, in rigid mode, the same nodes are tied by
``*RIGID BODY, REF NODE=..., ROT NODE=...`` to a reference node at the frame
origin.  One ``*STEP`` per unit load applies the force on the REF NODE and
the moment on the ROT NODE (CalculiX: its translational DOFs are the rotation
vector components), with components rotated from frame to CAD axes.

In block mode the block elements get ``E * block_ratio`` and the same
minimum-norm nodal forces as :func:`linkfea.fem.problem.solve_link`; the twist is then
fitted to the printed block-node displacements.
"""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np

from linkfea.fem.fit import fit_rigid_motion
from linkfea.fem.p2 import link_p2
from linkfea.fem.problem import interface_nodes
from linkfea.mechanics.frames import rigid_motion_matrix
from linkfea.mechanics.materials import Material
from linkfea.runtime.errors import LinkFeaError, SolverError

# ccx/Abaqus C3D10 corner-then-edge order equals ours: an identity map kept explicit.
C3D10_ORDER = np.arange(10)


@dataclass(frozen=True)
class CalculixResult:
    """Compliance computed by CalculiX.

    Attributes
    ----------
    compliance : ndarray (6, 6)
        Raw (unsymmetrized) compliance in the mesh frame, at its origin.
    wall_time : float
        Seconds spent in ``ccx``.
    n_nodes : int
        Number of nodes written (P2 nodes plus the reference nodes).
    fit_residual : float
        Largest relative rigid-fit residual (block mode; 0 in rigid mode).
    peak_memory_mb : float
        Largest resident memory of the ccx process seen (Linux ``VmHWM``; 0 if unknown).
    """

    compliance: np.ndarray
    wall_time: float
    n_nodes: int
    fit_residual: float = 0.0
    peak_memory_mb: float = 0.0


def _vm_hwm_mb(pid: int) -> float:
    """Peak resident memory of a running process in MB (Linux /proc), 0 if unavailable."""
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return float(line.split()[1]) / 1024.0
    except OSError:
        pass
    return 0.0


# CalculiX reads numeric fields of at most 20 characters: "%.13e" fits any double.
def _fmt_rows(rows, per_line=8):
    """Integer lists as CalculiX data lines (at most 16 entries, short lines)."""
    rows = np.asarray(rows).ravel()
    return "\n".join(", ".join(str(int(v)) for v in rows[i:i + per_line]) for i in range(0, len(rows), per_line))


def write_inp(path, mesh, material: Material, mode: str = "rigid", block_ratio: float = 1000.0) -> dict:
    """Write the CalculiX input deck of the 6 unit-load cases.

    Returns
    -------
    dict
        ``ref`` and ``rot`` node numbers (1-based, rigid mode), the ``ref_nodes``
        (0-based P2 indices) and the P2 ``points``.
    """
    p2 = link_p2(mesh)
    clamped, ref_nodes = interface_nodes(p2, mesh, mode)
    block = np.asarray(mesh.block, dtype=bool)
    frame = mesh.frame
    R = frame.axes.T  # CAD <- frame
    n = len(p2.points)
    ref_id, rot_id = n + 1, n + 2
    out = ["*HEADING", "linkfea unit-load cases, units N mm MPa", "*NODE, NSET=NALL"]
    ids = np.arange(1, n + 1)
    out.extend(f"{i}, {x:.13e}, {y:.13e}, {z:.13e}" for i, (x, y, z) in zip(ids, p2.points))
    if mode == "rigid":
        o = frame.origin
        out.append(f"{ref_id}, {o[0]:.13e}, {o[1]:.13e}, {o[2]:.13e}")
        out.append(f"{rot_id}, {o[0]:.13e}, {o[1]:.13e}, {o[2]:.13e}")
    conn = p2.cells[:, C3D10_ORDER] + 1
    eids = np.arange(1, len(conn) + 1)
    sets = [("EBODY", ~block if mode == "block" else np.ones(len(block), bool))]
    if mode == "block":
        sets.append(("EBLOCK", block))
    for name, mask in sets:
        if not mask.any():
            continue
        out.append(f"*ELEMENT, TYPE=C3D10, ELSET={name}")
        out.extend(f"{e}, " + ", ".join(str(v) for v in c) for e, c in zip(eids[mask], conn[mask]))
    out += ["*NSET, NSET=NCLAMP", _fmt_rows(clamped + 1)]
    out += ["*NSET, NSET=NCOUP", _fmt_rows(ref_nodes + 1)]
    out += ["*MATERIAL, NAME=MBODY", "*ELASTIC", f"{material.E:.13e}, {material.nu:.13e}",
            "*SOLID SECTION, ELSET=EBODY, MATERIAL=MBODY"]
    if mode == "block" and block.any():
        out += ["*MATERIAL, NAME=MBLOCK", "*ELASTIC", f"{material.E * block_ratio:.13e}, {material.nu:.13e}",
                "*SOLID SECTION, ELSET=EBLOCK, MATERIAL=MBLOCK"]
    out += ["*BOUNDARY", "NCLAMP, 1, 3"]
    if mode == "rigid":
        out += [f"*RIGID BODY, NSET=NCOUP, REF NODE={ref_id}, ROT NODE={rot_id}",
                "*NSET, NSET=NREF", f"{ref_id}, {rot_id}"]
    else:
        Rm = rigid_motion_matrix(p2.points[ref_nodes], frame.origin, frame.axes).reshape(-1, 6)
        F = (Rm @ np.linalg.solve(Rm.T @ Rm, np.eye(6))).reshape(len(ref_nodes), 3, 6)
    for k in range(6):
        out += ["*STEP", "*STATIC", "*CLOAD, OP=NEW"]
        if mode == "rigid":
            vec = R[:, k % 3]  # unit force (k < 3) or moment (k >= 3) along frame axis k % 3, in CAD components
            node = ref_id if k < 3 else rot_id
            out.extend(f"{node}, {c + 1}, {vec[c]:.13e}" for c in range(3) if vec[c] != 0.0)
            out += ["*NODE PRINT, NSET=NREF", "U"]
        else:
            for nid, f in zip(ref_nodes + 1, F[:, :, k]):
                out.extend(f"{nid}, {c + 1}, {f[c]:.13e}" for c in range(3) if f[c] != 0.0)
            out += ["*NODE PRINT, NSET=NCOUP", "U"]
        out.append("*END STEP")
    tmp = Path(str(path) + ".part")
    tmp.write_text("\n".join(out) + "\n")
    os.replace(tmp, path)
    return {"ref": ref_id, "rot": rot_id, "ref_nodes": ref_nodes, "points": p2.points}


_NUM = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[EeDd][-+]?\d+)?"
_ROW = re.compile(rf"^\s*(\d+)\s+({_NUM})\s+({_NUM})\s+({_NUM})\s*$")


def parse_dat_displacements(text: str) -> list[dict]:
    """Displacement blocks of a ccx ``.dat`` file, in order: one ``{node: (ux, uy, uz)}`` per block."""
    blocks = []
    current = None
    for line in text.splitlines():
        if line.strip().startswith("displacements"):
            current = {}
            blocks.append(current)
            continue
        if current is None:
            continue
        m = _ROW.match(line)
        if m:
            current[int(m.group(1))] = tuple(float(v.replace("D", "E").replace("d", "e")) for v in m.groups()[1:])
        elif line.strip() and current:
            current = None
    return blocks


def solve_calculix(mesh, material: Material, mode: str = "rigid", block_ratio: float = 1000.0,
                   ccx: Optional[str] = None, workdir=None, threads: Optional[int] = None) -> CalculixResult:
    """Compliance of a link by CalculiX on the same P2 mesh (C3D10).

    Parameters
    ----------
    mesh : linkfea.mesh.linkmesh.LinkMesh
    material : Material
    mode : {"rigid", "block"}
    block_ratio : float
    ccx : str, optional
        Executable (default: ``ccx`` on the PATH).
    workdir : path, optional
        Where to run (default: a temporary directory, removed afterwards).
    threads : int, optional
        Solver threads for ccx (``OMP_NUM_THREADS``, ``CCX_NPROC_EQUATION_SOLVER``).

    Returns
    -------
    CalculixResult
    """
    exe = ccx or shutil.which("ccx")
    if exe is None:
        raise LinkFeaError("CalculiX (ccx) not installed: install Debian package calculix-ccx")
    own_dir = workdir is None
    wd = Path(tempfile.mkdtemp(prefix="linkfea_ccx_")) if own_dir else Path(workdir)
    try:
        info = write_inp(wd / "link.inp", mesh, material, mode, block_ratio)
        env = dict(os.environ)
        if threads:
            env["OMP_NUM_THREADS"] = env["CCX_NPROC_EQUATION_SOLVER"] = str(threads)
        t0 = time.perf_counter()
        with open(wd / "ccx.log", "w") as log:
            proc = subprocess.Popen([exe, "-i", "link"], cwd=wd, env=env, stdout=log, stderr=subprocess.STDOUT)
            peak = 0.0
            while proc.poll() is None:  # sample ccx's high-water mark of resident memory
                peak = max(peak, _vm_hwm_mb(proc.pid))
                time.sleep(0.05)
        wall = time.perf_counter() - t0
        dat = wd / "link.dat"
        if proc.returncode != 0 or not dat.exists():
            tail = (wd / "ccx.log").read_text(errors="replace").strip().splitlines()[-5:]
            raise SolverError(f"CalculiX failed (exit {proc.returncode}): {' | '.join(tail)}")
        blocks = parse_dat_displacements(dat.read_text())
        if len(blocks) != 6:
            raise SolverError(f"CalculiX .dat has {len(blocks)} displacement blocks, expected 6")
        axes = mesh.frame.axes
        C = np.zeros((6, 6))
        res = 0.0
        if mode == "rigid":
            for k, b in enumerate(blocks):
                C[:3, k] = axes @ np.array(b[info["ref"]])
                C[3:, k] = axes @ np.array(b[info["rot"]])
        else:
            ids = info["ref_nodes"] + 1
            u = np.array([[b[i] for i in ids] for b in blocks])  # (6, n, 3)
            tw, r = fit_rigid_motion(info["points"][info["ref_nodes"]], u, mesh.frame.origin, axes)
            C = tw.T
            res = float(np.max(r))
        return CalculixResult(C, wall, len(info["points"]) + (2 if mode == "rigid" else 0), res, peak)
    finally:
        if own_dir:
            shutil.rmtree(wd, ignore_errors=True)  # own file: the mkdtemp folder made above
