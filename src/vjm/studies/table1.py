"""The seed's Table 1 (Orthoglide 3-PUU and 3-PRPaR at Q0, Q1, Q2) beside our k_tran and k_rot.

k_tran is in mm/N and k_rot in rad/(N mm), as in the seed table file
(``data/seed_table1.csv``, columns ``k_tran_mm_per_N`` and ``k_rot_rad_per_Nmm``).

>>> import vjm
>>> rows = table1_rows([vjm.load_model("puu")])
>>> [r["point"] for r in rows], rows[0]["seed_k_tran"]
(['Q0', 'Q1', 'Q2'], 0.000278)
>>> round(rows[0]["k_tran"] / rows[0]["seed_k_tran"], 2)   # the actuator stiffness is fitted to Q0
1.0
"""
from __future__ import annotations

import csv
import os

import numpy as np

from ..errors import VjmError
from ..resources import seed_table

#: the architectures of Table 1, in the order the ``vjm table1`` command takes their models
ARCHITECTURES = ("orthoglide-3PUU", "orthoglide-3PRPaR")


def read_seed_table(path=None) -> list[dict]:
    """Rows of the seed table (architecture, point, x, y, z, k_tran_mm_per_N, k_rot_rad_per_Nmm)."""
    path = seed_table() if path is None else path
    if not os.path.isfile(path):
        raise VjmError(f"seed table not found: {path}")
    with open(path, encoding="utf-8") as fh:
        rows = [r for r in csv.DictReader(line for line in fh if not line.startswith("#"))]
    return rows


def check_order(models, paths) -> None:
    """The models are a 3-PUU then a 3-PRPaR (``paths`` name them in the error)."""
    for m, arch, path in zip(models, ARCHITECTURES, paths):
        if m.architecture != arch:
            raise VjmError(f"{path} is a {m.architecture} model; table1 takes the 3-PUU model first, "
                           f"then the 3-PRPaR")


def table1_rows(models) -> list[dict]:
    """Our k_tran/k_rot at the seed's points next to the seed's values, for each model, with their
    spread from the links' FEA error bars (``k_tran_spread``, ``k_rot_spread``, :mod:`vjm.sweep.spread`;
    zero when no link carries an error estimate)."""
    seed = read_seed_table()
    out = []
    for m in models:
        rows = [r for r in seed if r["architecture"] == m.architecture]
        if not rows:
            raise VjmError(f"the seed's Table 1 has no {m.architecture}")
        P = np.array([[float(r["x"]), float(r["y"]), float(r["z"])] for r in rows])
        res = m.stiffness_map(P, spread=True)
        for r, kt, kr, dt, dr in zip(rows, res.k_tran, res.k_rot, res.k_tran_spread, res.k_rot_spread):
            st, sr = float(r["k_tran_mm_per_N"]), float(r["k_rot_rad_per_Nmm"])
            out.append(dict(architecture=m.architecture, point=r["point"], seed_k_tran=st, k_tran=float(kt),
                            seed_k_rot=sr, k_rot=float(kr), k_tran_spread=float(dt), k_rot_spread=float(dr)))
    return out


def describe_link(link) -> str:
    """``rigid``, ``beam ...``, ``linkfea FILE`` or ``inline compliance``: where a link's compliance comes from."""
    s = link.source or {}
    if link.compliance is None:
        return "rigid"
    if "beam" in s:
        b = s["beam"]
        return "beam " + " ".join(f"{k}={v}" for k, v in b.items())
    if "linkfea" in s:
        bar = "" if link.error is None else f" (FEA error bar up to {100 * float(max(link.error)):.2g}%)"
        return f"linkfea {os.path.basename(s['linkfea'])}{bar}"
    return "inline compliance"


def _ours(value: float, spread: float, bars: bool) -> str:
    """``2.83`` or, when a link carries an error bar, ``2.83+-0.052`` (one word: columns stay split by blanks)."""
    return f"{value:.3g}+-{spread:.2g}" if bars else f"{value:.3g}"


def report_lines(rows: list[dict], models) -> list[str]:
    """The table as text (k_tran in 1e-4 mm/N, k_rot in 1e-7 rad/(N mm), ratio ours/seed) and the models used.

    When a link carries an FEA error bar, "ours" reads ``value+-spread`` (:mod:`vjm.sweep.spread`)."""
    bars = any(link.error is not None for m in models for link in m.links.values())
    w = 18 if bars else 12
    lines = ["k_tran [1e-4 mm/N] and k_rot [1e-7 rad/(N mm)]: ours vs seed Table 1 (ratio ours/seed)",
             f"{'architecture':<19}{'pt':<4}{'k_tran ours':>{w}}{'seed':>8}{'ratio':>7}"
             f"{'k_rot ours':>{w}}{'seed':>8}{'ratio':>7}"]
    for r in rows:
        kt = _ours(r["k_tran"] * 1e4, r.get("k_tran_spread", 0.0) * 1e4, bars)
        kr = _ours(r["k_rot"] * 1e7, r.get("k_rot_spread", 0.0) * 1e7, bars)
        lines.append(f"{r['architecture']:<19}{r['point']:<4}{kt:>{w}}{r['seed_k_tran'] * 1e4:>8.3g}"
                     f"{r['k_tran'] / r['seed_k_tran']:>7.2f}{kr:>{w}}{r['seed_k_rot'] * 1e7:>8.3g}"
                     f"{r['k_rot'] / r['seed_k_rot']:>7.2f}")
    for m in models:
        a = m.actuator
        lines.append(f"{m.architecture}: L={m.geometry.get('L')} r={m.geometry.get('r')} d={m.geometry.get('d')} mm, "
                     f"actuator {a.stiffness:g} N/mm, foot {describe_link(m.foot)}, leg {describe_link(m.leg)}")
    if bars:
        lines.append("+-: the spread of ours when every FEA link's compliance moves within its error bar (linear "
                     "sensitivity, links added in magnitude; beam and inline links contribute none). The FEA "
                     "compliance is too small, so the true value most likely lies on the + side.")
    else:
        lines.append("No link carries an FEA error estimate (beam, inline or rigid links): no error bar to carry.")
    lines.append("The seed publishes neither link sections nor actuator stiffness: ours are chosen (docs/table1.md);"
                 " the actuator is set so that k_tran(Q0) matches with the default beam links.")
    return lines
