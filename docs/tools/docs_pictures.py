"""Make the pictures of the docs (docs/img/) from the project's own commands.

Run from the project root: ``.venv/bin/python docs/tools/docs_pictures.py [--only NAME ...]``.  Each
picture comes from the commands a user runs (``linkfea compute``, ``vjm map``, ``vjm simulate`` and ``vjm
diagnose``), run in a scratch folder with this checkout's ``src``; the report is rendered by headless
Chromium as a browser shows it.  The PNGs are written small (a 256-colour palette, at most 900 pixels wide)
so that the repository stays light; tests/test_docs_site.py checks that the pages show them.

* ``link_mesh_frame.png``: the bundled bar's mesh and the frame its compliance is given in;
* ``map_k_tran.png``, ``map_ratio.png``: the 3-PUU's k_tran map, and the map with an FEA leg over it;
* ``robot_joint_map.png``: the UR10's k_tran over two joints;
* ``diagnose_report.png``: the top of a ``vjm diagnose`` report.
"""
from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
IMG = ROOT / "docs" / "img"
PUU = str(ROOT / "data/orthoglide/puu.yaml")
UR10 = str(ROOT / "data/robots/ur10/ur10.yaml")
WIDTH = 900


def _env(work: Path) -> dict:
    return dict(os.environ, PYTHONPATH=str(ROOT / "src"), MPLBACKEND="Agg", OMP_NUM_THREADS="1",
                LINKFEA_CACHE_DIR=str(work / "meshes"))


def run(work: Path, tool: str, *args: str) -> None:
    """``linkfea ...`` or ``vjm ...`` as the user runs it, in ``work``."""
    cmd = [sys.executable, "-m", f"{tool}.cli", *args]
    print("$", tool, *args, flush=True)
    subprocess.run(cmd, cwd=work, env=_env(work), check=True)


def small_png(src: Path, name: str, crop: bool = False) -> Path:
    """``src`` written to docs/img/``name``: at most WIDTH pixels wide, a 256-colour palette; ``crop``: the
    white margins cut to 20 pixels."""
    from PIL import Image, ImageChops

    with Image.open(src) as im:
        im = im.convert("RGB")
        if crop:
            box = ImageChops.difference(im, Image.new("RGB", im.size, "white")).getbbox()
            if box:
                im = im.crop((max(box[0] - 20, 0), max(box[1] - 20, 0), min(box[2] + 20, im.width),
                              min(box[3] + 20, im.height)))
        if im.width > WIDTH:
            im = im.resize((WIDTH, round(im.height * WIDTH / im.width)), Image.LANCZOS)
        out = IMG / name
        im.quantize(256, method=Image.MEDIANCUT).save(out, optimize=True)
    print(f"wrote {out.relative_to(ROOT)} ({out.stat().st_size // 1024} KB)")
    return out


def link(work: Path) -> None:
    """The bar's mesh (its surface, edges drawn) and its compliance frame as an x, y, z triad."""
    run(work, "linkfea", "compute", "bar", "--out", "link/result.json")
    sys.path.insert(0, str(ROOT / "src"))
    import numpy as np
    import pyvista as pv

    from linkfea.result.linkresult import load

    res = load(work / "link" / "result.json")
    grid = res.to_pyvista()
    size = float(np.linalg.norm(np.ptp(grid.points, axis=0)))
    pl = pv.Plotter(off_screen=True, window_size=[1600, 1000])
    pl.set_background("white")
    pl.add_mesh(grid.extract_surface(algorithm="dataset_surface"), color="lightsteelblue", show_edges=True,
                edge_color="dimgray", line_width=0.5)
    f = res.frame
    for axis, colour, label in zip(f.axes, ("red", "green", "blue"), "xyz"):
        pl.add_mesh(pv.Arrow(start=f.origin, direction=axis, scale=0.25 * size, tip_length=0.15, shaft_radius=0.02), color=colour)
        pl.add_point_labels([np.asarray(f.origin) + 0.28 * size * np.asarray(axis)], [label], font_size=28,
                            text_color=colour, shape=None, show_points=False, always_visible=True)
    pl.view_isometric()
    pl.camera.zoom(1.5)
    shot = work / "link.png"
    pl.screenshot(str(shot))
    pl.close()
    small_png(shot, "link_mesh_frame.png", crop=True)


def maps(work: Path) -> None:
    """The 3-PUU's map with beam links, and the map with the bar's FEA result as its leg compared with it."""
    run(work, "vjm", "map", PUU, "--grid", "41", "--slice", "z=0", "--out", "map")
    small_png(work / "map" / "k_tran.png", "map_k_tran.png")
    if not (work / "link" / "result.json").is_file():
        run(work, "linkfea", "compute", "bar", "--out", "link/result.json")
    run(work, "vjm", "map", PUU, "--grid", "41", "--slice", "z=0", "--leg", "link/result.json", "--out", "map_fea",
        "--compare", "map")
    small_png(work / "map_fea" / "k_tran_ratio.png", "map_ratio.png")


def robot(work: Path) -> None:
    run(work, "vjm", "map", UR10, "--joints", "shoulder_lift_joint=-2.6:-0.4:41,elbow_joint=0.3:2.6:41",
        "--out", "robot")
    small_png(work / "robot" / "k_tran.png", "robot_joint_map.png")


def report(work: Path) -> None:
    """The diagnosis of a hidden clearance (the demo's), its report.html as Chromium shows it."""
    run(work, "vjm", "simulate", PUU, "--effect", "clearance:backlash=0.003", "--poses", "random:30", "--loads",
        "axes:100", "--noise-t", "0.001", "--seed", "1", "--out", "measurements.csv")
    run(work, "vjm", "diagnose", PUU, "measurements.csv", "--out", "report")
    browser = next((shutil.which(n) for n in ("chromium", "chromium-browser", "google-chrome") if shutil.which(n)),
                   None)
    if browser is None:
        raise SystemExit("headless Chromium is needed for the report's picture (Debian package chromium)")
    shot = work / "report.png"
    subprocess.run([browser, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
                    f"--user-data-dir={work / 'profile'}", "--virtual-time-budget=10000", "--window-size=1000,1250",
                    f"--screenshot={shot}", (work / "report" / "report.html").as_uri()],
                   check=True, capture_output=True, timeout=180)
    small_png(shot, "diagnose_report.png")


PICTURES = {"link": link, "maps": maps, "robot": robot, "report": report}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", nargs="*", choices=sorted(PICTURES), help="make these pictures only")
    args = ap.parse_args(argv)
    IMG.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="docs-pictures-") as d:
        for name in args.only or PICTURES:
            PICTURES[name](Path(d))
    return 0


if __name__ == "__main__":
    sys.exit(main())
