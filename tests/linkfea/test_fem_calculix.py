"""Cross-check with CalculiX: same P2 mesh as C3D10, same clamp, *RIGID BODY on the same nodes.

Both codes solve the same discrete problem, so they must agree to solver and
print precision (ccx prints 7 significant digits): 1e-5 relative, norm-wise.
"""
import dataclasses
import shutil

import numpy as np
import pytest
from meshes import bar_link_mesh

from linkfea.fem.fit import compliance_from_solution
from linkfea.fem.problem import solve_link
from linkfea.mechanics.frames import Frame

pytestmark = [
    pytest.mark.calculix,
    pytest.mark.skipif(shutil.which("ccx") is None,
                       reason="CalculiX (ccx) not installed: install Debian package calculix-ccx"),
]


def _rel(a, b):
    return np.linalg.norm(a - b) / np.linalg.norm(b)


def _rotated_frame():
    c, s = np.cos(0.7), np.sin(0.7)
    axes = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]]) @ np.array(
        [[1.0, 0.0, 0.0], [0.0, np.cos(-0.4), np.sin(-0.4)], [0.0, -np.sin(-0.4), np.cos(-0.4)]])
    return Frame(np.array([190.0, 3.0, -2.0]), axes)


def test_calculix_rigid_slender_bar(steel):
    """The 200 x 20 x 10 bar of test_fem_beam, rigid tip coupling, tip frame: 20 x 4 x 2 cells (6k DOF; the same
    discrete problem in both solvers, so any size tells: they agreed to 4e-8 to 6e-8 at 6k, 17k and 36k DOF,
    and the pair took 16 s of CPU on 36k, 6 s on 17k, 1.5 s on 6k)."""
    from calculix import solve_calculix

    mesh = bar_link_mesh(200.0, 20.0, 10.0, 20, 4, 2)
    ours = compliance_from_solution(solve_link(mesh, steel)).raw
    ccx = solve_calculix(mesh, steel).compliance
    assert _rel(ccx, ours) < 1e-5


@pytest.mark.parametrize("mode", ["rigid", "block"])
def test_calculix_rotated_frame_and_block(steel, mode):
    """A moved, rotated reference frame (loads rotated to CAD axes in ccx) and the pseudo-rigid block."""
    from calculix import solve_calculix

    mesh = dataclasses.replace(bar_link_mesh(200.0, 20.0, 10.0, 20, 4, 2, block_length=10.0, nb=2),
                               frame=_rotated_frame())
    ours = compliance_from_solution(solve_link(mesh, steel, mode=mode)).raw
    res = solve_calculix(mesh, steel, mode=mode)
    assert _rel(res.compliance, ours) < 1e-5


@pytest.fixture(scope="module")
def bracket(tmp_path_factory):
    """The filleted L-bracket of tests/brackets.py, exported to STEP once for both modes."""
    from brackets import bracket_step

    return bracket_step(tmp_path_factory.mktemp("step"))


@pytest.mark.parametrize("mode", ["rigid", "block"])
def test_calculix_on_the_gmsh_mesh_of_a_filleted_step_bracket(steel, mode, bracket):
    """The CAD-conforming gmsh mesh of the filleted L-bracket (tests/brackets.py, read back from
    STEP), clamped on its base face, tip frame on the upright's top: same discrete problem, so
    CalculiX C3D10 agrees to its print precision.  A 16 mm edge: the fillets and the bore still
    set most of the mesh (3.3k tets, 1.1k curved edges, against 4.1k at 10 mm), and the two
    codes agreed to 1e-7 at both sizes."""
    from brackets import BASE, TIP
    from calculix import solve_calculix

    from linkfea.cad import build_link
    from linkfea.mesh import mesh_link

    link = build_link(str(bracket), base=BASE, tip=TIP, with_block=(mode == "block"))
    mesh = mesh_link(link, 16.0, with_block=(mode == "block"))
    assert mesh.mesher == "gmsh"
    ours = compliance_from_solution(solve_link(mesh, steel, mode=mode)).raw
    ccx = solve_calculix(mesh, steel, mode=mode).compliance
    assert _rel(ccx, ours) < 1e-5
