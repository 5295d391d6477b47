"""Choosing a STEP's faces: ``linkfea faces`` lists selectors that pick what they describe, a selector
that finds nothing names the nearest faces, and ``--preview`` draws the base, the tip and the frame."""
import math
import os
import subprocess
import sys

import numpy as np
import pytest
from brackets import BASE, BASE_AREA, TIP, TIP_AREA, bracket_step

from linkfea.cad import build_link
from linkfea.cad.faces import BASE_RGB, TIP_RGB
from linkfea.cad.selectors import faces_area_centroid, parse_selector, select_faces
from linkfea.cad.step import read_step_solid
from linkfea.runtime.errors import LinkFeaError

BORE_RADIUS, ARM_HEIGHT = 4.0, 12.0  # tests/brackets.py: the 8 mm bore through the 12 mm arm


@pytest.fixture(scope="module")
def listed(tmp_path_factory):
    """The bracket STEP, and ``linkfea faces`` run on it once with a preview."""
    folder = tmp_path_factory.mktemp("faces")
    step = bracket_step(folder)
    png = folder / "pics" / "preview.png"
    p = subprocess.run([sys.executable, "-m", "linkfea", "faces", str(step), "--base", BASE, "--tip", TIP,
                        "--preview", str(png)], capture_output=True, text=True, timeout=600,
                       env=dict(os.environ, OMP_NUM_THREADS="1"))
    assert p.returncode == 0, p.stderr
    rows = [ln.split() for ln in p.stdout.splitlines() if ln.startswith("  ")]
    return step, rows, png


def test_listed_selectors_pick_the_faces_they_describe(listed):
    step, rows, _ = listed
    body = read_step_solid(step)
    assert len(rows) >= 10
    kinds = {r[1] for r in rows}
    assert kinds == {"plane", "cylinder"}
    for r in rows:
        sel, n, area = r[0], int(r[2]), float(r[4])
        picked = select_faces(body, parse_selector(sel))
        assert len(picked) == n, r
        assert math.isclose(faces_area_centroid(picked)[0], area, rel_tol=1e-3), r
    by_sel = {r[0]: r for r in rows}
    # the interfaces of tests/brackets.py by the selectors the docs use, areas by their closed forms
    assert float(by_sel[BASE][4]) == pytest.approx(BASE_AREA, rel=1e-3)
    assert float(by_sel[TIP][4]) == pytest.approx(TIP_AREA, rel=1e-3)
    bore = [r for r in rows if r[1] == "cylinder" and "radius" in r and float(r[r.index("radius") + 1]) == BORE_RADIUS
            and r[-1] == "1)"]  # axis (0, 0, 1)
    assert len(bore) == 3  # the bore and the base's two r = 4 fillets along z: the bore is the largest
    big = max(bore, key=lambda r: float(r[4]))
    assert float(big[4]) == pytest.approx(2 * math.pi * BORE_RADIUS * ARM_HEIGHT, rel=1e-3)


def test_preview_shows_base_tip_and_frame(listed):
    import matplotlib.image as mpimg

    _, _, png = listed
    img = (mpimg.imread(png)[..., :3] * 255).astype(int)
    assert img.shape[0] >= 300 and np.ptp(img) > 100  # not blank

    def near(rgb, tol=70):
        return int(np.sum(np.all(np.abs(img - np.array(rgb)) <= tol, axis=-1)))

    assert near(BASE_RGB) > 50 and near(TIP_RGB) > 50
    assert near((255, 0, 0), 40) > 50 and near((0, 128, 0), 40) > 50  # the frame's x and y arrows


def test_a_selector_that_finds_nothing_names_the_nearest(listed):
    step, _, _ = listed
    with pytest.raises(LinkFeaError, match=r"base selector plane:1,0,0,1,0,0,tol=0.01 finds no face; nearest: "
                                           r"plane:x=0 \(plane, 144 mm\^2, 1 mm away\)"):
        build_link(str(step), base="plane:x=1", tip=TIP, with_block=False)
    with pytest.raises(LinkFeaError, match=r"tip selector .* finds no face; nearest: plane:z=105 "):
        build_link(str(step), base=BASE, tip="plane:z=104.5", with_block=False)


def test_faces_refuses_a_script_and_a_preview_without_selectors(listed, tmp_path):
    import shlex

    from bad_inputs import Case, run

    step, _, _ = listed
    # the script through a real `linkfea` process (its exit status), the preview in process as the bad-input
    # table runs its cases (``main`` returns the status the process would end with)
    p = subprocess.run([sys.executable, "-m", "linkfea", "faces", "bar"], capture_output=True, text=True, timeout=300)
    lines = [ln for ln in p.stderr.splitlines() if ln.strip()]
    assert p.returncode == 2 and len(lines) == 1 and lines[0].startswith("error: "), p.stderr
    res = run(Case("", shlex.join(["linkfea", "faces", str(step), "--preview", str(tmp_path / "p.png")]), ""),
              tmp_path)
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert res.status == 2 and len(lines) == 1 and lines[0].startswith("error: "), res.stderr
    assert not (tmp_path / "p.png").exists()
