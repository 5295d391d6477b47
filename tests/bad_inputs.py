"""The bad-input table: every bad input tried on ``linkfea`` and ``vjm``, and what it must get.

One :class:`Case` per line of :data:`CASES`: the command line, the files it needs (made on the fly in an
empty folder, the command's working directory) and a fragment of the one ``error:`` line expected.  Every
case must exit with status 2, print exactly one ``error:`` line on stderr and no traceback, repeat no
phrase, and leave the folder as it was.  ``tests/test_bad_inputs.py`` checks them; ``docs/tools/
bad_inputs_table.py`` writes ``docs/bad_inputs.md`` from the same list.

Placeholders in the command: ``{puu}``, ``{prpar}``, ``{delta}``, ``{linear}``, ``{hexapod}`` (bundled model
files).
Adding a case is one line: ``Case("18.x", "vjm ... --flag value", "fragment", {"file.csv": TEXT})``.
A file name may hold a folder (``rep/report.json``); ``links`` makes symbolic links (name -> target).
"""
from __future__ import annotations

import contextlib
import hashlib
import io
import json
import os
import shlex
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PLACES = {"puu": ROOT / "data/orthoglide/puu.yaml", "prpar": ROOT / "data/orthoglide/prpar.yaml",
          "delta": ROOT / "data/orthoglide/delta.yaml", "linear": ROOT / "data/machines/linear_delta.yaml",
          "hexapod": ROOT / "data/machines/hexapod_6ups.yaml", "ur10": ROOT / "data/robots/ur10/ur10.yaml"}


@dataclass(frozen=True)
class Case:
    issue: str      # where the case comes from (issue.item)
    command: str    # "linkfea ..." or "vjm ...", with {puu}-style placeholders
    expect: str     # a fragment of the error line
    files: dict = field(default_factory=dict)  # name -> text written before the run ("encoding": its codec)
    note: str = ""  # what the files hold, for the table (default: their first lines)
    links: dict = field(default_factory=dict)  # name -> target of a symbolic link made before the run
    number: int = 0  # the row's number in docs/bad_inputs.md (0: the one after the previous row's)

    @property
    def argv(self) -> list[str]:
        return shlex.split(self.command.format(**{k: str(v) for k, v in PLACES.items()}))


@dataclass(frozen=True)
class Outcome:
    status: int
    stderr: str
    stdout: str
    changed: list  # files created, changed or removed in the folder


# ------------------------------------------------------------------ files the cases use

HDR = "x,y,z,Fx,Fy,Fz,Mx,My,Mz,dx,dy,dz,rx,ry,rz"


def _rows(scale_t=1.0, scale_r=1.0, rotations=False) -> list[str]:
    """Deflections of the 3-PUU at its isotropic posture under 100 N along each axis (and 10 N m about
    each axis with ``rotations``), computed with the bundled model: measured in mm and rad, times the scales."""
    import numpy as np

    import vjm

    C = vjm.load_model(PLACES["puu"]).stiffness([0.0, 0.0, 0.0]).C
    loads = [100.0 * e for e in np.eye(6)[:3]] + ([1e4 * e for e in np.eye(6)[3:]] if rotations else [])
    out = []
    for w in loads:
        t = np.round(C @ w, 12) + 0.0  # no round-off dust (6e-18) in the table
        rot = ",".join(f"{scale_r * v:.6g}" for v in t[3:]) if rotations else ",,"
        out.append("0,0,0," + ",".join(f"{v:g}" for v in w) + "," + ",".join(f"{scale_t * v:.6g}" for v in t[:3])
                   + "," + rot)
    return out


ROWS = _rows()
GOOD = "\n".join([HDR] + ROWS) + "\n"
MICRONS = "\n".join([HDR] + _rows(scale_t=1000.0)) + "\n"          # translations in µm
DEGREES = "\n".join([HDR] + _rows(rotations=True, scale_r=180 / 3.141592653589793)) + "\n"  # rotations in degrees


def _csv(header_extra="", row_extra="", rows=ROWS):
    return "\n".join([HDR + header_extra] + [r + row_extra for r in rows]) + "\n"


def _model(**changes) -> str:
    """puu.yaml with top-level keys replaced (YAML text)."""
    import yaml

    with open(PLACES["puu"], encoding="utf-8") as fh:
        d = yaml.safe_load(fh)
    d.update(changes)
    return yaml.safe_dump(d, sort_keys=False)


def _linear(old: str, new: str) -> str:
    text = PLACES["linear"].read_text(encoding="utf-8")
    assert old in text
    return text.replace(old, new)


C_DIAG = [1e-4, 1e-4, 2e-4, 1e-7, 1e-7, 2e-7]


def _result(**changes) -> str:
    """A linkfea result document (diagonal compliance), with keys replaced or removed (value None)."""
    import numpy as np

    doc = {"schema": "linkfea.result/1", "compliance": np.diag(C_DIAG).tolist(),
           "stiffness": np.diag(1 / np.array(C_DIAG)).tolist(),
           "frame": {"origin": [0, 0, 0], "x_axis": [1, 0, 0], "y_axis": [0, 1, 0], "z_axis": [0, 0, 1]},
           "units": {"compliance": "mm/N, rad/(N mm)"}}
    doc.update(changes)
    return json.dumps({k: v for k, v in doc.items() if v is not None})


#: a machine description whose chains leave the platform no motion (mobility 0)
LOCKED = """name: three sliders
geometry: {}
actuator: {stiffness: 1000.0}
platform: {dof: 3, seed: [0, 0, 0], workspace: [[-10, -10, -10], [10, 10, 10]]}
chains:
  - {name: cx, transforms: [Tx(q0) actuated]}
  - {name: cy, transforms: [Ty(q0) actuated]}
  - {name: cz, transforms: [Tz(q0) actuated]}
"""



def _box(lo, hi) -> list:
    """The 12 outward triangles of the box from ``lo`` to ``hi`` (mm)."""
    v = [(x, y, z) for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return [t for a, b, c, d in quads for t in ((v[a], v[b], v[c]), (v[a], v[c], v[d]))]


def stl(triangles) -> str:
    """An ASCII STL of the triangles (each three (x, y, z) corners)."""
    facets = "".join("facet normal 0 0 0\n outer loop\n" + "".join(f"  vertex {p[0]} {p[1]} {p[2]}\n" for p in t)
                     + " endloop\nendfacet\n" for t in triangles)
    return f"solid s\n{facets}endsolid s\n"


BAR = _box((0, 0, 0), (100, 20, 10))
#: a flat square closed by four triangles in the plane z = 0 (watertight, no volume)
FLAT = [((0, 0, 0), (100, 0, 0), (100, 20, 0)), ((0, 0, 0), (100, 20, 0), (0, 20, 0)),
        ((0, 0, 0), (0, 20, 0), (100, 0, 0)), ((100, 0, 0), (0, 20, 0), (100, 20, 0))]
STL = "linkfea compute s.stl --base plane:x=0 --tip plane:x=100 --out o/r.json"


def _sha(text: str) -> str:
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def _report_folder(edited: str) -> dict:
    """A report folder of `vjm diagnose --suggest` whose manifest records the files as written, with
    ``edited`` (one of them) changed by the user since."""
    written = {"model_updated.yaml": "# vjm model file.\nname: as written\n", "next_measurements.csv": "x,y,z\n0,0,0\n"}
    man = {"schema": "linkfea.outputs/1", "sets": {"vjm diagnose": {"files": {n: _sha(t) for n, t in written.items()},
                                                                    "run": "0" * 32}}}
    files = {f"rep/{n}": t + ("# my edit\n" if n == edited else "") for n, t in written.items()}
    return {"m.csv": GOOD, "rep/.linkfea-outputs.json": json.dumps(man), **files}

#: a link script whose build() runs ``body`` (line 4)
SCRIPT = "PARAMS = {{}}\n\ndef build(**p):\n{body}\n"
LINE_NC = "G21 G90\nG0 X0 Y0 Z0\nG1 X100 F100\n"
#: nine levels of ten aliases of the level below (a "billion laughs")
LAUGHS = "laughs:\n  a0: &a0 [1, 1, 1, 1, 1, 1, 1, 1, 1, 1]\n" + "".join(
    f"  a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * 10)}]\n" for i in range(1, 9))

# ------------------------------------------------------------------ the cases
D = "vjm diagnose {puu} m.csv --out rep"
S = "vjm simulate {puu} --out s.csv"
HD = "vjm diagnose {hexapod} m.csv --out rep"
HEX_HDR = "x,y,z,ox,oy,oz,Fx,Fy,Fz,Mx,My,Mz,dx,dy,dz,rx,ry,rz"

# ------------------------------------------------------------------ robots (issue 26)

def _urdf(joints: str, links=("base", "l1", "l2"), inertial='<inertial><mass value="2"/><origin xyz="0.1 0 0"/>'
          '<inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial>') -> str:
    body = "".join(f'<link name="{n}">{inertial if n != "base" else ""}</link>' for n in links)
    return f'<?xml version="1.0"?><robot name="r">{body}{joints}</robot>\n'


def _joint(name, parent, child, jtype="revolute", axis="0 0 1"):
    lim = '<limit lower="-2" upper="2" effort="1" velocity="1"/>' if jtype in ("revolute", "prismatic") else ""
    return (f'<joint name="{name}" type="{jtype}"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="0 0 0.3"/><axis xyz="{axis}"/>{lim}</joint>')


ARM = _urdf(_joint("j1", "base", "l1") + _joint("j2", "l1", "l2"))
ROBOT = "urdf: r.urdf\njoints: {j1: {stiffness: 1.0e+8}, j2: {stiffness: 5.0e+7}}\n"

POSES = "j1,j2,l2.x,l2.y,l2.z\n" + "".join(f"{0.1 * k:.2f},{-0.05 * k:.3f},{k},{2 * k},{600 + k}\n" for k in range(40))
CAL_FILES = {"r.yaml": ROBOT, "r.urdf": ARM, "p.csv": POSES}
#: the poses in two registration groups, a and b (38.5)
GROUPED = "j1,j2,l2.x,l2.y,l2.z,group\n" + "".join(f"{r},{'ab'[k % 2]}\n" for k, r in enumerate(POSES.splitlines()[1:]))
#: a commands.csv of vjm compensate with a row added since (its sha256 no longer the one its first line records)
EDITED_COMMANDS = ("# commands by vjm compensate from ur10.yaml; targets t.csv; sha256 " + "0" * 64 + "\ntarget,status\n"
                   "1,ok\n2,ok\n")
#: a calibration's output folder whose calibrated.yaml (in its manifest) is the model of the next run into it
READ_FROM_OUT = {"o/calibrated.yaml": ROBOT, "o/r.urdf": ARM, "p.csv": POSES, "o/.linkfea-outputs.json": json.dumps(
    {"schema": "linkfea.outputs/1", "sets": {"vjm calibrate": {"files": {
        "calibrated.yaml": hashlib.sha256(ROBOT.encode()).hexdigest()}, "run": "0"}}})}
#: two measured points per row, l1 and l2 (27.2)
TWO_POINTS = "j1,j2,l1.x,l1.y,l1.z,l2.x,l2.y,l2.z\n" + "".join(
    f"{0.1 * k:.2f},{-0.05 * k:.3f},{k},{-k},{300 + k},{k},{2 * k},{600 + k}\n" for k in range(40))
#: a hexapod's absolute poses: its six strut lengths (near the home pose's 598 mm) and the platform's point (27.1)
HEX_POSES = ("A1.l,A2.l,A3.l,B1.l,B2.l,B3.l,platform.x,platform.y,platform.z\n" + "".join(
    ",".join([f"{598 + 0.5 * ((k + i) % 7):.2f}" for i in range(6)] + [f"{k}", f"{-k}", f"{550 + k}"]) + "\n"
    for k in range(40)))


# ------------------------------------------------------------------ units, ranges and malformed URDFs (issue 40)

#: the two-joint arm with its joints off the z axis: the point l2 moves with j1 (a circle of radius 300 mm)
#: a design spec of the 3-PUU's leg bar: {free} its free parameters, {rest} more top-level lines
DESIGN = ("machine: " + str(PLACES["puu"]) + "\nlinks:\n  leg:\n    cad: parallelogram_bar\n    fixed: {{boss_height: 20}}\n"
          "    free: {free}\nconstraints: {{k_tran_max: 0.015}}\n{rest}")
#: a design spec of the 3-PUU's leg as a beam: {beam} its mapping, {free} its free dimensions
BEAM_DESIGN = ("machine: " + str(PLACES["puu"]) + "\nlinks:\n  leg:\n    beam: {beam}\n    free: {free}\n"
               "constraints: {{k_tran_max: 0.015}}\n")
ARM_X = ARM.replace('<origin xyz="0 0 0.3"/>', '<origin xyz="0.3 0 0.1"/>')


def _arm_poses(q_scale=1.0, p_scale=1.0, rows=40, header="j1,j2,l2.x,l2.y,l2.z", extra="") -> str:
    """Poses of ARM_X measured exactly (mm, rad), the joints times ``q_scale``, the points times ``p_scale``."""
    import math

    out = [header]
    for k in range(rows):
        q1, q2 = -1.5 + 0.075 * k, -1.0 + 0.05 * k
        p = (1000 + 300 + 300 * math.cos(q1), 300 * math.sin(q1), 200.0)
        out.append(",".join([f"{q_scale * q1:.6g}", f"{q_scale * q2:.6g}"] + [f"{p_scale * v:.6g}" for v in p]) + extra)
    return "\n".join(out) + "\n"


X_FILES = {"r.yaml": ROBOT, "r.urdf": ARM_X, "p.csv": _arm_poses()}
#: ARM_X as a model file with other keys, for the model-file checks
def _xrobot(extra: str, urdf: str = ARM_X) -> dict:
    return {"r.yaml": ROBOT + extra, "r.urdf": urdf}


#: the Puma 560's first rows as a DH table, its lengths in metres
DH_METRES = """name: puma
dh:
  joints:
    - {name: a1, a: 0, alpha: pi/2, d: 0.6604}
    - {name: a2, a: 0.4318, alpha: 0, d: 0.14909}
    - {name: a3, a: 0.0203, alpha: -pi/2, d: 0}
"""
TARGET = "x,y,z\n884,164,436\n"

CASES = [
    # 18.2: numeric options, vjm
    Case("18.2", D + " --alpha 0", "--alpha must be in (0, 1), got 0", {"m.csv": GOOD}),
    Case("18.2", D + " --alpha -1", "--alpha must be in (0, 1), got -1", {"m.csv": GOOD}),
    Case("18.2", D + " --alpha nan", "--alpha must be a finite number in (0, 1), got nan", {"m.csv": GOOD}),
    Case("18.2", D + " --alpha 2", "--alpha must be in (0, 1), got 2", {"m.csv": GOOD}),
    Case("18.2", D + " --alpha 1", "--alpha must be in (0, 1), got 1", {"m.csv": GOOD}),
    Case("18.2", D + " --alpha abc", "Invalid value for '--alpha'", {"m.csv": GOOD}),
    Case("18.2", D + " --suggest -1", "'--suggest'", {"m.csv": GOOD}),
    Case("18.2", "vjm stiffness {puu} --at nan,0,0", "--at expects finite numbers"),
    Case("18.2", "vjm stiffness {puu} --at 1e999,0,0", "--at expects finite numbers"),
    Case("18.2", "vjm map {puu} --grid 1 --out map", "--grid must be a whole number >= 2, got 1"),
    Case("18.2", "vjm map {puu} --grid 2.5 --out map", "Invalid value for '--grid'"),
    Case("18.2", "vjm map {puu} --slice z=nan --out map", "--slice expects axis=value"),
    Case("18.2", "vjm map {puu} --orientation nan,0,0 --out map", "--orientation expects finite numbers"),
    Case("18.2", "vjm sweep {puu} --grid 1 --leg leg.json --out sw", "--grid must be a whole number >= 2, got 1"),
    Case("18.2", S + " --noise-t -1", "--noise-t must be >= 0 mm, got -1"),
    Case("18.2", S + " --noise-t nan", "--noise-t must be a finite number >= 0 mm, got nan"),
    Case("18.2", S + " --noise-r -1e-6", "--noise-r must be >= 0 rad, got -1e-06"),
    Case("18.2", S + " --seed -1", "--seed must be a whole number >= 0, got -1"),
    Case("18.2", S + " --poses grid:0", "--poses grid:0: the count must be a whole number >= 1, got 0"),
    Case("18.2", S + " --poses random:x", "--poses random:x: 'x' is not a whole number"),
    Case("18.2", S + " --loads axes:inf", "--loads axes:inf: 'inf' is not a finite number"),
    Case("18.2", S + " --loads axes:nan", "--loads axes:nan: 'nan' is not a finite number"),
    Case("18.2", S + " --loads random:0:100", "--loads random:0:100: the count must be a whole number >= 1"),
    Case("18.2", S + " --effect gravity:weight=-5", "effect gravity.weight must be >= 0 N, got -5"),
    Case("18.2", S + " --effect gravity:weight=nan", "effect gravity.weight must be a finite number"),
    Case("18.2", S + " --effect gravty:weight=5", "unknown effect 'gravty' (did you mean 'gravity'?)"),
    Case("18.2", S + " --effect clearance:gap=0.01", "unknown parameter 'gap' of clearance; known: backlash"),
    # 18.2: numeric options, linkfea (checked before the CAD is built)
    Case("18.2", "linkfea compute bar --mesh-size 0", "--mesh-size must be > 0 mm, got 0"),
    Case("18.2", "linkfea compute bar --mesh-size -2", "--mesh-size must be > 0 mm, got -2"),
    Case("18.2", "linkfea compute bar --mesh-size nan", "--mesh-size must be a finite number > 0 mm, got nan"),
    Case("18.2", "linkfea compute bar --mesh-size inf", "--mesh-size must be a finite number > 0 mm, got inf"),
    Case("18.2", "linkfea compute bar --mesh-size abc", "Invalid value for '--mesh-size'"),
    Case("18.2", "linkfea compute bar --mode block --block-ratio 0.5", "--block-ratio must be > 1, got 0.5"),
    Case("18.2", "linkfea compute bar --block-ratio nan", "--block-ratio must be a finite number > 1, got nan"),
    Case("18.2", "linkfea compute bar --envelope 0", "--envelope must be in (0, 0.1), got 0"),
    Case("18.2", "linkfea compute bar --envelope 0.5", "--envelope must be in (0, 0.1), got 0.5"),
    Case("18.2", "linkfea compute bar --envelope nan", "--envelope must be a finite number in (0, 0.1), got nan"),
    Case("18.2", "linkfea compare bar --beams 0 --out cmp", "--beams must be > 0 (numbers of beams), got 0"),
    Case("18.2", "linkfea compare bar --beams 1.5 --out cmp", "--beams '1.5' is not an integer"),
    Case("18.2", "linkfea compare bar --mesh-size nan --out cmp", "--mesh-size must be a finite number > 0 mm"),
    Case("18.2", "linkfea sweep bar -p length=100,120 --sample 0 --out sw", "--sample must be a whole number >= 1"),
    Case("18.2", "linkfea sweep bar -p length=100:120 --sample 3 --seed -1 --out sw",
         "--seed must be a whole number >= 0, got -1"),
    Case("18.2", "linkfea sweep bar -p length=100,120 --workers 0 --out sw",
         "--workers must be a whole number >= 1, got 0"),
    Case("18.2", "linkfea sweep bar -p length=100,120 --mesh-size -1 --out sw", "--mesh-size must be > 0 mm, got -1"),
    Case("18.2", "linkfea sweep bar -p length=100,120 --envelope 1 --out sw", "--envelope must be in (0, 0.1), got 1"),
    Case("18.2", "linkfea sweep bar -p length=100,120 --memory-limit abc --out sw",
         "--memory-limit: cannot read 'abc'; use auto, 0 (no limit) or a size such as 4GB"),
    Case("18.2", "linkfea sweep bar -p length=100,120 --memory-limit -4GB --out sw",
         "--memory-limit must be auto, 0 (no limit) or a positive size such as 4GB, got '-4GB'"),
    Case("18.2", "linkfea compute bar --mesh-sise 3", "No such option: --mesh-sise"),
    # 18.3: measurement files
    Case("18.3", D, "column 'temperature': unknown column; known columns: x, y, z,",
         {"m.csv": _csv(",temperature", ",21.5")}),
    Case("18.3", D, "column 'sigm_t': unknown column (did you mean 'sigma_t'?)",
         {"m.csv": _csv(",sigm_t", ",0.001")}),
    Case("18.3", D, "column 'Sigma-r': unknown column (did you mean 'sigma_r'?)",
         {"m.csv": _csv(",Sigma-r", ",1e-6")}),
    Case("18.3", D, "row 3: repeats row 2 exactly", {"m.csv": "\n".join([HDR, ROWS[0], ROWS[0], ROWS[1]]) + "\n"}),
    Case("18.3", D, "the measured translations are 1e+03 x the model's", {"m.csv": MICRONS}),
    Case("18.3", D, "check the units (mm for translations", {"m.csv": MICRONS}),
    Case("18.3", D, "the measured rotations are", {"m.csv": DEGREES}),
    Case("18.3", D, "the file is UTF-16 text; save it as UTF-8", {"m.csv": "\ufeff" + GOOD, "encoding": "utf-16"}),
    Case("18.3", D, "row 1: byte 0xb0 is not UTF-8 text", {"m.csv": HDR.replace("x,", "x°,", 1) + "\n" + ROWS[0],
                                                          "encoding": "latin-1"}),
    Case("18.3", D, "the header is one field", {"m.csv": GOOD.replace(",", "|")}),
    Case("18.3", D, "has 16 fields, header has 15 (malformed CSV; a decimal comma needs ; as the separator)",
         {"m.csv": "\n".join([HDR, "0,0,0,100,0,0,0,0,0,0,028,0,0,,,"]) + "\n"}),
    Case("18.9", D, "row 3, columns 'x,y,z': pose (500, 0, 0) mm is unreachable: the y leg",
         {"m.csv": "\n".join([HDR, ROWS[0], "500,0,0,100,0,0,0,0,0,0.02,0,0,,,", ROWS[1]]) + "\n"}),
    # 18.4: model files and link results
    Case("18.4", "vjm stiffness m.yaml --at 0,0,0", "effects.gravty: unknown effect (did you mean 'gravity'?); the effects written here: gravity,",
         {"m.yaml": _model(effects={"gravty": {"weight": 10.0}})}, "puu.yaml with effects: {gravty: {weight: 10}}"),
    Case("18.4", "vjm stiffness m.yaml --at 0,0,0", "effects.gravity.weight must be in [0, 100000] N, got -10",
         {"m.yaml": _model(effects={"gravity": {"weight": -10.0}})}, "puu.yaml with effects: {gravity: {weight: -10}}"),
    Case("18.4", "vjm stiffness m.yaml --at 0,0,0", "effects.clearance.backlash must be in [0, 1] mm, got 50",
         {"m.yaml": _model(effects={"clearance": {"backlash": 50.0}})}, "puu.yaml with effects: {clearance: {backlash: 50}}"),
    Case("18.4", "vjm stiffness m.yaml --at 0,0,0", "effects.clearance: unknown parameter 'gap' of clearance",
         {"m.yaml": _model(effects={"clearance": {"gap": 0.01}})}, "puu.yaml with effects: {clearance: {gap: 0.01}}"),
    Case("18.4", "vjm stiffness m.yaml --at 0,0,0", "effects.passive_clearance: missing backlash",
         {"m.yaml": _model(effects={"passive_clearance": {}})}, "puu.yaml with effects: {passive_clearance: {}}"),
    Case("18.4", "vjm stiffness m.yaml --at 0,0,0", "effects.leg_axial: leg_axial changes the model itself",
         {"m.yaml": _model(effects={"leg_axial": {"factor": 2.0}})}, "puu.yaml with effects: {leg_axial: {factor: 2}}"),
    Case("18.4", "vjm stiffness m.yaml --at 0,0,0", "geometry.Lenght: unknown key for orthoglide-3PUU; its geometry is L, r (mm)",
         {"m.yaml": _model(geometry={"L": 310.0, "r": 50.0, "Lenght": 300.0})}, "puu.yaml with geometry: {L: 310, r: 50, Lenght: 300}"),
    Case("18.4", "vjm stiffness m.yaml --at 0,0,0", "geometry.d: unknown key for orthoglide-3PUU",
         {"m.yaml": _model(geometry={"L": 310.0, "r": 50.0, "d": 80.0})}, "puu.yaml with geometry: {L: 310, r: 50, d: 80}"),
    Case("18.4", "vjm stiffness {puu} --at 0,0,0 --leg leg.json", "not a linkfea result, missing schema",
         {"leg.json": _result(schema=None)}, "a link result without schema"),
    Case("18.4", "vjm stiffness {puu} --at 0,0,0 --leg leg.json", "schema 'linkfea.result/9' is not",
         {"leg.json": _result(schema="linkfea.result/9")}, "a link result of schema linkfea.result/9"),
    Case("18.4", "vjm stiffness {puu} --at 0,0,0 --leg leg.json", "stiffness contradicts the compliance",
         {"leg.json": _result(stiffness=[[2 / c if i == j else 0.0 for j in range(6)]
                                         for i, c in enumerate(C_DIAG)])},
         "a link result whose stiffness is twice the inverse of its compliance"),
    Case("18.4", "vjm stiffness m.yaml --at 0,0,0", "geometry.Rr: no expression of the platform or the chains uses it",
         {"m.yaml": _linear("geometry:\n", "geometry:\n  Rr: 12.0\n")},
         "linear_delta.yaml with an extra geometry name Rr that no expression uses"),
    # 18.9: messages
    Case("18.9", "vjm stiffness m.yaml --at 0,0,0", "'9**9**9' is too large: its value is beyond the largest",
         {"m.yaml": _linear("Tx(R), Tz(q0) actuated", "Tx(9**9**9), Tz(q0) actuated")},
         "linear_delta.yaml, first element Tx(9**9**9)"),
    Case("18.9", "vjm stiffness m.yaml --at 0,0,0", "element 1 'Tx(1, 2)': '1, 2' is not an arithmetic expression",
         {"m.yaml": _linear("Tx(R), Tz(q0) actuated", "'Tx(1, 2)', Tz(q0) actuated")},
         "linear_delta.yaml, first element Tx(1, 2)"),
    Case("18.9", "vjm stiffness {puu} --at 500,0,0", "pose (500, 0, 0) mm is unreachable"),
    Case("18.9", "vjm stiffness m.yaml --at 0,0,0", "move in 0 independent directions at the seed posture "
         "(0, 0, 0, 0, 0, 0); check the chains (a platform has 3 or 6 dof)", {"m.yaml": LOCKED},
         "a description whose three chains lock the platform (one slider each along x, y, z)"),
    # link script parameters (checked before: listed for the table)
    Case("18.2", "linkfea compute bar -p length=nan", "parameter 'length' must be a finite number, got nan"),
    Case("18.2", "linkfea compute bar -p length=-5", "parameter 'length' must be > 0 mm, got -5"),
    # 18.7: work that cannot fit is refused before it starts
    Case("18.7", "linkfea sweep bar --param width=1:100000:0.001 --out sw", "99,999,001 designs are too many"),
    Case("18.7", "linkfea sweep bar --param width=10:20 --sample 1000000000000 --out sw",
         "1,000,000,000,000 designs are too many"),
    # 18.8: data files never run code
    Case("18.8", "vjm stiffness m.yaml --at 0,0,0", "the YAML tag !!python/object/apply:os.system is not allowed",
         {"m.yaml": "name: evil\nL: !!python/object/apply:os.system ['touch MARKER']\n"},
         "a model file with a YAML tag that would run a shell command"),
    Case("18.8", "vjm stiffness m.yaml --at 0,0,0", "calling system() is not allowed",
         {"m.yaml": _linear("Tx(R), Tz(q0) actuated", "\"Tx(__import__('os').system('touch MARKER'))\", Tz(q0) actuated")},
         "linear_delta.yaml, first element Tx(__import__('os').system('touch MARKER'))"),
    Case("18.8", "vjm stiffness m.yaml --at 0,0,0", "attribute access .__class__ is not allowed",
         {"m.yaml": _linear("Tx(R), Tz(q0) actuated", "Tx(R.__class__), Tz(q0) actuated")},
         "linear_delta.yaml, first element Tx(R.__class__)"),
    # 20.5: platform orientations (ox,oy,oz) in measurement and pose files
    Case("20.5", D, "m.csv: column 'ox': the file gives platform orientations (ox,oy,oz) but the machine's platform "
                    "only translates (3 dof)", {"m.csv": _csv(",ox,oy,oz", ",0,0,0.05")}),
    Case("20.5", D, "column 'oz': missing column(s) oz: the platform orientation is a rotation vector ox,oy,oz (rad)",
         {"m.csv": _csv(",ox,oy", ",0,0")}),
    Case("20.5", HD, "row 2, column 'oy': value is missing (required column)",
         {"m.csv": HEX_HDR + "\n0,0,550,0,,0,1000,0,0,0,0,0,0.01,0,0,,,\n"}),
    Case("20.5", HD, "row 2, columns 'x,y,z,ox,oy,oz': pose (0, 0, 550, 1.5, 0, 0) is unreachable by chain",
         {"m.csv": HEX_HDR + "\n0,0,550,1.5,0,0,1000,0,0,0,0,0,0.01,0,0,,,\n"}),
    Case("20.5", S + " --tilt 0.1", "--tilt 0.1 rad: the machine's platform only translates (3 dof)"),
    Case("20.5", "vjm simulate {hexapod} --tilt -0.1 --out s.csv", "--tilt must be in [0, 3.14159] rad, got -0.1"),
    Case("20.5", S + " --poses p.csv", "p.csv: column 'ox': the file gives platform orientations (ox,oy,oz) but the "
                                     "machine's platform only translates (3 dof)", {"p.csv": "x,y,z,ox,oy,oz\n0,0,0,0,0,0\n"}),
    # vjm path: options and toolpaths
    Case("22", "vjm path {puu} pocket.nc --out o --chord-tol -1", "--chord-tol and --step must be numbers > 0 (mm)"),
    Case("22", "vjm path {puu} pocket.nc --out o --tolerance nan", "--tolerance must be a number > 0 (mm), got nan"),
    Case("22", "vjm path {puu} p.nc --out o --wrench 10,0,0,0,0,0", "line 3",
         {"p.nc": "G21 G90\nG0 X0 Y0 Z0\nG1 X5 Q3\n"}, "a G-code line with an unknown word Q"),
    # 30.4: options and inputs that were accepted but should not be
    Case("30.4", "vjm stiffness m.yaml --at 0,0,0", "m.yaml, line 9: the key 'geometry' is given twice (first on line 6)",
         {"m.yaml": PLACES["puu"].read_text(encoding="utf-8").replace("actuator:", "geometry: {L: 200.0, r: 40.0}"
                                                                      "\nactuator:", 1)},
         "puu.yaml with a second geometry: {L: 200, r: 40} (YAML keeps the last one silently)"),
    Case("30.4", "vjm map {puu} --orientation 0,0,0.1 --out map",
         "--orientation 0,0,0.1 rad: the machine's platform only translates (3 dof)"),
    Case("30.4", "vjm stiffness m.yaml --at 0,0,0", "'(-8)**(1/3)' has no real value ((-8) ** 0.333333",
         {"m.yaml": _linear("Tx(R), Tz(q0) actuated", "'Tx((-8)**(1/3))', Tz(q0) actuated")},
         "linear_delta.yaml, first element Tx((-8)**(1/3))"),
    Case("30.4", "linkfea compute bar --tolerance nan", "--tolerance must be a percentage in (0%, 100%) such as "
                                                        "1%, or a fraction in (0, 1) such as 0.01; got 'nan'"),
    Case("30.4", "linkfea compute bar --tolerance nan%", "; got 'nan%'"),
    Case("30.4", "linkfea compute bar --tolerance 200%", "--tolerance must be a percentage in (0%, 100%) such as "
                                                         "1%, or a fraction in (0, 1) such as 0.01; got '200%'"),
    Case("30.4", "linkfea compute bar --tolerance 0", "; got '0'"),
    Case("30.4", "linkfea compute bar -p length=100 -p length=300", "--param length given twice (100 and 300)"),
    Case("30.4", STL, "s.stl: expected one body, found 2 separate closed surfaces",
         {"s.stl": stl(BAR + _box((200, 0, 0), (300, 20, 10)))}, "two disjoint boxes 100 x 20 x 10 mm"),
    Case("30.4", STL, "s.stl: expected one body, found 2 separate closed surfaces",
         {"s.stl": stl(BAR + _box((40, -40, 0), (60, 60, 10)))}, "two boxes that cross each other"),
    Case("30.4", STL, "s.stl: the surface encloses no volume", {"s.stl": stl(FLAT)},
         "four triangles closing a flat square (watertight, zero volume)"),
    Case("30.4", STL, "s.stl: a vertex has a non-finite coordinate (nan, 0, 0), in triangle 1",
         {"s.stl": stl([((float("nan"), 0, 0),) + BAR[0][1:]] + BAR[1:])}, "a box whose first vertex is nan"),


    # 30.1: the user's files (checked before any work)
    Case("30.1", "linkfea compute bar --out r.json", "r.vtu exists and r.json does not record its bytes",
         {"r.json": _result(), "r.vtu": "<my own mesh/>"}, "a result written with --no-picture, and the user's r.vtu"),
    Case("30.1", "linkfea compute bar --out r.json", "r.png exists and r.json does not record its bytes",
         {"r.json": _result(), "r.png": "my picture"}, "a result written with --no-picture, and the user's r.png"),
    Case("30.1", "linkfea compute bar --out r.json", "r.vtu exists and r.json does not record its bytes",
         {"r.json": _result(files={"vtu": {"name": "r.vtu", "sha256": _sha("<its mesh/>")}}), "r.vtu": "<my mesh/>"},
         "a result JSON copied beside the user's r.vtu (it records another r.vtu's sha256)"),
    Case("30.1", D + " --suggest 3", "model_updated.yaml was changed since linkfea or vjm wrote it",
         _report_folder("model_updated.yaml"), "rep/ of an earlier run; the user edited rep/model_updated.yaml"),
    Case("30.1", D + " --suggest 3", "next_measurements.csv was changed since linkfea or vjm wrote it",
         _report_folder("next_measurements.csv"), "rep/ of an earlier run; the user edited rep/next_measurements.csv"),
    Case("30.1", D, "cannot read measurement file m.csv: it is not a regular file", links={"m.csv": "/dev/zero"},
         note="m.csv -> /dev/zero"),
    Case("30.1", S + " --poses p.csv", "cannot read CSV file p.csv: it is not a regular file", links={"p.csv": "/dev/zero"},
         note="p.csv -> /dev/zero"),
    Case("30.1", "linkfea compute bar --out r.json", "r.json is a symbolic link to elsewhere/r.json, which does not exist",
         links={"r.json": "elsewhere/r.json"}, note="r.json -> elsewhere/r.json (dangling)"),
    Case("30.1", S, "s.csv is a symbolic link to gone.csv, which does not exist", links={"s.csv": "gone.csv"},
         note="s.csv -> gone.csv (dangling)"),
    Case("30.1", D, "rep is a symbolic link to gone, which does not exist", {"m.csv": GOOD}, links={"rep": "gone"},
         note="m.csv; rep -> gone (dangling)"),
    Case("30.1", "linkfea sweep bar -p length=100,120 --scheduler tcp://127.0.0.1:1 --out sw",
         "cannot reach the Dask scheduler at tcp://127.0.0.1:1"),
    Case("26.7", "vjm stiffness r.yaml --q 0,0", "r.urdf: link 'l1' is the child of two joints ('j1' and 'j2'): a "
         "kinematic loop", {"r.yaml": ROBOT, "r.urdf": _urdf(_joint("j1", "base", "l1") + _joint("j2", "l2", "l1"))},
         "a URDF whose link l1 has two parents"),
    Case("26.7", "vjm stiffness r.yaml --q 0,0", "joint 'j2': its parent link 'arm' is not defined in the file",
         {"r.yaml": ROBOT, "r.urdf": _urdf(_joint("j1", "base", "l1") + _joint("j2", "arm", "l2"))},
         "a URDF joint whose parent link does not exist"),
    Case("26.7", "vjm stiffness r.yaml --q 0,0", "joint 'j2': unknown type 'hinge'",
         {"r.yaml": ROBOT, "r.urdf": _urdf(_joint("j1", "base", "l1") + _joint("j2", "l1", "l2", "hinge"))},
         "a URDF joint of type hinge"),
    Case("26.7", "vjm stiffness r.yaml --q 0,0", "joint 'j1' is floating",
         {"r.yaml": "urdf: r.urdf\n", "r.urdf": _urdf(_joint("j1", "base", "l1", "floating")
                                                       + _joint("j2", "l1", "l2"))}, "a URDF with a floating joint"),
    Case("26.7", "vjm stiffness r.yaml --q 0,0", "joint 'j2' is planar",
         {"r.yaml": "urdf: r.urdf\n", "r.urdf": _urdf(_joint("j1", "base", "l1") + _joint("j2", "l1", "l2", "planar"))},
         "a URDF with a planar joint"),
    Case("26.7", "vjm stiffness r.yaml --q 0,0", "link 'l1': a mass of 2 kg without a centre of mass",
         {"r.yaml": ROBOT, "r.urdf": _urdf(_joint("j1", "base", "l1") + _joint("j2", "l1", "l2"),
                                           inertial='<inertial><mass value="2"/></inertial>')},
         "a URDF inertial with a mass and no origin"),
    Case("26.7", "vjm stiffness r.yaml --q 0,0", "link 'l1': inertial mass must be a number >= 0 (kg), got '-2'",
         {"r.yaml": ROBOT, "r.urdf": _urdf(_joint("j1", "base", "l1") + _joint("j2", "l1", "l2"),
                                           inertial='<inertial><mass value="-2"/><origin xyz="0 0 0"/></inertial>')},
         "a URDF link of mass -2 kg"),
    Case("26.7", "vjm stiffness r.yaml --q 0,0 --self-weight", "self-weight: link 'l1' (moved by joint 'j1') has no "
         "inertial", {"r.yaml": ROBOT, "r.urdf": _urdf(_joint("j1", "base", "l1") + _joint("j2", "l1", "l2"),
                                                      inertial="")}, "self-weight of a URDF without inertials"),
    Case("26.7", "vjm stiffness r.yaml --q 0,0,0", "--q expects 2 numbers q1,...,q2",
         {"r.yaml": ROBOT, "r.urdf": ARM}, "three joint values for a two-joint arm"),
    Case("26.7", "vjm stiffness r.yaml --q 0,2.5 --strict-limits", "q[1] = 2.5 of joint 'j2' is outside its limits "
         "[-2, 2]", {"r.yaml": ROBOT, "r.urdf": ARM}, "a joint value beyond the URDF's limit"),
    Case("26", "vjm map r.yaml --out m", "r.yaml has no home: configuration; give --q q1,...,q2 (j1, j2)",
         {"r.yaml": ROBOT, "r.urdf": ARM}, "a robot map without a configuration"),
    Case("26.2", "vjm map r.yaml --q 0,0 --joints j1=-1:1:5,j9=0:1:5 --out m", "--joints names 'j9', not a joint "
         "with a coordinate of its own; joints: j1, j2", {"r.yaml": ROBOT, "r.urdf": ARM}, "a joint map of a joint "
         "the robot does not have"),
    Case("26.2", "vjm map r.yaml --q 0,0 --joints j1=-1:1:5,j2=0:2.5:5 --out m", "--joints j2: the range 0:2.5 leaves "
         "the joint's limits [-2, 2]", {"r.yaml": ROBOT, "r.urdf": ARM}, "a joint map beyond a joint's limits"),
    Case("26.2", "vjm map r.yaml --q 0,0 --joints j1=-1:1:5 --out m", "--joints varies two joints",
         {"r.yaml": ROBOT, "r.urdf": ARM}, "a joint map of one joint"),
    Case("26.2", "vjm map r.yaml --q 0,0,0 --out m", "--q expects 2 numbers q1,...,q2",
         {"r.yaml": ROBOT, "r.urdf": ARM}, "a robot map's seed of the wrong length"),
    Case("26.2", "vjm map r.yaml --q 0,0 --joints j1=-1:1:1,j2=0:1 --out m", "--joints j1: the number of values must "
         "be a whole number >= 2, got '1'", {"r.yaml": ROBOT, "r.urdf": ARM}, "a joint map of one value per joint"),
    Case("26.2", "vjm map r.yaml --q 0,0 --box 0:1,0:1 --out m", "--box expects x0:x1,y0:y1,z0:z1 (mm)",
         {"r.yaml": ROBOT, "r.urdf": ARM}, "a Cartesian robot map's box of two axes"),
    Case("26.2", "vjm map {puu} --joints a=0:1,b=0:1 --out m", "--joints is for serial robots",
         note="a joint map asked of a parallel machine"),
    Case("26.3", "vjm simulate r.yaml --poses random:5 --effect offset:j9=0.01 --out s.csv", "--effect offset: no "
         "joint 'j9'; joints: j1, j2", {"r.yaml": ROBOT, "r.urdf": ARM}, "a hidden offset of a joint the robot lacks"),
    Case("26.3", "vjm simulate r.yaml --poses random:5 --effect backlash:j1=0.01 --out s.csv", "--effect a robot takes "
         "offset:<joint>=<value>,... or compliance:<joint>=<factor>", {"r.yaml": ROBOT, "r.urdf": ARM},
         "a hidden effect a robot's simulation does not have"),
    Case("26.3", "vjm simulate r.yaml --poses random:5 --effect compliance:j1=-2 --out s.csv", "--effect "
         "compliance:j1 needs a finite number > 0, got '-2'", {"r.yaml": ROBOT, "r.urdf": ARM},
         "a negative compliance factor"),
    Case("26.3", "vjm simulate r.yaml --poses grid:4 --out s.csv", "--poses a robot takes random:N or a CSV of joint "
         "values (j1, j2)", {"r.yaml": ROBOT, "r.urdf": ARM}, "a grid of platform poses asked of a robot"),
    Case("26.3", "vjm simulate r.yaml --loads axes:50 --out s.csv", "--loads is for parallel machines",
         {"r.yaml": ROBOT, "r.urdf": ARM}, "loads asked of a robot's absolute poses"),
    Case("26.7", "vjm stiffness r.yaml --q 0,0", "r.urdf has no joint 'elbow'; its joints: j1, j2",
         {"r.yaml": "urdf: r.urdf\njoints:\n  j1: {stiffness: 1.0e+8}\n  elbow: {stiffness: 1.0e+8}\n", "r.urdf": ARM}, "a stiffness for a joint the URDF "
         "does not have"),
    Case("26.4", "vjm path {ur10} far.nc --out o --wrench 20,0,0,0,0,0 --step 5000", "far.nc line 3: the programmed point "
         "[2500.0, 160.0, 250.0] mm is out of the robot's reach", {"far.nc": "G21 G90\nG0 X800 Y160 Z250\nG1 X2500 "
                                                                    "F1000\n"}, "a UR10 toolpath reaching 2.5 m out"),


    # 27: vjm calibrate (absolute poses)
    Case("27", "vjm calibrate {puu} p.csv --out o", "a parallel machine; vjm calibrate takes a serial or tree robot",
         {"p.csv": POSES}, "a parallel machine given to the robot calibration"),
    Case("27", "vjm calibrate r.yaml p.csv --out o --folds 1", "--folds must be 0 (no cross-validation) or at least 2",
         CAL_FILES, "one fold"),
    Case("27", "vjm calibrate r.yaml p.csv --out o --register 2", "--register must be at least 3 poses", CAL_FILES,
         "validation files registered on 2 poses"),
    Case("27", "vjm calibrate r.yaml p.csv --out o --effects geometry,creep", "--effect creep: not an effect of absolute poses",
         CAL_FILES, "an effect the library does not have"),
    Case("27", "vjm calibrate r.yaml p.csv --out o --effects geometry,thermal", "p.csv: the thermal effect needs the "
         "rows' temperature, a meta_temperature column (C)", CAL_FILES, "a thermal scale without a temperature column"),
    Case("27", "vjm calibrate r.yaml p.csv --out o", "p.csv: no column for joint(s) j2",
         {**CAL_FILES, "p.csv": POSES.replace("j2,", "jj,")}, "a data file without a joint's column"),
    Case("27", "vjm calibrate r.yaml p.csv --out o --frame l1", "--frame l1: p.csv measures l2", CAL_FILES,
         "a frame the data does not measure"),
    Case("27", "vjm calibrate r.yaml p.csv --out o", "measured point hand: not a frame of the model",
         {**CAL_FILES, "p.csv": POSES.replace("l2.", "hand.")}, "a measured point that is no frame of the URDF"),
    Case("27", "vjm calibrate r.yaml p.csv --out o --validate v.csv", "v.csv: 5 rows; a validation file needs more "
         "than --register (30) rows", {**CAL_FILES, "v.csv": "\n".join(POSES.splitlines()[:6]) + "\n"},
         "a validation file shorter than its registration"),
    Case("27", "vjm calibrate r.yaml p.csv --out o", "p.csv: 4 rows (9 coordinates per fold) for up to 37 parameters",
         {**CAL_FILES, "p.csv": "\n".join(POSES.splitlines()[:5]) + "\n"}, "four poses"),
    Case("27", "vjm calibrate r.yaml p.csv --columns c.yaml --out o", "l2.x: unit 'deg' is not a length",
         {**CAL_FILES, "c.yaml": "columns: {j1: [j1, rad], j2: [j2, rad], l2.x: [l2.x, deg], l2.y: [l2.y, mm], "
          "l2.z: [l2.z, mm]}\n"}, "a column map giving a position in degrees"),
    Case("27", "vjm calibrate r.yaml p.csv --out o", "o: report.json is there and was not written by linkfea or vjm",
         {**CAL_FILES, "o/report.json": "{}\n"}, "an output folder holding the user's report.json"),
    # 27.1: vjm diagnose on absolute poses (a robot's model)
    Case("27.1", "vjm diagnose {puu} p.csv --out o", "p.csv: no column for actuator(s) x.q0, y.q0, z.q0: a parallel "
         "machine's absolute poses have a column per actuator", {"p.csv": POSES},
         "a parallel machine's model given a robot's absolute poses"),
    Case("27.1", "vjm diagnose {hexapod} p.csv --out o --targets t.csv", "--targets is for a serial or tree robot's "
         "absolute poses (the commands reaching them); a parallel machine's commands are its inverse kinematics",
         {"p.csv": HEX_POSES, "t.csv": "x,y,z\n0,0,550\n"}, "targets (compensated commands) asked of a parallel "
         "machine's absolute poses"),
    Case("27.1", "vjm diagnose {hexapod} p.csv --out o --effect compliance", "--effect compliance: not an effect of a "
         "parallel machine's absolute poses; effects: offset, attachment", {"p.csv": HEX_POSES},
         "a robot's effect asked of a parallel machine's absolute poses"),
    Case("27.1", "vjm diagnose {hexapod} p.csv --out o --suggest 5", "--suggest designs (posture, load) rows of "
         "deflection data", {"p.csv": HEX_POSES}, "rows to measure next asked of a parallel machine's absolute poses"),
    Case("27.1", "vjm diagnose {hexapod} p.csv --out o", "p.csv: measured point tool: a parallel machine's measured "
         "point is on its platform", {"p.csv": HEX_POSES.replace("platform.", "tool.")},
         "a parallel machine's measured point named otherwise than platform"),
    Case("27.1", "vjm diagnose {hexapod} p.csv --out o", "the forward kinematics does not close at the actuator values "
         "of 40 row(s)", {"p.csv": HEX_POSES.replace("598", "98")}, "strut lengths no assembly of the hexapod has"),
    Case("27.1", "vjm diagnose {hexapod} p.csv --out o", "o: report.json is there and was not written by linkfea or vjm",
         {"p.csv": HEX_POSES, "o/report.json": "{}\n"}, "a parallel machine's report folder holding the user's "
         "report.json"),
    Case("27.1", "vjm diagnose {puu} m.csv --columns c.yaml --out o", "--columns and --validate read absolute poses",
         {"m.csv": GOOD, "c.yaml": "columns: {}\n"}, "a column map given with a parallel machine's deflections"),
    Case("27.1", "vjm diagnose r.yaml p.csv --out o --suggest 5", "--suggest designs (posture, load) rows of "
         "deflection data", CAL_FILES, "rows to measure next asked of absolute poses"),
    Case("27.1", "vjm diagnose r.yaml p.csv --out o --tracker 0,0,0 --tracker-noise 0.01,1e-5", "--tracker: absolute "
         "poses state their sigmas", CAL_FILES, "a tracker noise model given for absolute poses"),
    Case("27.1", "vjm diagnose r.yaml p.csv --out o --effect creep", "--effect creep: not an effect of absolute poses",
         CAL_FILES, "an effect the absolute-pose library does not have"),
    Case("27.1", "vjm diagnose r.yaml p.csv --out o", "p.csv: no column for joint(s) j2",
         {**CAL_FILES, "p.csv": POSES.replace("j2,", "jj,")}, "absolute poses without a joint's column"),
    Case("27.1", "vjm diagnose r.yaml p.csv --out o", "measured point hand: not a frame of the model",
         {**CAL_FILES, "p.csv": POSES.replace("l2.", "hand.")}, "a measured point that is no frame of the URDF"),
    Case("27.1", "vjm diagnose r.yaml p.csv --out o --validate v.csv", "v.csv: 5 rows; a validation file needs more "
         "than --register (30) rows", {**CAL_FILES, "v.csv": "\n".join(POSES.splitlines()[:6]) + "\n"},
         "a validation file shorter than its registration"),
    Case("27.1", "vjm diagnose r.yaml p.csv --out o", "p.csv: 4 rows (9 coordinates per fold) for up to 37 parameters",
         {**CAL_FILES, "p.csv": "\n".join(POSES.splitlines()[:5]) + "\n"}, "four absolute poses"),
    Case("27.1", "vjm diagnose r.yaml p.csv --out o", "o: report.json is there and was not written by linkfea or vjm",
         {**CAL_FILES, "o/report.json": "{}\n"}, "a report folder holding the user's report.json"),
    Case("27.2", "vjm calibrate r.yaml p.csv --out o --effects geometry,payload", "--effects payload: a payload is "
         "weighed at one marker; the data measure 2 points", {**CAL_FILES, "p.csv": TWO_POINTS},
         "a payload asked of two measured points"),
    # 27.4: vjm compensate, and the commands written back by vjm calibrate / diagnose --targets
    Case("27.4", "vjm compensate {ur10} t.csv --out c.csv", "t.csv: no column z; a targets file has the columns "
         "x,y,z[,rx,ry,rz]", {"t.csv": "x,y\n900,100\n"}, "targets without a z column"),
    Case("27.4", "vjm compensate {ur10} t.csv --out c.csv", "t.csv: columns rx without the other rotation components",
         {"t.csv": "x,y,z,rx\n900,100,400,0.1\n"}, "one rotation component of three"),
    Case("27.4", "vjm compensate {ur10} t.csv --seed 0,-1.2,1.5 --out c.csv", "--seed expects 6 numbers",
         {"t.csv": "x,y,z\n900,100,400\n"}, "a seed of three joint values for a 6-joint arm"),
    Case("27.4", "vjm compensate {ur10} t.csv --out c.csv", "t.csv: no target can be commanded: target 1 unreachable",
         {"t.csv": "x,y,z\n5000,0,0\n"}, "one target 5 m out of a UR10's reach (several targets, some reachable: "
         "the others are written and these flagged, with a warning)"),
    Case("27.4", "vjm compensate {ur10} t.csv --out c.csv", "--out c.csv exists and is not a CSV written by vjm "
         "compensate", {"t.csv": "x,y,z\n900,100,400\n", "c.csv": "my notes\n"}, "an output file vjm did not write"),
    Case("27.4", "vjm compensate {ur10} t.csv --payload 5@1,2 --out c.csv", "--payload expects KG[@x,y,z]",
         {"t.csv": "x,y,z\n900,100,400\n"}, "a payload's point with two coordinates"),
    Case("27.4", "vjm calibrate r.yaml p.csv --out o --targets t.csv", "r.yaml has no home: configuration, the seed of the commands",
         {**CAL_FILES, "t.csv": "x,y,z\n500,0,300\n"}, "targets for a robot file without home:"),
    Case("27.4", "vjm diagnose {puu} m.csv --out o --targets t.csv", "--targets is for a serial or tree robot's",
         {"m.csv": GOOD, "t.csv": "x,y,z\n0,0,0\n"}, "targets given with a parallel machine's deflections"),

    # 30.2: one line where a traceback was
    Case("30.2", "linkfea compute bar --out .", "--out '.' is a folder, not a file: give a file name"),
    Case("30.2", "linkfea compute bar --out ''", "--out '.' is a folder, not a file: give a file name"),
    Case("30.2", "linkfea compute bar -p length=1e20", "parameter 'length' must be <= 1e+08 mm"),
    Case("30.2", "linkfea compute bar -p length=1e308", "parameter 'length' must be <= 1e+08 mm"),
    Case("30.2", "linkfea compute s.py --out r.json", "s.py, line 4: ZeroDivisionError: integer division or modulo by zero",
         {"s.py": SCRIPT.format(body="    return 1 // 0")}, "a link script whose build() divides by zero"),
    Case("30.2", "linkfea compute s.py --out r.json", "s.py, line 4: SyntaxError: '(' was never closed",
         {"s.py": SCRIPT.format(body="    return (")}, "a link script with a syntax error"),
    Case("30.2", "linkfea compute s.py --out r.json", "s.py, line 3: RecursionError: maximum recursion depth",
         {"s.py": "PARAMS = {}\ndef build(**p):\n    return build(**p)\n"}, "a link script whose build() recurses forever"),
    Case("30.2", "linkfea compute s.py --out r.json", "s.py, line 1: ModuleNotFoundError: No module named "
         "'no_such_module_30'", {"s.py": "import no_such_module_30\n" + SCRIPT.format(body="    pass")},
         "a link script importing a missing module"),
    Case("30.2", "linkfea compute s.py --out r.json", "s.py, line 5: the script called sys.exit(0)",
         {"s.py": "import sys\n" + SCRIPT.format(body="    sys.exit(0)")}, "a link script whose build() calls sys.exit(0)"),
    # 30.3: work estimated before it starts
    Case("30.3", "linkfea compute bar --mesh-size 1e-3", "a mesh of edge 0.001 mm would have about 2.2e+14 tets"),
    Case("30.3", "linkfea compute bar -p width=1e-4", "a mesh of edge 6e-05 mm would have about"),
    Case("30.3", "linkfea compute bar -p length=1e6", "a mesh of edge 4 mm would have about 1.7e+07 tets"),
    Case("30.3", "vjm path {puu} p.nc --out o --wrench 10,0,0,0,0,0 --step 1e-9",
         "vjm path would need about 1e+05 GB of memory for 1e+11 toolpath points", {"p.nc": LINE_NC},
         "a 100 mm straight move"),
    Case("30.3", "vjm path {puu} p.nc --out o --wrench 10,0,0,0,0,0 --chord-tol 1e-20",
         "for 7.85e+10 toolpath points", {"p.nc": LINE_NC + "G2 X0 Y0 I-50 J0\n"}, "a half circle of radius 50 mm"),
    Case("30.3", "vjm path {puu} p.nc --out o --wrench 1e300,0,0,0,0,0", "deflects the tool by inf mm",
         {"p.nc": LINE_NC}, "a 100 mm straight move"),
    Case("30.3", "vjm stiffness m.yaml --at 0,0,0", "the alias *c is inside the value &c names (a recursive anchor",
         {"m.yaml": PLACES["puu"].read_text(encoding="utf-8").replace(
             "  beam: {section: rect, width: 30.0, height: 10.0, length: 310.0, material: aluminium}",
             "  compliance: &c [*c, *c, *c, *c, *c, *c]")},
         "puu.yaml whose leg is compliance: &c [*c, *c, *c, *c, *c, *c]"),
    Case("30.3", "vjm stiffness m.yaml --at 0,0,0", "it holds 1.23e+09 values once its aliases are expanded",
         {"m.yaml": _linear("geometry:\n", LAUGHS + "geometry:\n")},
         "linear_delta.yaml with nine levels of ten aliases each (10^9 values)"),
    Case("30.3", "vjm stiffness m.yaml --at 0,0,0", "copies.count must be an integer in [1, 64], got 1000000000",
         {"m.yaml": _linear("count: 3", "count: 1000000000")}, "linear_delta.yaml with copies: {count: 1000000000}"),
    Case("26", "vjm sweep {ur10} --leg leg.json --out s", "ur10.yaml: a serial robot; vjm sweep is for parallel machines",
         note="a robot given to the link-design sweep"),
    # 40.1: the user's files; 40.2: inputs that hang, exhaust or crash
    Case("40.1", "vjm compensate {ur10} t.csv --out c.csv", "c.csv was changed since linkfea or vjm wrote it",
         {"t.csv": "x,y,z\n884,164,436\n", "c.csv": EDITED_COMMANDS}, "c.csv: a commands.csv whose first line "
         "says vjm wrote it, a row added since"),
    Case("40.1", "vjm calibrate o/calibrated.yaml p.csv --out o --force", "writing calibrated.yaml would replace "
         "o/calibrated.yaml, which this command reads", READ_FROM_OUT, "o/: a calibration's set; its calibrated.yaml "
         "the model read"),
    Case("40.2", "vjm calibrate r.yaml z.csv --out o", "cannot read absolute-pose file z.csv: it is not a regular "
         "file", CAL_FILES, "z.csv: a link to /dev/zero", links={"z.csv": "/dev/zero"}),
    Case("40.2", "vjm calibrate r.yaml p.csv --validate z.csv --out o", "cannot read absolute-pose file z.csv",
         CAL_FILES, "z.csv: a link to /dev/zero", links={"z.csv": "/dev/zero"}),
    Case("40.2", "vjm calibrate r.yaml p.csv --columns z.yaml --out o", "cannot read column map z.yaml: it is not "
         "a regular file", CAL_FILES, "z.yaml: a link to /dev/zero", links={"z.yaml": "/dev/zero"}),
    Case("40.2", "vjm stiffness d.yaml --q 0", "a chain of more than 1,000 joints (down to link 'l1001')",
         {"d.yaml": "urdf: d.urdf\n", "d.urdf": _urdf("".join(f'<joint name="j{i}" type="fixed"><parent link="l{i}"/>'
                                                               f'<child link="l{i + 1}"/></joint>' for i in range(5000)),
                                                       [f"l{i}" for i in range(5001)], inertial="")},
         "a URDF of 5,000 chained fixed joints (0.5 MB)"),
    # 38.2: an effect excluded from the candidates; 38.5: held-out files in the fitted set-up
    Case("38.2", "vjm calibrate r.yaml p.csv --out o --effect -creep", "--effect -creep: not an effect of absolute "
         "poses to exclude; effects: geometry, compliance", CAL_FILES, "an effect the library does not have, excluded"),
    Case("38.2", "vjm diagnose r.yaml p.csv --out o --effect geometry --effect -geometry", "--effect: every candidate "
         "excluded (-geometry)", CAL_FILES, "the one effect asked for, excluded"),
    Case("38.5", "vjm calibrate r.yaml p.csv --out o --same-setup", "--same-setup says the --validate files were "
         "measured in the fitted data's set-up; give --validate", CAL_FILES, "--same-setup without a held-out file"),
    Case("38.5", "vjm diagnose r.yaml g.csv --out o --validate v.csv --same-setup", "--same-setup: the fitted data "
         "hold 2 set-ups (groups a, b); give v.csv a group column naming its set-up",
         {**CAL_FILES, "g.csv": GROUPED, "v.csv": "\n".join(POSES.splitlines()[:6]) + "\n"},
         "--same-setup, the fitted data in two set-ups"),
    Case("38.5", "vjm calibrate r.yaml g.csv --out o --validate v.csv", "v.csv: rows of the fitted set-up(s) a and "
         "of other groups (c); hold out one set-up per file",
         {**CAL_FILES, "g.csv": GROUPED, "v.csv": GROUPED.replace(",b\n", ",c\n")},
         "a held-out file mixing a fitted set-up and another"),
    # 38.3: an effect asked for that the robot cannot have
    Case("38.3", "vjm calibrate r.yaml p.csv --out o --effect guide_tilt", "guide_tilt: no prismatic joint with a "
         "finite travel (a linear axis, a track, a column) on the path to l2: the effect has nothing to fit", CAL_FILES,
         "a two-joint revolute arm", number=360),
    Case("38.3", "vjm diagnose r.yaml p.csv --out o --effect link_scale", "link_scale: the model states no link "
         "spring (links: a beam, a linkfea result) on the path to l2: the effect has nothing to fit", CAL_FILES,
         "r.yaml: joint springs, no links:"),
    # 40.6: maps compared
    Case("40.6", "vjm map {puu} --grid 3 --slice z=0 --out m --compare m", "--compare m is the --out folder: its map "
         "would be replaced", note="a map compared with the folder it is written to", number=470),
    Case("40.6", "vjm map {puu} --grid 3 --slice z=0 --out m --compare o", "--compare o: holds no map.npz",
         {"o/notes.txt": "mine\n"}, "o/: a folder without a map"),
    Case("40.6", "vjm map {puu} --grid 3 --slice z=0 --out m --compare o", "--compare o/map.npz: not a readable "
         "map.npz", {"o/map.npz": "not a map\n"}, "o/map.npz: a text file"),
    # 38.1: the rated load of a robot file; 38.2: the practical threshold of an effect's gain
    Case("38.1", "vjm calibrate r.yaml p.csv --out o", "payload_limit must be > 0 (kg, the rated load), got -5",
         {**CAL_FILES, "r.yaml": ROBOT + "payload_limit: -5\n"}, "a negative rated load", number=320),
    Case("38.1", "vjm diagnose r.yaml p.csv --out o", "payload_limit must be a finite number, got 'heavy'",
         {**CAL_FILES, "r.yaml": ROBOT + "payload_limit: heavy\n"}, "a rated load that is no number"),
    Case("38.1", "vjm calibrate r.yaml p.csv --out o", "payload.mass 8 kg exceeds payload_limit 5 kg",
         {**CAL_FILES, "r.yaml": ROBOT + "payload: {frame: l2, mass: 8}\npayload_limit: 5\n"},
         "a payload above the rated load"),
    Case("38.2", "vjm diagnose r.yaml p.csv --out o --min-gain -0.01", "--min-gain must be a finite number of mm >= 0",
         CAL_FILES, "a negative practical threshold"),
    Case("38.2", "vjm calibrate r.yaml p.csv --out o --min-gain nan", "--min-gain must be a finite number of mm >= 0",
         CAL_FILES, "a practical threshold that is no number"),
    Case("38.2", D + " --min-gain 0.01", "--min-gain is the practical threshold of an effect on absolute poses",
         {"m.csv": GOOD}, "the threshold of absolute poses given with deflection data"),
    # 40.6: choosing faces (linkfea faces, the nearest faces of a selector that finds none)
    Case("40.6", "linkfea compute s.stl --base plane:x=1 --tip plane:x=100 --out o/r.json", "base selector "
         "plane:1,0,0,1,0,0,tol=0.01 finds no face; nearest: plane:x=0 (plane, 200 mm^2, 1 mm away)",
         {"s.stl": stl(BAR)}, "a 100 x 20 x 10 bar; the base plane 1 mm off its end face", number=440),
    Case("40.6", "linkfea faces bar", "bar: linkfea faces reads a STEP file or an STL/OBJ/PLY surface",
         note="a cad/ script (it names its own faces)"),
    Case("40.6", "linkfea faces s.stl --preview p.png", "--preview draws the base and the tip: give --base and --tip "
         "too", {"s.stl": stl(BAR)}, "a preview without the faces to colour"),
    Case("40.6", "linkfea faces s.stl --base plane:x=0 --tip plane:x=100 --preview p.png", "--preview p.png exists "
         "and is not a preview linkfea wrote; it is never overwritten", {"s.stl": stl(BAR), "p.png": "mine\n"},
         "p.png: the user's own file"),
    # 40.3: silent wrong answers, units and ranges
    Case("40.3", "vjm calibrate r.yaml d.csv --out o", "joint j1 = 85.94 is beyond 2 pi rad (one turn): degrees where radians are meant?", {**X_FILES, "d.csv": _arm_poses(180 / 3.141592653589793)},
         "d.csv: the joints in degrees", number=400),
    Case("40.3", "vjm calibrate r.yaml m.csv --out o", "points in metres", {**X_FILES, "m.csv": _arm_poses(p_scale=1e-3)},
         "m.csv: the points in metres"),
    Case("40.3", "vjm calibrate r.yaml p.csv --columns c.yaml --out o", "joint j1 is revolute (rad), but its column is "
         "mapped in mm", {**X_FILES, "c.yaml": "columns:\n  j1: [j1, mm]\n  j2: [j2, rad]\n  l2.x: l2.x\n  l2.y: l2.y\n"
                                              "  l2.z: l2.z\n"}, "c.yaml maps the revolute joint j1 in mm"),
    Case("40.3", "vjm calibrate r.yaml p.csv --columns c.yaml --out o", "radians mapped as deg",
         {**X_FILES, "c.yaml": "columns:\n  j1: [j1, deg]\n  j2: [j2, deg]\n  l2.x: l2.x\n  l2.y: l2.y\n  l2.z: l2.z\n"},
         "c.yaml maps the radian columns as deg"),
    Case("40.3", "vjm calibrate r.yaml p.csv --out o --frame l2 --frame l2", "--frame l2 is given twice", X_FILES,
         "X_FILES: a two-joint arm whose point l2 runs on a circle of 300 mm, and 40 exact poses of it"),
    Case("40.3", "vjm diagnose r.yaml p.csv --out o --folds 1000000", "at most 50, got 1000000", X_FILES, "X_FILES"),
    Case("40.3", "vjm calibrate r.yaml s.csv --out o", "the data hold 1 distinct pose (60 rows)",
         {**X_FILES, "s.csv": "j1,j2,l2.x,l2.y,l2.z\n" + "0.1,0.2,1598,30,200\n" * 60}, "s.csv: 60 copies of one row"),
    Case("40.3", "vjm calibrate r.yaml h.csv --out o", "column 'l2.x' appears twice in the header (columns 3 and 6)",
         {**X_FILES, "h.csv": _arm_poses(header="j1,j2,l2.x,l2.y,l2.z,l2.x", extra=",0")}, "h.csv: two columns l2.x"),
    Case("40.3", "vjm simulate r.yaml --out s.csv --effect offset:j2=0.1,j2=0.2", "offset:j2 is given twice (0.1 and "
         "0.2)", X_FILES, "X_FILES"),
    Case("40.3", "vjm stiffness r.yaml --q 0,0", "links add up to 632.5 m from its base to a frame, beyond 100 m",
         _xrobot("", ARM_X.replace('xyz="0.3 0 0.1"', 'xyz="300 0 100"')), "r.urdf: ARM_X written in millimetres"),
    Case("40.3", "vjm stiffness d.yaml --q 0,0,0", "below 5 mm: lengths in metres where millimetres are meant",
         {"d.yaml": DH_METRES}, "d.yaml: the Puma 560's first three DH rows in metres"),
    Case("40.3", "vjm stiffness r.yaml --q 0,0", "has magnitude 9810 m/s^2, not within 5% of 9.80665 (mm/s^2?",
         _xrobot("gravity: [0, 0, -9810]\n"), "r.yaml: gravity: [0, 0, -9810]"),
    Case("40.3", "vjm stiffness r.yaml --q 0,0", "masses.l2.mass must be in [0, 100000] kg, got 1e+300",
         _xrobot("masses: {l2: {mass: 1.0e+300, com: [0, 0, 0]}}\n"), "r.yaml: a point mass of 1e300 kg"),
    Case("40.3", "vjm stiffness r.yaml --q 0,0", "payload.mass must be in [0, 100000] kg, got 1e+300",
         _xrobot("payload: {frame: l2, mass: 1.0e+300}\n"), "r.yaml: a payload of 1e300 kg"),
    Case("40.3", "vjm stiffness r.yaml --q 0,0", "joints.j1.stiffness must be at least 1 N mm/rad",
         {"r.yaml": ROBOT.replace("1.0e+8", "1.0e-300"), "r.urdf": ARM_X}, "r.yaml: j1's stiffness 1e-300"),
    Case("40.3", "vjm stiffness r.yaml --q 0,0", "<inertia> of link 'l1': ixx must be 1 finite number, got 'nan'",
         _xrobot("", ARM_X.replace('ixx="1"', 'ixx="nan"', 1)), "r.urdf: ixx=\"nan\" in l1's inertial"),
    Case("40.3", "vjm stiffness d.yaml --q 0,0,0", "dh.joints[0].alpha: 90 rad is beyond one turn: degrees? write it "
         "as 90*deg", {"d.yaml": DH_METRES.replace("0.6604", "660.4").replace("0.4318", "431.8").replace(
             "alpha: pi/2, d", "alpha: 90, d")}, "d.yaml: a DH row with alpha: 90"),
    Case("40.3", "vjm stiffness r.yaml --q 0,0", "home: j1 = 90 is beyond 2 pi rad (one turn): degrees where radians are meant?",
         _xrobot("home: [90, -45]\n"), "r.yaml: home: [90, -45] (degrees)"),
    Case("40.3", "vjm compensate {ur10} t.csv --out c.csv --seed 0,-69,86,-107,-90,0", "--seed: shoulder_lift_joint = "
         "69 is beyond 2 pi rad", {"t.csv": TARGET}, "the seed in degrees"),
    Case("40.3", "vjm compensate {ur10} t.csv --out c.csv", "a rotation vector of 180 rad (rx,ry,rz = 180, 0, 0), "
         "beyond one turn", {"t.csv": "x,y,z,rx,ry,rz\n884,164,436,180,0,0\n"}, "t.csv: a target with rx = 180"),
    Case("40.3", "vjm compensate {ur10} t.csv --out c.csv", "t.csv: column 'x' appears twice in the header",
         {"t.csv": "x,y,z,x\n884,164,436,0\n"}, "t.csv: two columns x"),
    Case("40.3", "vjm stiffness r.yaml --q 0,0", "tools: 'base' is fixed to the robot's base",
         _xrobot("tools: [base]\n"), "r.yaml: tools: [base], the URDF's root link"),
    # 40.4: tracebacks and the URDF parser's lines where one line is promised
    Case("40.4", "vjm stiffness r.yaml --q 0,0", "joint 'j1': axis xyz='0 0 0' is zero",
         _xrobot("", ARM_X.replace('<axis xyz="0 0 1"/>', '<axis xyz="0 0 0"/>', 1)), "r.urdf: an axis 0 0 0"),
    Case("40.4", "vjm stiffness r.yaml --q 0,0", "<origin> of joint 'j1': xyz='1e308 0 0.1' is beyond 10000",
         _xrobot("", ARM_X.replace('xyz="0.3 0 0.1"', 'xyz="1e308 0 0.1"', 1)), "r.urdf: an origin at 1e308 m"),
    Case("40.4", "vjm calibrate r.yaml g.csv --out o", "sigmas must be at least 1e-06 mm",
         {**X_FILES, "g.csv": _arm_poses(header="j1,j2,l2.x,l2.y,l2.z,l2.sigma", extra=",1e-300")},
         "g.csv: a sigma of 1e-300 mm"),
    Case("40.4", "vjm calibrate r.yaml b.csv --out o", "beyond 1e+06 mm (1 km)",
         {**X_FILES, "b.csv": _arm_poses(p_scale=1e300)}, "b.csv: the points times 1e300"),
    Case("40.4", "vjm calibrate r.yaml p.csv --columns c.yaml --out o", "no two consecutive ones the same",
         {**X_FILES, "c.yaml": "rotation: euler_XXY\ncolumns:\n  j1: j1\n"}, "c.yaml: rotation: euler_XXY"),
    Case("40.4", "vjm stiffness r.yaml --q 0,0", "<limit> of joint 'j1': lower must be 1 finite number, got 'nan'",
         _xrobot("", ARM_X.replace('lower="-2"', 'lower="nan"', 1)), "r.urdf: a limit lower=\"nan\""),
    Case("40.4", "vjm stiffness r.yaml --q 0,0", "<origin> of joint 'j1': rpy must be 3 finite numbers, got 'inf 0 0'",
         _xrobot("", ARM_X.replace('xyz="0.3 0 0.1"', 'xyz="0.3 0 0.1" rpy="inf 0 0"', 1)), "r.urdf: an origin rpy=\"inf 0 0\""),
    Case("40.4", "vjm stiffness r.yaml --q 0,0", "joint 'j1': a revolute joint needs <limit",
         _xrobot("", ARM_X.replace('<limit lower="-2" upper="2" effort="1" velocity="1"/>', "", 1)),
         "r.urdf: a revolute joint without <limit>"),
    Case("40.4", "vjm stiffness r.yaml --q 0,0", "two links named 'l2'",
         _xrobot("", ARM_X.replace("</robot>", '<link name="l2"/></robot>')), "r.urdf: link l2 twice"),
    Case("40.4", "vjm stiffness r.yaml --q 0,0", "2 root links (base, x)",
         _xrobot("", ARM_X.replace("</robot>", '<link name="x"/></robot>')), "r.urdf: a link no joint holds"),
    Case("40.4", "vjm stiffness r.yaml --q 0,0", "the root element is <model>; a URDF's is <robot>",
         _xrobot("", ARM_X.replace("<robot ", "<model ").replace("</robot>", "</model>")), "r.urdf: a <model> root"),
    Case("40.4", "vjm stiffness r.yaml --q 0,0", "joint 'j4': mimics joint 'j3', itself a mimic",
         _xrobot("", _urdf(_joint("j1", "base", "l1") + _joint("j2", "l1", "l2") + _joint("j3", "l2", "l3").replace(
             "<axis", '<mimic joint="j2"/><axis') + _joint("j4", "l3", "l4").replace("<axis", '<mimic joint="j3"/><axis'),
             ("base", "l1", "l2", "l3", "l4"))), "r.urdf: a mimic of a mimic"),
    Case("40.4", "vjm stiffness r.yaml --q 0,0", "a kinematic cycle: links b <- a <- b (joints j3, j4)",
         _xrobot("", ARM_X.replace("</robot>", '<link name="a"/><link name="b"/>' + _joint("j3", "a", "b", "fixed")
                                   + _joint("j4", "b", "a", "fixed") + "</robot>")), "r.urdf: links a and b each other's parent"),
    Case("40.4", "vjm stiffness r.yaml --q 0,0", "joint 'j2': link 'l2' is both its parent and its child",
         _xrobot("", ARM_X.replace('<parent link="l1"/><child link="l2"/>', '<parent link="l2"/><child link="l2"/>'))
         , "r.urdf: a joint whose parent is its child"),
    # 38.0: a DH table's named frames (a calibrated marker) are fixed to a frame of the table
    Case("38.0", "vjm stiffness d.yaml --q 0", "dh.frames.m.at: no frame 'link7'; frames: tool, link1",
         {"d.yaml": "dh:\n  joints:\n    - {name: a, a: 100}\n  frames:\n    m: {at: link7}\n"},
         "a DH table whose frame m is fixed to a frame it does not have"),
    # 39.7: vjm design refuses a bad spec before any FEA
    Case("39.7", "vjm design s.yaml --out o", "parallelogram_bar.py has no parameter 'thickness'",
         {"s.yaml": DESIGN.format(free="{thickness: [1, 2]}", rest="")}, "s.yaml: a free parameter the script lacks"),
    Case("39.7", "vjm design s.yaml --out o", "the bounds [24, 8] are reversed",
         {"s.yaml": DESIGN.format(free="{width: [24, 8]}", rest="")}, "s.yaml: width: [24, 8]"),
    Case("39.7", "vjm design s.yaml --out o", "does not build at the corner boss_height=20, width=30, height=8",
         {"s.yaml": DESIGN.format(free="{width: [8, 30], height: [8, 16]}", rest="")},
         "s.yaml: width up to 30 mm, wider than the 24 mm bosses"),
    Case("39.7", "vjm design s.yaml --out o", "constraint sag_max: a parallel model cannot give it",
         {"s.yaml": DESIGN.format(free="{width: [8, 24]}", rest="").replace("k_tran_max: 0.015", "sag_max: 0.5")},
         "s.yaml: a self-weight sag limit on a parallel machine"),
    Case("39.7", "vjm design s.yaml --out o", "budget: 3 runs is below the search's minimum of 4",
         {"s.yaml": DESIGN.format(free="{width: [8, 24]}", rest="budget: 3\n")}, "s.yaml: budget: 3"),
    Case("39.7", "vjm design s.yaml --out o", "has no link 'arm'; its links: foot, leg",
         {"s.yaml": DESIGN.format(free="{width: [8, 24]}", rest="").replace("  leg:", "  arm:")},
         "s.yaml: a link named arm"),
    Case("39.7", "vjm design s.yaml --out o --targets 0.01,x", "--targets expects k_tran_max limits",
         {"s.yaml": DESIGN.format(free="{width: [8, 24]}", rest="")}, "a target that is not a number"),
    Case("39.7", "vjm design s.yaml --out o --seed -1", "--seed must be an integer >= 0",
         {"s.yaml": DESIGN.format(free="{width: [8, 24]}", rest="")}, "a negative seed"),
    Case("39.7", "vjm design s.yaml --out o", "the machine's leg is 310.0 mm long",
         {"s.yaml": BEAM_DESIGN.format(beam="{section: rect, length: 31, material: aluminium}",
                                       free="{width: [8, 24]}")}, "s.yaml: a leg beam 31 mm long on the 310 mm leg"),
    Case("39.7", "vjm design s.yaml --out o", "a rect beam frees its section's dimensions (width, height)",
         {"s.yaml": BEAM_DESIGN.format(beam="{section: rect, length: 310, material: aluminium}",
                                       free="{diameter: [8, 24]}")}, "s.yaml: a rectangle's diameter freed"),
    Case("39.7", "vjm design s.yaml --out o", "q[0] = -120 of joint 'shoulder_pan_joint' is outside its limits",
         {"s.yaml": "machine: " + str(PLACES["ur10"]) + "\nlinks:\n  forearm:\n    beam: {section: tube, length: 572.3, "
          "material: aluminium, inner_diameter: 40}\n    free: {diameter: [60, 130]}\nconstraints: {sag_max: 1.5}\n"
          "joints: {shoulder_pan_joint: [-120, 120]}\n"}, "s.yaml: a joint range in degrees"),
    # 40.3: --folds bounded wherever it is taken: at most 50, and no more than the postures or rows held out
    Case("40.3", "vjm diagnose {puu} m.csv --out rep --folds 1000000", "--folds must be a whole number in [2, 50], "
         "got 1000000", {"m.csv": GOOD}, number=480),
    Case("40.3", "vjm diagnose {puu} m.csv --out rep --folds 2", "--folds 2: the data hold 1 posture, and each fold "
         "holds out at least one: too few to cross-validate", {"m.csv": GOOD}),
    Case("40.3", "vjm calibrate r.yaml p.csv --out o --folds 41", "--folds 41: the data hold 40 rows", X_FILES,
         "X_FILES (40 poses)"),
]


# ------------------------------------------------------------------ running a case

def _snapshot(folder: Path) -> dict:
    """Size and time of each file and link; a folder's presence only (a probe for writability touches its time)."""
    return {str(p.relative_to(folder)): "folder" if p.is_dir() and not p.is_symlink()
            else (p.lstat().st_size, p.lstat().st_mtime_ns) for p in folder.rglob("*")}


def write_files(case: Case, folder: Path) -> None:
    enc = case.files.get("encoding", "utf-8")
    for name, text in case.files.items():
        if name != "encoding":
            (folder / name).parent.mkdir(parents=True, exist_ok=True)
            (folder / name).write_bytes(text.encode(enc))
    for name, target in case.links.items():
        (folder / name).symlink_to(target)


def run(case: Case, folder: Path) -> Outcome:
    """Run ``case`` in-process in ``folder`` (made empty by the caller)."""
    from linkfea.cli import main as linkfea_main
    from vjm.cli import main as vjm_main

    folder = Path(folder)
    write_files(case, folder)
    before = _snapshot(folder)
    argv = case.argv
    main = {"linkfea": linkfea_main, "vjm": vjm_main}[argv[0]]
    err, out = io.StringIO(), io.StringIO()
    cwd = os.getcwd()
    os.chdir(folder)
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
            try:
                status = main(argv[1:])
            except SystemExit as exc:  # a command that exits by itself
                status = exc.code if isinstance(exc.code, int) else 1
    finally:
        os.chdir(cwd)
    after = _snapshot(folder)
    changed = sorted(k for k in set(before) | set(after) if before.get(k) != after.get(k))
    return Outcome(status, err.getvalue(), out.getvalue(), changed)


def doubled_phrase(text: str, n: int = 6) -> str | None:
    """A run of ``n`` words that occurs twice in ``text`` (a message that repeats itself), or None."""
    words = text.split()
    seen = set()
    for i in range(len(words) - n + 1):
        g = " ".join(words[i:i + n])
        if g in seen:
            return g
        seen.add(g)
    return None
