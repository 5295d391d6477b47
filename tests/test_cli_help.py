"""Both commands' help as a newcomer reads it in an 80-column terminal, and their ``--version``.

Every option name and every word of every help text must appear whole in the rendered help (a table
that cuts ``model_updated.yaml`` to ``model_updated.ya…`` or wraps ``--no-outliers`` over two lines fails),
and no line is wider than the terminal.
"""
from __future__ import annotations

from importlib import metadata

import click
import pytest
import typer
from typer.testing import CliRunner

from linkfea.cli import app as linkfea_app
from vjm.cli import app as vjm_app

WIDTH = 80


def _commands(app: typer.Typer) -> list[tuple[list[str], click.Command]]:
    """(argv prefix, click command) of the app itself and of each of its commands."""
    group = typer.main.get_command(app)
    out = [([], group)]
    for name, cmd in getattr(group, "commands", {}).items():
        out.append(([name], cmd))
    return out


CASES = [(prog, app, argv, cmd) for prog, app in (("vjm", vjm_app), ("linkfea", linkfea_app))
         for argv, cmd in _commands(app)]


@pytest.mark.parametrize("prog,app,argv,cmd", CASES, ids=[" ".join([c[0], *c[2]]) for c in CASES])
def test_help_at_80_columns_keeps_every_word_whole(prog, app, argv, cmd):
    r = CliRunner(env={"COLUMNS": str(WIDTH), "TERMINAL_WIDTH": str(WIDTH)}).invoke(app, [*argv, "--help"],
                                                                                  prog_name=prog)
    assert r.exit_code == 0, r.output
    lines = r.output.splitlines()
    assert max(len(ln) for ln in lines) <= WIDTH, max(lines, key=len)
    tokens = set(r.output.split())
    tokens |= {t.rstrip(",") for t in tokens}  # "-p, --param"
    for p in cmd.params:
        for name in [*p.opts, *p.secondary_opts]:
            if name.startswith("-"):
                assert name in tokens, f"{prog} {' '.join(argv)}: option {name} not whole in the help"
        for word in (getattr(p, "help", None) or "").split():
            assert word in tokens, f"{prog} {' '.join(argv)} {p.name}: help word {word!r} cut in the help"
    for word in (cmd.help or "").split("\f")[0].split():
        assert word in tokens, f"{prog} {' '.join(argv)}: description word {word!r} cut"


def test_vjm_help_says_what_it_covers():
    """The description names the robots it takes (not only parallel machines) and what it does to them."""
    r = CliRunner(env={"COLUMNS": str(WIDTH)}).invoke(vjm_app, ["--help"], prog_name="vjm")
    head = " ".join(r.output.split("Options:")[0].split()).lower()
    for word in ("serial", "tree", "parallel", "stiffness", "calibration", "diagnosis"):
        assert word in head, (word, head)


@pytest.mark.parametrize("prog,app", [("vjm", vjm_app), ("linkfea", linkfea_app)])
def test_version(prog, app):
    r = CliRunner().invoke(app, ["--version"], prog_name=prog)
    assert r.exit_code == 0, r.output
    assert r.output == f"{prog} {metadata.version('linkfea-vjm')}\n"


@pytest.mark.parametrize("main_module", ["vjm.cli", "linkfea.cli"])
def test_version_through_main(main_module, capsys):
    """The console entry points (``main(argv)``), as the installed commands run them."""
    import importlib

    main = importlib.import_module(main_module).main
    assert main(["--version"]) == 0
    assert capsys.readouterr().out.strip().endswith(metadata.version("linkfea-vjm"))
