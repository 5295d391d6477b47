"""CAD side of the link stage: scripts, parameters, selectors, STEP input.

Truth here is geometry: the volumes of prisms and the positions of faces are
known in closed form, independent of CadQuery.
"""
import math

import numpy as np
import pytest

from linkfea.cad import Box, Plane, build_link
from linkfea.cad.selectors import parse_selector, select_faces
from linkfea.cad.step import load_step, validate_solid
from linkfea.runtime.errors import LinkFeaError


@pytest.mark.parametrize("section,area", [
    ("rect", 20.0 * 10.0),
    ("circle", math.pi * 10.0**2),
    ("tube", math.pi * (10.0**2 - 6.0**2)),
])
def test_bar_is_a_valid_prism_with_the_closed_form_volume(section, area):
    """Volume = A L for the bar (A of the section), A * L_block for the block; frame at the tip centroid."""
    link = build_link("bar", {"section": section, "length": "150"})
    assert link.body.isValid() and link.block.isValid()
    assert link.body.Volume() == pytest.approx(area * 150.0, rel=1e-9)
    assert link.block.Volume() == pytest.approx(area * link.block.BoundingBox().xlen, rel=1e-9)
    assert link.block.BoundingBox().xmin == pytest.approx(150.0)
    np.testing.assert_allclose(link.frame.origin, [150.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(link.frame.axes[0], [1.0, 0.0, 0.0])
    assert len(link.base_faces) == 1 and len(link.tip_faces) == 1
    assert link.base_faces[0].Area() == pytest.approx(area, rel=1e-9)


@pytest.mark.parametrize("name", ["orthoglide_foot", "parallelogram_bar"])
def test_orthoglide_links_are_single_valid_solids_with_distinct_interfaces(name):
    link = build_link(name)
    assert len(link.body.Solids()) == 1 and link.body.isValid()
    assert link.block is not None and link.block.isValid()
    # The block touches the body only on the tip interface: no volume in common.
    assert link.block.intersect(link.body).Volume() < 1e-6 * link.block.Volume()
    assert link.base_faces and link.tip_faces
    bb = link.body.BoundingBox()
    assert 100.0 <= bb.xlen <= 400.0


def test_foot_is_not_a_beam():
    """A pocket and a rib: the volume is well below its bounding prism's and there are many faces."""
    link = build_link("orthoglide_foot")
    assert len(link.body.Faces()) > 20
    arm = link.params["arm_width"] * link.params["arm_height"] * link.params["length"]
    assert link.body.Volume() < arm


def test_foot_fillet_rounds_every_concave_edge():
    """``fillet`` (the machining radius) leaves no concave edge, and adds (1 - pi/4) r^2 per mm of
    the sharp foot's concave edges (all 90 degree corners; the ends where fillets meet add O(r^3),
    within 5% here); 0 is the sharp foot, a negative radius one error line."""
    from linkfea.mesh.gmsh import concave_edges

    sharp = build_link("orthoglide_foot", with_block=False)
    assert build_link("orthoglide_foot", {"fillet": 0}, with_block=False).body.Volume() == sharp.body.Volume()
    edges = concave_edges(sharp.body)
    r = 2.5
    rounded = build_link("orthoglide_foot", {"fillet": r}, with_block=False)
    assert rounded.body.isValid() and len(rounded.body.Solids()) == 1 and concave_edges(rounded.body) == []
    added = (1 - math.pi / 4) * r ** 2 * sum(e.Length() for e in edges)
    assert rounded.body.Volume() - sharp.body.Volume() == pytest.approx(added, rel=0.05)
    with pytest.raises(LinkFeaError, match="fillet") as exc:
        build_link("orthoglide_foot", {"fillet": -1})
    assert "\n" not in str(exc.value)


def test_parallelogram_pin_pitch():
    """Frame origin at the tip pin centre, 310 mm from the base pin centre (the base bore's centroid)."""
    link = build_link("parallelogram_bar")
    base_c = np.array(link.base_faces[0].Center().toTuple())
    np.testing.assert_allclose(np.linalg.norm(link.frame.origin - base_c), 310.0, atol=1e-6)
    assert [f.geomType() for f in link.tip_faces] == ["CYLINDER"]


@pytest.mark.parametrize("params,word", [
    ({"length": 0}, "length"),
    ({"width": -5}, "width"),
    ({"height": float("nan")}, "height"),
    ({"diameter": "inf"}, "diameter"),
    ({"material": "unobtainium"}, "unobtainium"),
    ({"lenght": 100}, "lenght"),
    ({"section": "hexagon"}, "section"),
    ({"section": "tube", "inner_diameter": 25}, "inner_diameter"),
    ({"length": "abc"}, "length"),
])
def test_bad_bar_parameters_raise_one_clear_error(params, word):
    with pytest.raises(LinkFeaError) as exc:
        build_link("bar", params)
    msg = str(exc.value)
    assert word in msg and "\n" not in msg


def test_unknown_material_override_and_unknown_script():
    with pytest.raises(LinkFeaError, match="unknown material"):
        build_link("bar", material="cheese")
    with pytest.raises(LinkFeaError, match="no link script"):
        build_link("no_such_link")


def test_selector_syntax():
    p = parse_selector("plane:x=200")
    assert p == Plane((200.0, 0.0, 0.0), (1.0, 0.0, 0.0))
    p = parse_selector("plane:0,0,5,0,0,2,tol=0.5")
    assert p.normal == (0.0, 0.0, 1.0) and p.tol == 0.5
    b = parse_selector("box:-1,-50,-50,1,50,50")
    assert b == Box((-1.0, -50.0, -50.0), (1.0, 50.0, 50.0))
    assert parse_selector(str(b)) == b and parse_selector(str(p)) == p
    assert parse_selector("box:-inf,-inf,-inf,1,inf,inf").lo[0] == -math.inf
    for bad in ["plane", "cyl:x=0", "plane:x=a", "plane:1,2,3", "box:1,2,3", "box:1,1,1,0,2,2", "plane:0,0,0,0,0,0"]:
        with pytest.raises(LinkFeaError):
            parse_selector(bad)


def test_selectors_pick_the_right_faces():
    link = build_link("bar")
    assert len(select_faces(link.body, parse_selector("plane:x=0"))) == 1
    assert len(select_faces(link.body, parse_selector("plane:y=10"))) == 1  # side face at y = width/2
    assert len(select_faces(link.body, parse_selector("box:-1,-50,-50,1,50,50"))) == 1
    assert select_faces(link.body, parse_selector("plane:x=100")) == []


def test_selector_finding_nothing_and_overlapping_interfaces_are_errors():
    with pytest.raises(LinkFeaError, match="finds no face"):
        build_link("bar", tip="plane:x=123")
    with pytest.raises(LinkFeaError, match="overlap"):
        build_link("bar", base="plane:x=200", tip="plane:x=200")
    # A base box that grabs the side faces too touches the tip face along its edges.
    with pytest.raises(LinkFeaError, match="overlap"):
        build_link("bar", base="box:-1,-50,-50,201,50,50", tip="plane:x=200")


def _export(shape, path):
    import cadquery as cq

    cq.exporters.export(cq.Workplane().add(shape), str(path))
    return path


def test_step_link_frame_and_extruded_block(tmp_path):
    """STEP bar: origin = tip face centroid (200,0,0), x = outward normal, block = tip face x 0.5 sqrt(A)."""
    bar = build_link("bar")
    step = _export(bar.body, tmp_path / "bar.step")
    link = load_step(step, parse_selector("plane:x=0"), parse_selector("plane:x=200"), with_block=True)
    np.testing.assert_allclose(link.frame.origin, [200.0, 0.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(link.frame.axes[0], [1.0, 0.0, 0.0], atol=1e-12)
    h = 0.5 * math.sqrt(200.0)
    assert link.block.Volume() == pytest.approx(200.0 * h, rel=1e-9)
    assert link.block.BoundingBox().xmin == pytest.approx(200.0)
    rigid = load_step(step, parse_selector("plane:x=0"), parse_selector("plane:x=200"), with_block=False)
    assert rigid.block is None


def test_broken_step_files_are_rejected(tmp_path):
    import cadquery as cq

    box = cq.Workplane().box(100, 10, 10, centered=(False, True, True)).val()
    shell = cq.Shell.makeShell([f for f in box.Faces() if f.Center().x < 99.0])  # tip face removed
    step = _export(shell, tmp_path / "open.step")
    with pytest.raises(LinkFeaError, match="no closed solid"):
        load_step(step, parse_selector("plane:x=0"), parse_selector("plane:x=100"))
    with pytest.raises(LinkFeaError, match="not found"):
        load_step(tmp_path / "missing.step", parse_selector("plane:x=0"), parse_selector("plane:x=100"))
    bad = tmp_path / "garbage.step"
    bad.write_text("ISO-10303-21;\nthis is not a step file\n")
    with pytest.raises(LinkFeaError):
        load_step(bad, parse_selector("plane:x=0"), parse_selector("plane:x=100"))


def test_step_solid_with_a_spherical_face_is_accepted(tmp_path):
    """A cylinder (r 10, 50 long) with a hemispherical end: a valid solid whose triangulation has a
    zero-area triangle at the sphere's pole; it loads, with the closed-form volume pi r^2 L + 2/3 pi r^3."""
    import cadquery as cq

    body = (cq.Workplane("XY").circle(10.0).extrude(50.0)
            .union(cq.Workplane("XY").workplane(offset=50.0).sphere(10.0)).val())
    step = _export(body, tmp_path / "rounded.step")
    link = load_step(step, parse_selector("plane:z=0"), parse_selector("box:-11,-11,49.9,11,11,61"),
                     with_block=False)
    assert link.body.Volume() == pytest.approx(math.pi * 100.0 * 50.0 + 2.0 / 3.0 * math.pi * 1000.0, rel=1e-3)


def test_self_intersecting_solid_is_rejected():
    """Two overlapping box shells put in one solid: valid-looking topology, intersecting faces."""
    import cadquery as cq
    from OCP.BRep import BRep_Builder
    from OCP.TopoDS import TopoDS_Solid

    a = cq.Workplane().box(100, 10, 10).val()
    b = cq.Workplane().box(100, 10, 10).translate((0, 5, 0)).val()
    builder, s = BRep_Builder(), TopoDS_Solid()
    builder.MakeSolid(s)
    builder.Add(s, a.Shells()[0].wrapped)
    builder.Add(s, b.Shells()[0].wrapped)
    with pytest.raises(LinkFeaError):
        validate_solid(cq.Solid(s), "crossed")
    validate_solid(a, "box")  # the sound one passes


def test_step_bore_tip_block_fills_the_bore(tmp_path):
    """A bore as the tip: block mode fills it with a pin (volume pi r^2 h = pi 25 x 12 mm^3)
    that touches the body on the bore only; the frame is the rigid-mode frame."""
    link = build_link("parallelogram_bar")
    step = _export(link.body, tmp_path / "leg.step")
    tip = "box:298,-8,-7,322,8,7"
    blk = load_step(step, parse_selector("box:-6,-6,-7,6,6,7"), parse_selector(tip), with_block=True)
    assert blk.block.Volume() == pytest.approx(math.pi * 25.0 * 12.0, rel=1e-9)
    assert blk.block.intersect(blk.body).Volume() <= 1e-9
    rigid = load_step(step, parse_selector("box:-6,-6,-7,6,6,7"), parse_selector(tip), with_block=False)
    assert rigid.block is None
    # A bore has no net normal: x runs from the base centroid to the tip centroid.
    np.testing.assert_allclose(rigid.frame.origin, [310.0, 0.0, 0.0], atol=1e-6)
    np.testing.assert_allclose(rigid.frame.axes[0], [1.0, 0.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(blk.frame.axes, rigid.frame.axes, atol=1e-12)


def test_block_filling_more_than_the_tip_is_an_error():
    """A blind hole selected by its wall only: the filling pin would be bonded to the hole's bottom too."""
    import cadquery as cq

    plate = cq.Workplane("XY").box(60, 20, 10, centered=(False, True, False))
    body = plate.cut(cq.Workplane("XY").workplane(offset=4).center(50, 0).circle(3).extrude(6)).val()
    from linkfea.cad.step import fill_block

    wall = [f for f in body.Faces() if f.geomType() == "CYLINDER"]
    assert len(wall) == 1
    with pytest.raises(LinkFeaError, match="touches the body"):
        fill_block(body, wall, "blind")
    bottom = [f for f in body.Faces() if f.geomType() == "PLANE" and abs(f.Center().z - 4) < 1e-9]
    assert fill_block(body, wall + bottom, "blind").Volume() == pytest.approx(math.pi * 9 * 6, rel=1e-9)


def test_tip_override_rebuilds_frame_and_block():
    """New interfaces on a script: bottom face (z = -5) clamped, top face (z = +5) as tip.
    The frame moves to the top face centroid (100, 0, 5) with x = +z (outward normal), and
    the block is the top face extruded by 0.5 sqrt(200 x 20) mm."""
    link = build_link("bar", base="plane:z=-5", tip="plane:z=5", with_block=True)
    np.testing.assert_allclose(link.frame.origin, [100.0, 0.0, 5.0], atol=1e-9)
    np.testing.assert_allclose(link.frame.axes[0], [0.0, 0.0, 1.0], atol=1e-12)
    h = 0.5 * math.sqrt(200.0 * 20.0)
    assert link.block.Volume() == pytest.approx(200.0 * 20.0 * h, rel=1e-9)
    assert link.block.BoundingBox().zmin == pytest.approx(5.0)
