"""How vjm's objects show themselves: short text reprs, a readable principal-compliance picture, a
labelled sag, and a map's save returning its folder."""
import numpy as np
import pytest

import vjm
from vjm.maps.views import pyplot

plt = pyplot()
UR10 = "data/robots/ur10/ur10.yaml"
Q = [0.0, -1.2, 1.5, -1.9, -1.57, 0.0]
#: a repr is a few lines, not a dump of every array
MAX_LINES, MAX_CHARS = 4, 400


@pytest.fixture(scope="module")
def puu():
    return vjm.load_model("puu")


@pytest.fixture(scope="module")
def ur10():
    return vjm.load_model(UR10)


def _short(text: str) -> None:
    assert len(text.splitlines()) <= MAX_LINES and max(len(ln) for ln in text.splitlines()) <= MAX_CHARS, text


def test_model_robot_and_result_reprs_are_a_few_lines_with_the_facts(puu, ur10):
    m = repr(puu)
    _short(m)
    assert puu.architecture in m and "foot" in m and "leg" in m
    r = puu.stiffness([0.0, 0.0, 0.0])
    s = repr(r)
    _short(s)
    # the figures the repr states are the result's own (independent: the eigenvalues of C's block)
    assert f"k_tran = {float(np.linalg.eigvalsh(r.C[:3, :3]).max()):.4g} mm/N" in s and "rank 6" in s
    many = puu.stiffness_map(np.array([[0.0, 0.0, 0.0], [20.0, -10.0, 5.0], [-30.0, 5.0, 0.0]]))
    _short(repr(many))
    assert "3 poses" in repr(many) and f"{np.min(many.k_tran):.4g}..{np.max(many.k_tran):.4g}" in repr(many)
    u = repr(ur10)
    _short(u)
    assert all(j in u for j in ur10.q_names[:5]) and "tool0" in u and "9.80665" in u
    h = ur10._repr_html_()
    assert h.startswith("<p><b>vjm RobotModel</b>") and "shoulder_lift_joint" in h and "<table>" in h
    _short(repr(ur10.stiffness(Q)))


def test_sag_is_labelled_and_reads_as_its_array(ur10):
    one = ur10.self_weight(Q)
    _short(repr(one))
    assert one.tool == "tool0" and one.q_names == ur10.q_names and one.units[:3] == ("mm",) * 3
    t = np.asarray(one)
    assert isinstance(t, np.ndarray) and t.shape == (6,)
    assert f"dz {t[2]:.4g} mm" in repr(one)
    assert np.isclose(float(one.length), np.linalg.norm(t[:3]))
    # old code reading it as the bare array: indexing, arithmetic, numpy functions give plain arrays
    assert isinstance(one[:3], np.ndarray) and np.array_equal(one[:3], t[:3])
    assert one.max() == t.max() and one.T.shape == (6,) and isinstance(one.copy(), np.ndarray)
    assert isinstance(one * 2.0, np.ndarray) and np.array_equal(one * 2.0, 2.0 * t)
    assert isinstance(np.zeros(6) + one, np.ndarray) and np.allclose(one, t) and one == pytest.approx(t)
    many = ur10.self_weight(np.array([Q, Q]))
    assert many.shape == (2, 6) and np.array_equal(many.q, np.array([Q, Q])) and "2 configurations" in repr(many)
    out = np.full((3, 6), np.nan)
    out[:2] = many
    assert np.array_equal(out[:2], np.asarray(many))
    s, info = ur10.self_weight(Q, return_info=True)
    assert np.array_equal(np.asarray(s), t) and "converged" in info


def _inside(fig) -> None:
    """Every artist of the figure (labels, ticks, title) within the figure's box."""
    fig.canvas.draw()
    r = fig.canvas.get_renderer()
    box = fig.bbox
    for a in fig.axes:
        b = a.get_tightbbox(r)
        assert b.x0 >= box.x0 - 0.5 and b.y0 >= box.y0 - 0.5 and b.x1 <= box.x1 + 0.5 and b.y1 <= box.y1 + 0.5, \
            (b, box)


def test_principal_plot_at_the_readme_point_is_readable(puu, tmp_path):
    """At the README's point the three translational compliances are equal: the axes still span a
    decade around the bars, and nothing is clipped."""
    r = puu.stiffness([0, 0, 0])
    ax = r.plot()
    fig = ax.figure
    try:
        t = np.linalg.eigvalsh(r.C[:3, :3])
        assert np.ptp(t) <= 1e-9 * t.max()  # the case that collapsed the axis
        rot = np.linalg.eigvalsh(r.C[3:, 3:])
        for a, v in ((ax, t), (fig.axes[1], rot)):
            lo, hi = a.get_ylim()
            assert a.get_yscale() == "log" and hi / lo >= 10.0 and lo < v.min() and v.max() < hi
        _inside(fig)
        path = tmp_path / "p.png"
        fig.savefig(path)
        img = plt.imread(path)
        assert img.shape[0] > 100 and np.ptp(img[..., :3]) > 0.5  # drawn, not blank
    finally:
        plt.close(fig)


def test_stiffness_map_save_returns_its_folder(puu, tmp_path):
    smap = puu.map(grid=3, slice="z=0")
    out = smap.save(tmp_path / "m")
    assert out == tmp_path / "m" and (out / "map.npz").is_file()
