"""Triangle surfaces at default settings, and what a computation says by default: the interface facets of
a face that runs smoothly into a fillet, the concave edges of a triangle solid, the default material,
and progress on stderr."""
import numpy as np
import pytest
from brackets import BASE, BASE_AREA, TIP, TIP_AREA, bracket_solid

from linkfea.cad import build_link
from linkfea.cad.surface import read_surface
from linkfea.mesh.gmsh import concave_edges
from linkfea.mesh.linkmesh import tri_areas_normals
from linkfea.mesh.pytetwild import select_facets


def _stl(shape, path, angular: float = 0.1):
    import cadquery as cq

    cq.exporters.export(cq.Workplane().add(shape), str(path), tolerance=0.1, angularTolerance=angular)
    return path


@pytest.fixture(scope="module")
def bracket_stl(tmp_path_factory):
    """The filleted bracket of tests/brackets.py as a plain STL (cadquery's default tolerances)."""
    return _stl(bracket_solid(), tmp_path_factory.mktemp("stl") / "bracket.stl")


def test_interface_facets_of_an_exact_mesh_are_the_face(bracket_stl):
    """On the input triangles themselves (a mesh that follows the surface exactly) the facets taken as
    base and tip are the faces' own: 144 mm^2 each.  The fillets' first strips lie within the mesher's
    envelope of the plane and nearly parallel to it; counted in, they gave +3.3% and the area gate
    refused the STL."""
    link = build_link(str(bracket_stl), base=BASE, tip=TIP, with_block=False)
    V, F = read_surface(bracket_stl)
    env = 1e-3 * link.body.BoundingBox().DiagonalLength  # the default envelope (linkfea.mesh.DEFAULT_EPSILON)
    ttol = 0.25 * env
    for faces, area in ((link.base_faces, BASE_AREA), (link.tip_faces, TIP_AREA)):
        sel = select_facets(V, F, faces, 1.5 * env + ttol, ttol, link.body)
        assert tri_areas_normals(V, F[sel])[0].sum() == pytest.approx(area, rel=1e-9)


def test_concave_edges_of_a_triangle_solid_are_the_corners_of_the_cad(tmp_path):
    """An L with a sharp inner corner and one with a filleted inner corner, as STLs with coarse facets
    (0.3 rad): the triangle solid has the CAD's concave edges (one corner, none), not the fillet's kinks."""
    import cadquery as cq

    def ell(r):
        L = cq.Workplane("XY").box(40, 10, 10, centered=False).union(
            cq.Workplane("XY").box(10, 10, 40, centered=False))
        return (L.edges("|Y").edges(cq.selectors.NearestToPointSelector((10, 5, 10))).fillet(r) if r else L).val()

    for r, corners in ((0.0, 1), (3.0, 0)):
        solid = ell(r)
        assert len(concave_edges(solid)) == corners  # the CAD's
        link = build_link(str(_stl(solid, tmp_path / f"l{r:g}.stl", angular=0.3)), base="plane:x=40",
                          tip="plane:z=40", with_block=False)
        assert len(link.body.Faces()) > (20 if r else 10)  # triangles, each a face
        found = concave_edges(link.body)
        assert len(found) == corners
        if corners:
            assert np.allclose(found[0].Center().toTuple(), (10.0, 5.0, 10.0), atol=1e-6)


@pytest.fixture(scope="module")
def box_step(tmp_path_factory):
    import cadquery as cq

    path = tmp_path_factory.mktemp("step") / "box.step"
    cq.exporters.export(cq.Workplane("XY").box(60, 10, 10, centered=False), str(path))
    return path


def test_default_material_and_progress_are_said(box_step, capsys):
    """A STEP computed without a material says, in one line, that it is steel by default; progress lines
    reach stderr unless turned off (progress=False); a material given is not remarked on."""
    from linkfea import ComputeOptions, compute

    opts = ComputeOptions(base="plane:x=0", tip="plane:x=60", mesh_size=5.0)
    res = compute(str(box_step), opts)
    err = capsys.readouterr().err.splitlines()
    assert res.material.name == "steel"
    assert sum("material: steel (E = 210000 MPa, nu = 0.3) by default" in ln for ln in err) == 1
    assert any(ln.startswith("linkfea [") and "meshing" in ln for ln in err)
    res = compute(str(box_step), ComputeOptions(base="plane:x=0", tip="plane:x=60", mesh_size=5.0,
                                                material="aluminium"), progress=False)
    assert res.material.name == "aluminium" and capsys.readouterr().err == ""
    lines: list = []
    compute("bar", ComputeOptions(mesh_size=8.0), progress=lines.append)
    assert lines and not any("material" in ln for ln in lines)  # a script names its own


def test_a_mesh_of_slivers_is_said():
    """A mesh whose tets are mostly slivers (gmsh on an exported STL) gets a warning; a sound one none.
    Regular tets have radius ratio 1, a tet flattened to 1e-4 of its height about 1e-4."""
    from linkfea.mesh.linkmesh import radius_ratio, sliver_warning

    P = np.array([[0, 0, 0], [1, 0, 0], [0.5, np.sqrt(3) / 2, 0], [0.5, np.sqrt(3) / 6, np.sqrt(2 / 3)],
                  [0.5, np.sqrt(3) / 6, 1e-4 * np.sqrt(2 / 3)]])
    T = np.array([[0, 1, 2, 3], [0, 1, 2, 4]])
    rr = radius_ratio(P, T)
    assert rr[0] == pytest.approx(1.0, rel=1e-9) and rr[1] < 1e-3
    for tets, warned in (([0] * 99, False), ([0] * 90 + [1] * 10, False), ([0] * 60 + [1] * 40, True)):
        q = {"n_poor_tets": int(np.sum(rr[tets] < 0.1)), "radius_ratio_min": float(rr[tets].min())}
        msg = sliver_warning("l", q, len(tets), "gmsh")
        assert bool(msg) is warned
        if warned:
            assert msg.startswith("l: 40% of the mesh's tets are slivers") and "--mesher pytetwild" in msg
