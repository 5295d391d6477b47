"""Beams in series (serial chain of 6-dof springs) against closed forms."""
import numpy as np
import pytest

from linkfea.beam.closed_form import BeamSegment, cantilever_compliance, rect_section, series_compliance
from linkfea.runtime.errors import LinkFeaError

E, NU = 210e3, 0.3


@pytest.mark.parametrize("shear", [False, True])
@pytest.mark.parametrize("n", [2, 8])
def test_prismatic_bar_split_in_series_equals_one_beam(shear, n):
    """A prismatic cantilever cut into n equal pieces clamped end to end is the same cantilever.

    Truth: seed eq. 14 for the whole length (plus the Timoshenko shear term), coupling
    terms k26 = L^2/2EIz and k35 = -L^2/2EIy included.  The sum over pieces of
    X_i C_i X_i^T is exact algebra (polynomials in x), so only round-off remains: 1e-12.
    """
    L, sec = 200.0, rect_section(20.0, 10.0, NU)
    segs = [BeamSegment(-L + i * L / n, -L + (i + 1) * L / n, sec) for i in range(n)]
    C = series_compliance(segs, E, NU, shear)
    C1 = cantilever_compliance(L, sec, E, NU, shear)
    scale = np.sqrt(np.outer(np.diag(C1), np.diag(C1)))
    assert np.max(np.abs(C - C1) / scale) < 1e-12
    assert C[1, 5] > 0 and C[2, 4] < 0  # sign convention: Fy at the tip gives rz = +F L^2 / 2EIz


def test_stepped_cantilever_matches_unit_load_method():
    """Two-step cantilever, tip load Fy: v = a^3/3EI1 + (L^3 - a^3)/3EI2, rz = a^2/2EI1 + (L^2 - a^2)/2EI2.

    Truth: unit-load (Castigliano) integrals of M(x) = F x over each step, x from the tip,
    Euler-Bernoulli.  Exact algebra: 1e-12.
    """
    L, a = 300.0, 120.0
    s_tip, s_base = rect_section(20.0, 10.0, NU), rect_section(30.0, 16.0, NU)
    C = series_compliance([BeamSegment(-L, -a, s_base), BeamSegment(-a, 0.0, s_tip)], E, NU, shear=False)
    v = a**3 / (3 * E * s_tip.Iz) + (L**3 - a**3) / (3 * E * s_base.Iz)
    rz = a**2 / (2 * E * s_tip.Iz) + (L**2 - a**2) / (2 * E * s_base.Iz)
    assert C[1, 1] == pytest.approx(v, rel=1e-12)
    assert C[1, 5] == pytest.approx(rz, rel=1e-12)
    assert C[5, 5] == pytest.approx(a / (E * s_tip.Iz) + (L - a) / (E * s_base.Iz), rel=1e-12)


def test_offset_axis_couples_axial_force_and_bending():
    """Beam axis at z = e below the frame origin: an axial force Fx at the origin bends the beam.

    Truth (statics + small rotations): at the beam tip My = -e Fx, so ry = -e Fx L / EIy and the
    origin moves by ry x (0, 0, -e): dx = Fx L/EA + e^2 Fx L / EIy, ry/Fx = -e L / EIy.
    """
    L, e = 150.0, 7.0
    sec = rect_section(20.0, 10.0, NU)
    C = series_compliance([BeamSegment(-L, 0.0, sec, centroid=(0.0, e))], E, NU, shear=False)
    assert C[0, 0] == pytest.approx(L / (E * sec.A) + e**2 * L / (E * sec.Iy), rel=1e-12)
    assert C[4, 0] == pytest.approx(-e * L / (E * sec.Iy), rel=1e-12)
    assert np.allclose(C, C.T, rtol=0, atol=1e-14 * np.abs(C).max())


def test_rotated_principal_axes_match_unsymmetric_bending():
    """Section with principal axes turned by theta: tip translations under (Fy, Fz) are
    L^3/3E * [[Izz, Iyz], [Iyz, Iyy]]^-1 = L^3/(3E D) [[Iyy, -Iyz], [-Iyz, Izz]], D = Iyy Izz - Iyz^2.

    Truth: unsymmetric (oblique) bending of a cantilever, with Iyy, Izz, Iyz about the
    frame's y, z obtained from the principal ones by Mohr's circle.
    """
    L, th = 200.0, np.deg2rad(25.0)
    sec = rect_section(20.0, 10.0, NU)   # principal: Iy = about y', Iz = about z'
    c, s = np.cos(th), np.sin(th)
    Iyy = sec.Iy * c**2 + sec.Iz * s**2
    Izz = sec.Iy * s**2 + sec.Iz * c**2
    Iyz = (sec.Iz - sec.Iy) * s * c    # int y z over the section, y = c y' - s z', z = s y' + c z'
    C = series_compliance([BeamSegment(-L, 0.0, sec, angle=th)], E, NU, shear=False)
    D = Iyy * Izz - Iyz**2
    assert C[1, 1] == pytest.approx(L**3 / (3 * E) * Iyy / D, rel=1e-12)
    assert C[2, 2] == pytest.approx(L**3 / (3 * E) * Izz / D, rel=1e-12)
    assert C[1, 2] == pytest.approx(-L**3 / (3 * E) * Iyz / D, rel=1e-12)


def test_bad_segments():
    sec = rect_section(20.0, 10.0, NU)
    with pytest.raises(LinkFeaError, match="at least one segment"):
        series_compliance([], E, NU)
    with pytest.raises(LinkFeaError, match="x_end must exceed"):
        BeamSegment(0.0, -1.0, sec)
