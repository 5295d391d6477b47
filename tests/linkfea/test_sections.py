"""sectionproperties section constants against closed forms (issue 3, test 2)."""
import numpy as np
import pytest
from shapely import affinity
from shapely.geometry import Point, Polygon, box

from linkfea.beam.closed_form import cowper_circle, cowper_rect, rect_torsion_constant
from linkfea.beam.sections import section_constants
from linkfea.runtime.errors import LinkFeaError


def _disc(d, res=64):
    # 4 * res sides: the inscribed polygon's J is low by about (pi / 4res)^2 = 4e-5.
    return Point(0.0, 0.0).buffer(d / 2.0, quad_segs=res)


def test_circle_J_is_polar_moment():
    """Solid circle: J = Ip = pi d^4 / 32 (Saint-Venant, no warping).  Tolerance 0.5 % (issue)."""
    d = 20.0
    c = section_constants(_disc(d))
    assert c.J == pytest.approx(np.pi * d**4 / 32.0, rel=5e-3)
    assert c.Iyy == pytest.approx(np.pi * d**4 / 64.0, rel=5e-3)


def test_tube_J_is_polar_moment():
    """Tube: J = pi (D^4 - d^4) / 32.  Tolerance 0.5 %."""
    D, d = 30.0, 22.0
    c = section_constants(_disc(D).difference(_disc(d)))
    assert c.J == pytest.approx(np.pi * (D**4 - d**4) / 32.0, rel=5e-3)


@pytest.mark.parametrize("w,h", [(20.0, 10.0), (10.0, 10.0), (40.0, 4.0)])
def test_rectangle_J_matches_series_solution(w, h):
    """Rectangle: J from the warping function within 1 % of the Saint-Venant series
    J = a b^3/3 (1 - 192 b/(pi^5 a) sum tanh(n pi a/2b)/n^5) (Timoshenko & Goodier §109),
    and clearly not Iy + Iz (which overestimates J by 18 % for a square, more for flat ones)."""
    c = section_constants(box(0.0, 0.0, w, h))
    Jref = rect_torsion_constant(w, h)
    assert c.J == pytest.approx(Jref, rel=1e-2)
    assert c.Iyy + c.Izz > 1.15 * Jref


def test_rectangle_shear_area_is_cowper_kappa_at_nu0():
    """Shear area of a rectangle: sectionproperties' geometric shear area (its shear function with
    nu = 0) equals Cowper's kappa A at nu = 0, kappa = 10/12 = 5/6 (Cowper 1966, table 1), to 0.5 %.

    Cowper's kappa depends mildly on nu (0.850 at nu = 0.3); the geometric value is what the beam
    models use for arbitrary sections, so it is within 2.5 % of Cowper at nu = 0.3: that is the
    size of the approximation, not a numerical error."""
    c = section_constants(box(0.0, 0.0, 20.0, 10.0))
    for As in (c.Asy, c.Asz):
        assert As / c.area == pytest.approx(cowper_rect(0.0), rel=5e-3)
        assert As / c.area == pytest.approx(cowper_rect(0.3), rel=2.5e-2)


def test_circle_shear_area_is_cowper_kappa_at_nu0():
    """Solid circle: kappa = 6/7 at nu = 0 (Cowper 1966).  Tolerance 0.5 %."""
    c = section_constants(_disc(20.0))
    assert cowper_circle(0.0) == pytest.approx(6.0 / 7.0)
    assert c.Asy / c.area == pytest.approx(6.0 / 7.0, rel=5e-3)
    assert c.Asz / c.area == pytest.approx(6.0 / 7.0, rel=5e-3)


def test_rotated_rectangle_principal_axes():
    """A 30 x 6 rectangle turned by 30 deg: principal angle 30 deg, I1 = 30 * 6^3/12 about the long
    axis, I2 = 6 * 30^3/12; Iyy, Izz, Iyz follow Mohr's circle (exact for a polygon: 1e-6)."""
    w, h, th = 30.0, 6.0, np.deg2rad(30.0)
    c = section_constants(affinity.rotate(box(-w / 2, -h / 2, w / 2, h / 2), 30.0, origin=(0, 0)))
    I1, I2 = w * h**3 / 12, h * w**3 / 12
    assert c.angle == pytest.approx(th, abs=1e-6)
    assert (c.I1, c.I2) == pytest.approx((I1, I2), rel=1e-6)
    cs, sn = np.cos(th), np.sin(th)
    assert c.Iyy == pytest.approx(I1 * cs**2 + I2 * sn**2, rel=1e-6)
    assert c.Izz == pytest.approx(I1 * sn**2 + I2 * cs**2, rel=1e-6)
    assert c.Iyz == pytest.approx((I2 - I1) * sn * cs, rel=1e-6)
    assert c.centroid == pytest.approx((0.0, 0.0), abs=1e-9)
    s = c.principal_section()
    assert (s.Iy, s.Iz) == pytest.approx((I1, I2), rel=1e-6)


def test_I_section_shear_areas_by_direction():
    """I-section, web along z: the shear area along z is about the web area (h t_w = 80), and along y
    about 5/6 of the flanges (2 b t_f = 160): the directions must not be swapped.  Loose (15 %):
    these are engineering approximations of the shear-function result."""
    I = box(-20, -2, 20, 0).union(box(-20, 40, 20, 42)).union(box(-1, 0, 1, 40))
    c = section_constants(I)
    assert c.Asz == pytest.approx(80.0, rel=0.15)
    assert c.Asy == pytest.approx(5.0 / 6.0 * 160.0, rel=0.15)


@pytest.mark.parametrize("poly, msg", [
    (Polygon([(0, 0), (10, 10), (10, 0), (0, 10)]), "cannot be meshed"),   # bow-tie (self-intersecting)
    (Polygon([(0, 0), (10, 0), (20, 0)]), "cannot be meshed"),              # zero area
    (Polygon(), "cannot be meshed"),                                        # empty
    ("a square", "shapely Polygon"),
])
def test_bad_sections_raise(poly, msg):
    with pytest.raises(LinkFeaError, match=msg):
        section_constants(poly)
