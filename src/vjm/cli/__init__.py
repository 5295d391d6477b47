"""``vjm`` command line, one module per command (in meshio's style): ``stiffness``, ``map``, ``table1``,
``sweep``, ``calibrate``, ``compensate``, ``diagnose``, ``simulate``, ``path``, ``design``.

Each module holds its command's function; this one builds the typer ``app`` and registers them.  Every
command turns a user error into one ``error:`` line on stderr and exit status 2 (:mod:`.common`).
"""
from __future__ import annotations

import sys

import typer

from linkfea.runtime.clirun import HELP_SETTINGS, version_option

from . import calibrate, compensate, design, diagnose, map, path, simulate, stiffness, sweep, table1

app = typer.Typer(add_completion=False, **HELP_SETTINGS,
                  help="Stiffness, deflection, diagnosis and calibration of robots by the virtual-joint method: "
                       "serial and tree robots (URDF, DH) and parallel machines.")


@app.callback()
def _root(version: bool = version_option("vjm")):
    """Stiffness, deflection, diagnosis and calibration of serial, tree and parallel robots."""
    from linkfea.runtime.errors import LinkFeaWarning, warnings_as_lines

    from ..errors import VjmWarning

    warnings_as_lines(VjmWarning, LinkFeaWarning)


app.command("stiffness")(stiffness.stiffness)
app.command("map")(map.map_cmd)
app.command("table1")(table1.table1)
app.command("sweep")(sweep.sweep_cmd)
app.command("calibrate")(calibrate.calibrate_cmd)
app.command("compensate")(compensate.compensate_cmd)
app.command("diagnose")(diagnose.diagnose_cmd)
app.command("simulate")(simulate.simulate_cmd)
app.command("path")(path.path_cmd)
app.command("design")(design.design_cmd)


def main(argv=None) -> int:
    """Console entry point (``vjm``): the exit status; a usage error is one ``error:`` line."""
    from linkfea.runtime.clirun import run

    return run(app, argv, "vjm")


if __name__ == "__main__":
    sys.exit(main())
