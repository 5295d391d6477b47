"""Triangle-surface input (STL, OBJ, PLY): checks, selectors on the input triangles, and the
6x6 of an STL export of a bundled link against its CAD (gmsh path, independent mesher)."""
import os
import subprocess
import sys

import numpy as np
import pytest

from linkfea.cad import build_link
from linkfea.runtime.errors import LinkFeaError


@pytest.fixture(scope="module")
def bar_stl(tmp_path_factory):
    import cadquery as cq

    path = tmp_path_factory.mktemp("stl") / "bar.stl"
    cq.exporters.export(cq.Workplane().add(build_link("bar").body), str(path))
    return path


@pytest.mark.parametrize("fmt", ["stl", "obj", "ply"])
def test_surface_formats_selectors_and_frame(bar_stl, fmt):
    """The 200 x 20 x 10 bar read back from STL, OBJ and PLY: volume 40000 mm^3, the base
    selector picks the input triangles of x = 0 (200 mm^2), the frame sits at the tip centroid."""
    import trimesh

    path = bar_stl if fmt == "stl" else bar_stl.with_suffix(f".{fmt}")
    if fmt != "stl":
        trimesh.load(str(bar_stl)).export(str(path))
    link = build_link(str(path), base="plane:x=0", tip="plane:x=200", with_block=True)
    assert link.body.Volume() == pytest.approx(40000.0, rel=1e-9)
    assert sum(f.Area() for f in link.base_faces) == pytest.approx(200.0, rel=1e-9)
    assert all(len(f.Edges()) == 3 for f in link.base_faces)
    np.testing.assert_allclose(link.frame.origin, [200.0, 0.0, 0.0], atol=1e-9)
    assert link.block.Volume() == pytest.approx(200.0 * 0.5 * np.sqrt(200.0), rel=1e-9)


def test_stl_of_the_bar_gives_the_cad_compliance(bar_stl, tmp_path):
    """pytetwild on the STL triangles vs gmsh on the CAD: within 1% entry by entry (relative to
    sqrt(Cii Cjj)); the interfaces are exact, so the area gate passes without refinement."""
    from linkfea import ComputeOptions
    from linkfea.pipeline import compute

    s = compute(str(bar_stl), ComputeOptions(base="plane:x=0", tip="plane:x=200", mesh_size=5.0), cache_dir=tmp_path)
    assert s.mesh.mesher == "pytetwild"
    c = compute("bar", ComputeOptions(mesh_size=5.0))
    assert c.mesh.mesher == "gmsh"
    d = np.sqrt(np.outer(np.diag(c.compliance), np.diag(c.compliance)))
    assert np.abs((s.compliance - c.compliance) / d).max() <= 0.01


def test_open_stl_is_one_error_line_and_no_file(bar_stl, tmp_path, monkeypatch):
    import trimesh

    tm = trimesh.load(str(bar_stl))
    open_path = tmp_path / "open.stl"
    trimesh.Trimesh(tm.vertices, tm.faces[1:], process=False).export(str(open_path))
    with pytest.raises(LinkFeaError, match="not watertight"):
        build_link(str(open_path), base="plane:x=0", tip="plane:x=200")
    out = tmp_path / "o" / "r.json"
    env = dict(os.environ, LINKFEA_CACHE_DIR=str(tmp_path / "cache"))
    # the open surface through a real `linkfea` process (its exit status), the other two in process as the
    # bad-input table runs its cases (``main`` returns the status the process would end with)
    p = subprocess.run([sys.executable, "-m", "linkfea", "compute", str(open_path), "--base", "plane:x=0", "--tip",
                        "plane:x=200", "--out", str(out)], capture_output=True, text=True, env=env, timeout=300)
    lines = [ln for ln in p.stderr.splitlines() if ln.strip()]
    assert p.returncode == 2 and len(lines) == 1 and lines[0].startswith("error: "), p.stderr
    assert not out.parent.exists() or not any(out.parent.iterdir())
    import shlex

    from bad_inputs import Case, run

    monkeypatch.setenv("LINKFEA_CACHE_DIR", env["LINKFEA_CACHE_DIR"])
    for args in ([str(bar_stl)], [str(tmp_path / "missing.ply"), "--base", "plane:x=0", "--tip", "plane:x=200"]):
        res = run(Case("", shlex.join(["linkfea", "compute", *args, "--out", str(out)]), ""), tmp_path)
        lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
        assert res.status == 2 and len(lines) == 1 and lines[0].startswith("error: "), res.stderr
        assert not out.parent.exists() or not any(out.parent.iterdir())


@pytest.mark.parametrize("triangles, message", [
    ("two", r"^s.stl: expected one body, found 2 separate closed surfaces"),
    ("crossing", r"^s.stl: expected one body, found 2 separate closed surfaces"),
    ("flat", r"^s.stl: the surface encloses no volume"),
    ("nan", r"^s.stl: a vertex has a non-finite coordinate \(nan, 0, 0\), in triangle 1; "),
])
def test_surface_that_is_not_one_solid_body_is_refused_first(tmp_path, triangles, message):
    """Two disjoint boxes (40,000 mm^3, of which one box would have been kept), two crossing boxes, a
    watertight surface of no volume, a NaN vertex: each refused by what it is, before any other check
    and without a warning from trimesh (warnings are errors here)."""
    import warnings

    from bad_inputs import BAR, FLAT, _box, stl

    from linkfea.cad.surface import read_surface

    tris = {"two": BAR + _box((200, 0, 0), (300, 20, 10)), "crossing": BAR + _box((40, -40, 0), (60, 60, 10)),
            "flat": FLAT, "nan": [((float("nan"), 0, 0),) + BAR[0][1:]] + BAR[1:]}[triangles]
    path = tmp_path / "s.stl"
    path.write_text(stl(tris))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(LinkFeaError, match=message):
            read_surface(path)
    path.write_text(stl(BAR))
    V, F = read_surface(path)  # the box alone: 100 x 20 x 10 mm
    assert abs(np.einsum("ij,ij->i", V[F[:, 0]], np.cross(V[F[:, 1]], V[F[:, 2]])).sum() / 6.0 - 2e4) < 1e-9
