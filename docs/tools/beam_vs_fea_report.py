"""Write the tables and pictures of docs/beam_vs_fea.md: every bundled cad/ link against its N-beam models.

Run from the project root: ``.venv/bin/python docs/tools/beam_vs_fea_report.py [names...] > /tmp/results.md``;
the PNGs go to ``docs/img/beam_vs_fea_<name>.png``, the Markdown to stdout (paste it under Results).
The numbers come from :func:`linkfea.beam.compare.compare`, the same code as ``linkfea compare``.
"""
from __future__ import annotations

import sys
from pathlib import Path

from linkfea.beam.compare import DEFAULT_BEAMS, compare
from linkfea.beam.report import figure_png, markdown_table
from linkfea.cad import CAD_DIR
from linkfea.files.atomic import write_bytes
from linkfea.runtime.errors import LinkFeaError


def library_report(names=None, beams=None, img_dir="docs/img", mesh_size=None) -> str:
    """Compare every bundled cad/ link at its default parameters; Markdown of the results.

    PNGs go to ``img_dir/beam_vs_fea_<name>.png``.  A link whose comparison fails is
    reported with its error message instead of numbers.
    """
    beams = DEFAULT_BEAMS if beams is None else beams

    names = names or sorted(p.stem for p in CAD_DIR.glob("*.py") if not p.stem.startswith("_"))
    img_dir = Path(img_dir)
    rows, details = [], []
    for name in names:
        try:
            rec = compare(name, beams, mesh_size=mesh_size).to_dict()
            write_bytes(img_dir / f"beam_vs_fea_{name}.png", figure_png(rec))
        except LinkFeaError as exc:
            rows.append(f"| {name} | – | failed: {exc} | | | | |")
            continue
        for m in rec["beams"]:
            t, e = m["timoshenko"]["summary"], m["euler_bernoulli"]["summary"]
            rows.append(f"| {name} | {m['n']} | {100 * e['max_principal_error_translation']:.0f} / "
                        f"{100 * e['max_principal_error_rotation']:.0f} | "
                        f"{100 * t['max_principal_error_translation']:.0f} / {100 * t['max_principal_error_rotation']:.0f}"
                        f" | {t['max_angle_deg']:.1f} | {100 * t['max_abs_diagonal_error']:.0f} | "
                        f"{100 * t['max_abs_coupling_error']:.0f} |")
        mesh = rec["fea"].get("mesh", {})
        details.append(markdown_table(rec) + f"\nFEA: {mode_text(rec)}; mesh {mesh}.\n\n"
                       f"![{name}](img/beam_vs_fea_{name}.png)\n")
    head = ("| link | N | EB max principal error, transl. / rot. (%) | Timoshenko, transl. / rot. (%) | "
            "Timoshenko max angle (deg) | Timoshenko max abs diagonal (%) | Timoshenko max abs coupling (%) |\n"
            "|---|---:|---:|---:|---:|---:|---:|\n")
    return head + "\n".join(rows) + "\n\n" + "\n".join(details)


def mode_text(rec: dict) -> str:
    return str(rec["fea"].get("mode", "rigid")) + " tip coupling"


if __name__ == "__main__":
    print(library_report(sys.argv[1:] or None))
