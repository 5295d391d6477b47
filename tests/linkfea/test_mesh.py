"""Meshing with pytetwild: block tagging, envelope facet selection, cache.

The references are CAD quantities (areas and volumes computed by OCC from the
exact BRep), so they are independent of the mesher.
"""
import dataclasses

import numpy as np
import pytest

from linkfea.cad import build_link
from linkfea.cad.selectors import parse_selector
from linkfea.mesh import mesh_link
from linkfea.mesh.linkmesh import tet_faces, tet_volumes, tri_areas_normals
from linkfea.mesh.pytetwild import select_facets
from linkfea.runtime.errors import LinkFeaError

H = 5.0


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return tmp_path_factory.mktemp("meshes")


@pytest.fixture(scope="module")
def bar():
    return build_link("bar")


@pytest.fixture(scope="module")
def block_mesh(bar, cache):
    return mesh_link(bar, H, with_block=True, cache_dir=cache, mesher="pytetwild")


def test_tets_positive_and_all_points_used(block_mesh):
    m = block_mesh
    assert np.all(tet_volumes(m.points, m.tets) > 0)
    assert np.array_equal(np.unique(m.tets), np.arange(m.n_nodes))
    # Mesh volume vs CAD volume (200x20x10 bar + 10 mm block): within the envelope's effect.
    assert tet_volumes(m.points, m.tets).sum() == pytest.approx(200 * 20 * 10 + 10 * 20 * 10, rel=5e-3)


def test_block_cells_match_the_cad_block_volume(bar, block_mesh):
    """Centroid tagging: block cells fill the CAD block (20x10x10 mm = 2000 mm^3) within 2%."""
    m = block_mesh
    vb = tet_volumes(m.points, m.tets[m.block]).sum()
    assert vb == pytest.approx(bar.block.Volume(), rel=0.02)
    # No block cell on the body side of the interface plane, none of the body beyond it.
    cx = m.points[m.tets].mean(axis=1)[:, 0]
    assert np.all(cx[m.block] > 200.0) and np.all(cx[~m.block] < 200.0)


def test_base_facets_cover_the_whole_base_face(block_mesh):
    """The envelope fact: base facets sum to the CAD face area 20x10 = 200 mm^2 within 1%.

    fTetWild moves boundary vertices within epsilon x diagonal; facets selected
    with a tight tolerance would miss a large part of the clamp.
    """
    m = block_mesh
    A, n = tri_areas_normals(m.points, m.base_facets)
    assert A.sum() == pytest.approx(200.0, rel=0.01)
    assert np.all(n[:, 0] < -0.8)  # outward normals of the base point to -x
    assert np.all(np.abs(m.points[np.unique(m.base_facets), 0]) <= 1.5 * m.envelope + 1e-9)


def test_tip_facets_are_the_body_block_interface(block_mesh):
    m = block_mesh
    A, _ = tri_areas_normals(m.points, m.tip_facets)
    assert A.sum() == pytest.approx(200.0, rel=0.01)
    uniq, owners, _ = tet_faces(m.tets)
    key = {tuple(f) for f in np.sort(m.tip_facets, axis=1)}
    rows = [i for i, f in enumerate(map(tuple, uniq)) if f in key]
    o = owners[rows]
    assert np.all(o[:, 1] >= 0) and np.all(m.block[o[:, 0]] != m.block[o[:, 1]])


def test_rigid_mesh_has_no_block_and_boundary_tip_facets(bar, cache):
    m = mesh_link(bar, H, with_block=False, cache_dir=cache, mesher="pytetwild")
    assert not m.block.any()
    A, n = tri_areas_normals(m.points, m.tip_facets)
    assert A.sum() == pytest.approx(200.0, rel=0.01)
    assert np.all(n[:, 0] > 0.8)
    assert np.intersect1d(m.tip_facets, m.base_facets).size == 0


def test_cache_returns_identical_arrays(bar, block_mesh, cache):
    again = mesh_link(bar, H, with_block=True, cache_dir=cache, mesher="pytetwild")
    assert again.cache_key == block_mesh.cache_key
    for f in ("points", "tets", "block", "base_facets", "tip_facets"):
        assert np.array_equal(getattr(again, f), getattr(block_mesh, f)), f
    other = mesh_link(bar, 2 * H, with_block=True, cache_dir=cache, mesher="pytetwild")
    assert other.cache_key != block_mesh.cache_key
    assert len(list(cache.glob("*.npz"))) >= 2


def test_foot_base_flange_is_fully_clamped(cache):
    """The foot's flange face (70x60 mm = 4200 mm^2) is covered within 1% by the envelope selection.

    On this part fTetWild moves flange vertices off the exact plane: selecting
    with a tight tolerance (1e-9 mm) finds less area (measured here: about 6%
    less), which would soften the clamp.
    """
    link = build_link("orthoglide_foot")
    m = mesh_link(link, 6.0, with_block=False, cache_dir=cache, mesher="pytetwild")
    A = tri_areas_normals(m.points, m.base_facets)[0].sum()
    assert A == pytest.approx(4200.0, rel=0.01)
    uniq, owners, oriented = tet_faces(m.tets)
    bnd = oriented[owners[:, 1] < 0]
    tight = select_facets(m.points, bnd, link.base_faces, 1e-9, 0.25 * m.envelope)
    assert tri_areas_normals(m.points, bnd[tight])[0].sum() <= A + 1e-9


def test_mesh_level_interface_errors(bar, cache):
    nothing = dataclasses.replace(bar, base=parse_selector("plane:x=77"))
    with pytest.raises(LinkFeaError, match="finds no face"):
        mesh_link(nothing, 10.0, with_block=False, cache_dir=cache, mesher="pytetwild")
    same = dataclasses.replace(bar, base=parse_selector("plane:x=200"))
    with pytest.raises(LinkFeaError, match="overlap"):
        mesh_link(same, 10.0, with_block=False, cache_dir=cache, mesher="pytetwild")
    # the ranges of linkfea.options, in their one message format
    with pytest.raises(LinkFeaError, match=r"^mesh_size must be > 0 mm, got -1$"):
        mesh_link(bar, -1.0, cache_dir=cache, mesher="pytetwild")
    with pytest.raises(LinkFeaError, match=r"^mesh_size must be a finite number > 0 mm"):
        mesh_link(bar, float("nan"), cache_dir=cache, mesher="pytetwild")
    with pytest.raises(LinkFeaError, match=r"^envelope must be in \(0, 0.1\), got 0.2$"):
        mesh_link(bar, 10.0, epsilon=0.2, cache_dir=cache, mesher="pytetwild")


def test_quality_report(block_mesh):
    q = block_mesh.quality
    assert 0 < q["radius_ratio_min"] <= q["radius_ratio_mean"] <= 1
    assert q["edge_min"] <= q["edge_mean"] <= q["edge_max"]
    assert abs(q["volume_error"]) < 5e-3 and abs(q["base_area_error"]) < 0.01


def test_sizing_field_refines_only_near_small_curved_faces():
    """A round bar of radius 4 at H = 4 would get ~6 edges around: the field asks for
    2 pi r / 8 = pi mm on the surface, growing by GRADING per mm, capped at H; a prism needs none."""
    from linkfea.mesh.pytetwild import GRADING, sizing_field

    H = 4.0
    assert sizing_field([build_link("bar").body], H, 0.01) is None
    round_bar = build_link("bar", {"section": "circle", "length": 40, "diameter": 8})
    pts, tets, vals = sizing_field([round_bar.body], H, 0.01)
    assert tets.shape[1] == 4 and len(vals) == len(pts) and np.all(vals <= H)
    r = np.linalg.norm(pts[:, 1:], axis=1)
    inside = (pts[:, 0] > 1) & (pts[:, 0] < 39)
    d = np.abs(r - 4.0)
    expect = np.minimum(H, np.pi + GRADING * d)
    # Distances are to the tessellated cylinder (chord error ~ 0.01 mm here).
    np.testing.assert_allclose(vals[inside], expect[inside], atol=0.01)
    assert vals.min() < np.pi + GRADING * d.min() + 0.01 < H


def test_sizing_field_along_interface_borders():
    """pytetwild's area-gate refinement: the field is edge_size on the edges of the interface
    faces (their samples are background vertices) and edge_size + GRADING x distance elsewhere,
    capped at H: checked against the distance to the base face's 4 border lines (x = 0,
    y = +-10, z = +-5 on the 200 x 20 x 10 bar)."""
    from linkfea.mesh.pytetwild import GRADING, sizing_field

    bar = build_link("bar")
    H, h = 4.0, 0.5
    pts, tets, vals = sizing_field([bar.body], H, 0.01, bar.base_faces[0].Edges(), h)
    assert tets.shape[1] == 4 and tets.max() < len(pts) and len(vals) == len(pts)
    x, y, z = pts.T
    # distance to the rectangle's boundary lines in the plane x = 0
    dy = np.maximum(np.abs(y) - 10.0, 0.0)
    dz = np.maximum(np.abs(z) - 5.0, 0.0)
    inside = (np.abs(y) <= 10) & (np.abs(z) <= 5)
    d_in = np.minimum(10.0 - np.abs(y), 5.0 - np.abs(z))
    d_plane = np.where(inside, d_in, np.hypot(dy, dz))
    d = np.hypot(x, d_plane)
    np.testing.assert_allclose(vals, np.minimum(H, h + GRADING * d), atol=0.25 * h * GRADING + 1e-9)
    on_edge = d < 1e-9
    assert on_edge.sum() >= 4 * 10 and np.all(vals[on_edge] == h)
