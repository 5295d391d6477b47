"""The Python API: linkfea.compute / load / compare and their result objects; the Compliance contract."""
import json
import re

import numpy as np
import pytest

import linkfea
from linkfea.beam.closed_form import cantilever_compliance, rect_section
from linkfea.mechanics.compliance import SYMMETRY_RTOL, Compliance
from linkfea.runtime.errors import LinkFeaError

H = 8.0  # mm: a coarse P2 mesh of the 200 x 20 x 10 mm bar (about 5k DOF)


def _scaled(A, B):
    d = np.sqrt(np.outer(np.diag(B), np.diag(B)))
    return float(np.max(np.abs(A - B) / d))


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return tmp_path_factory.mktemp("meshes")


@pytest.fixture(scope="module")
def bar(cache):
    return linkfea.compute("bar", linkfea.ComputeOptions(mesh_size=H), cache_dir=cache)


def test_compute_gives_the_cli_matrix(bar, cache, tmp_path, monkeypatch):
    """`linkfea compute` (same mesh through the cache) writes the matrix compute() returns.  In process, as
    the bad-input table runs its commands (a real process's exit status is test_cli.py's concern).

    To rounding, not bit for bit: PARDISO and BLAS sum in an order that depends on the number of
    threads they get (1 or 2 MKL threads change the last digits; 1.4e-12 scaled was seen in a full
    suite run on a loaded machine), and the rounding bound of the solve is about cond(K) eps."""
    from linkfea.cli import main

    out = tmp_path / "bar.json"
    monkeypatch.setenv("LINKFEA_CACHE_DIR", str(cache))
    assert main(["compute", "bar", "--mesh-size", str(H), "--no-picture", "-q", "--out", str(out)]) == 0
    doc = json.loads(out.read_text())
    assert doc["mesh"]["cache_key"] == bar.mesh_info.cache_key
    assert _scaled(np.array(doc["compliance"]), bar.compliance) < 1e-9
    assert _scaled(np.array(doc["stiffness"]), bar.stiffness) < 1e-9 * np.max(np.abs(bar.stiffness))
    np.testing.assert_array_equal(doc["frame"]["origin"], bar.frame.origin)


def test_result_values_are_a_cantilever(bar):
    """The result object's matrices: C against Timoshenko (bending within 3% at this coarse mesh), K = C^-1."""
    steel = bar.material
    Cb = cantilever_compliance(200.0, rect_section(20.0, 10.0, steel.nu), steel.E, steel.nu, shear=True)
    for i in (0, 1, 2, 4, 5):
        assert bar.compliance[i, i] == pytest.approx(Cb[i, i], rel=0.03), i
    np.testing.assert_allclose(bar.compliance @ bar.stiffness, np.eye(6), atol=1e-8)
    np.testing.assert_allclose(bar.frame.origin, [200.0, 0.0, 0.0])
    assert bar.mesh_info.n_dofs == bar.solution.n_dofs and bar.mesh is not None
    assert {"symmetry_error", "fit_residual", "min_eigenvalue", "error_estimate"} <= set(bar.diagnostics.to_dict())
    assert isinstance(bar.value, Compliance) and not bar.compliance.flags.writeable


def test_save_load_round_trips_exactly(bar, tmp_path):
    path = bar.save(tmp_path / "r" / "bar.json")
    assert path.with_suffix(".vtu").is_file()
    back = linkfea.load(path)
    assert np.array_equal(back.compliance, bar.compliance)
    assert np.array_equal(back.stiffness, bar.stiffness)
    assert np.array_equal(back.frame.origin, bar.frame.origin) and np.array_equal(back.frame.axes, bar.frame.axes)
    assert back.value == bar.value
    assert back.material == bar.material and back.mode == bar.mode and back.params == bar.params
    assert back.diagnostics == bar.diagnostics and back.mesh_info == bar.mesh_info and back.solver == bar.solver
    assert back.to_dict() == bar.to_dict()
    a, b = bar.to_pyvista(), back.to_pyvista()
    for name in ("u_Fx", "u_Fy", "u_Mz"):
        assert np.array_equal(np.asarray(a.point_data[name]), np.asarray(b.point_data[name]))


def test_plot_writes_a_png(bar, tmp_path):
    png = tmp_path / "bar.png"
    bar.plot(off_screen=True, screenshot=png)
    data = png.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000


def test_repr_html_shows_both_matrices_and_units(bar):
    text = bar._repr_html_()
    cells = [float(v) for v in re.findall(r"<td>([-+0-9.eE]+)</td>", text)]
    assert len(cells) == 72
    np.testing.assert_allclose(np.reshape(cells[:36], (6, 6)), bar.compliance, rtol=1e-4)
    np.testing.assert_allclose(np.reshape(cells[36:], (6, 6)), bar.stiffness, rtol=1e-4)
    assert "mm/N" in text and "N/mm" in text and "Fx" in text and "dx" in text
    short = repr(bar)
    assert "bar" in short and "mm/N" in short and len(short.splitlines()) < 20


def test_compare_object(cache, tmp_path):
    """linkfea.compare: the slender bar's one-beam Timoshenko model is within 2% on the bending diagonal,
    the error table is the definition applied to the record's own matrices, plot() returns an Axes."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cmp = linkfea.compare("bar", "1,2", mesh_size=H)
    err = cmp.errors
    assert len(err) == 4 and set(err["N"]) == {1, 2}
    C = cmp.fea
    d = np.sqrt(np.diag(C))
    for row in err.records():
        theory = "timoshenko" if row["model"] == "Timoshenko" else "euler_bernoulli"
        Cb = cmp.beam(row["N"], theory)
        assert row["C22"] == pytest.approx((Cb[1, 1] - C[1, 1]) / d[1] ** 2, abs=1e-12)
        assert row["C26"] == pytest.approx((Cb[1, 5] - C[1, 5]) / (d[1] * d[5]), abs=1e-12)
    t1 = [r for r in err.records() if r["model"] == "Timoshenko" and r["N"] == 1][0]
    assert abs(t1["C22"]) < 0.02 and abs(t1["C33"]) < 0.02
    fig, ax = plt.subplots()
    assert cmp.plot(ax=ax) is ax and len(ax.lines) == 4
    plt.close(fig)
    paths = cmp.save(tmp_path / "cmp")
    assert json.loads((tmp_path / "cmp" / "compare.json").read_text()) == json.loads(json.dumps(cmp.to_dict()))
    assert set(paths) == {"compare.json", "compare.md", "compare.png"}
    assert "Timoshenko" in repr(cmp) and "<table>" in cmp._repr_html_()


# --------------------------------------------------------------------------- the Compliance contract
def _spd():
    A = np.random.default_rng(3).standard_normal((6, 6))
    return A @ A.T + 6 * np.eye(6)


def test_compliance_check_is_scale_aware():
    """Symmetry is judged against sqrt(Cii Cjj): a rotation-block asymmetry invisible next to the
    mm/N entries is still an asymmetry (an absolute tolerance on max |C| would let it through)."""
    C = np.diag([1e-3, 1e-3, 1e-3, 1e-9, 1e-9, 1e-9])
    C[3, 4] = C[4, 3] = 0.5e-9
    Compliance(C)
    C[4, 3] *= 1 + 10 * SYMMETRY_RTOL
    assert abs(C[4, 3] - C[3, 4]) < 1e-6 * np.max(np.abs(C))
    with pytest.raises(LinkFeaError, match="symmetric"):
        Compliance(C)
    with pytest.raises(LinkFeaError, match="6x6"):
        Compliance(np.eye(5))
    with pytest.raises(LinkFeaError, match="positive definite"):
        Compliance(np.diag([1.0, 1, 1, 1, 1, 0]))
    with pytest.raises(LinkFeaError, match="positive definite"):
        Compliance(np.eye(6) + 1.5 * (np.eye(6, k=1) + np.eye(6, k=-1)))


def test_vjm_links_use_the_same_check(tmp_path):
    """A vjm model file whose foot compliance fails the linkfea check is refused with the YAML key."""
    import yaml

    import vjm
    from vjm.resources import data_file

    d = yaml.safe_load(data_file("data/orthoglide/puu.yaml").read_text())
    C = np.diag([1e-3, 1e-3, 1e-3, 1e-9, 1e-9, 1e-9])
    C[3, 4], C[4, 3] = 0.5e-9, 0.5e-9 * (1 + 1e-4)
    d["foot"] = {"compliance": C.tolist()}
    (tmp_path / "m.yaml").write_text(yaml.safe_dump(d))
    with pytest.raises(vjm.VjmError, match="foot.*symmetric"):
        vjm.load_model(tmp_path / "m.yaml")
    C[4, 3] = C[3, 4]
    d["foot"] = {"compliance": C.tolist()}
    (tmp_path / "m.yaml").write_text(yaml.safe_dump(d))
    assert np.array_equal(vjm.load_model(tmp_path / "m.yaml").foot.compliance, C)


def test_compliance_moves_by_the_adjoint_map():
    """to_frame: the twist of the moved spring under the moved wrench is the moved twist (closed form)."""
    from linkfea.mechanics.frames import Frame

    C = _spd() * 1e-4
    A = Frame([0.0, 0.0, 0.0], np.eye(3))
    B = Frame.from_x([10.0, -5.0, 2.0], [0.0, 1.0, 0.0], y_hint=(0.0, 0.0, 1.0))
    cb = Compliance(C, A).to_frame(B)
    # A unit force Fz applied at B's origin (components in B) seen at A: moment r x F.
    F_cad = B.axes[2]
    r = B.origin - A.origin
    w_A = np.concatenate([F_cad, np.cross(r, F_cad)])
    t_A = C @ w_A
    # The twist at B's origin, in B's axes: d_B = d_A + rot x r, rot unchanged.
    d_B = t_A[:3] + np.cross(t_A[3:], r)
    t_B = np.concatenate([B.axes @ d_B, B.axes @ t_A[3:]])
    np.testing.assert_allclose(cb.matrix[:, 2], t_B, rtol=1e-10, atol=1e-16)


@pytest.mark.parametrize("mode", ["rigid", "block"])
def test_the_iterative_solver_on_a_small_link(bar, cache, mode, tmp_path, monkeypatch):
    """``compute(solver='iterative')`` on the coarse bar (its P1 level too small for pyamg to coarsen) agrees
    with the direct solve, through the API and the command line (exit 0, the same matrix)."""
    from linkfea.cli import main

    direct = bar if mode == "rigid" else linkfea.compute("bar", linkfea.ComputeOptions(mesh_size=H, mode=mode), cache_dir=cache)
    it = linkfea.compute("bar", linkfea.ComputeOptions(mesh_size=H, mode=mode, solver="iterative"), cache_dir=cache)
    assert it.solver.factorizer == "cg+p1mg"
    assert _scaled(it.compliance, direct.compliance) < 1e-6
    monkeypatch.setenv("LINKFEA_CACHE_DIR", str(cache))
    out = tmp_path / "r.json"
    assert main(["compute", "bar", "--mesh-size", str(H), "--mode", mode, "--solver", "iterative", "-q",
                 "--no-picture", "--out", str(out)]) == 0
    assert _scaled(np.array(json.loads(out.read_text())["compliance"]), direct.compliance) < 1e-6
