"""Running a typer app as a command: every usage error is one ``error:`` line and exit status 2.

click formats a bad flag value (``--alpha abc``) as a usage block and a framed
message over several lines; the commands of this project report every bad
input the same way, as one line.  ``run`` is the body of ``linkfea``'s and
``vjm``'s ``main(argv)``; tests call it in-process.
"""
from __future__ import annotations

import signal
import sys
import threading

import typer
from typer.core import TyperGroup
from typer.exceptions import TyperException

#: a hyphen that text wrapping does not break at, swapped in while the help is wrapped
_HYPHEN = "\u2011"


#: the help formatter of the click that typer runs on (typer >= 0.22 carries its own copy of click)
_Formatter: type = typer.Context.formatter_class


class _WholeWords(_Formatter):
    """click's help layout, wrapped at spaces only: ``--no-outliers`` and ``cross-validation`` stay whole."""

    def write_text(self, text: str) -> None:
        super().write_text(text.replace("-", _HYPHEN))

    def write_dl(self, rows, col_max: int = 30, col_spacing: int = 2) -> None:
        super().write_dl([(a, b.replace("-", _HYPHEN)) for a, b in rows], col_max, col_spacing)

    def write(self, string: str) -> None:
        super().write(string.replace(_HYPHEN, "-"))


class _HelpContext(typer.Context):
    formatter_class = _WholeWords


class _HelpGroup(TyperGroup):
    """The app's group: its commands' help is laid out by :class:`_WholeWords` too."""
    context_class = _HelpContext

    def get_command(self, ctx, cmd_name):
        cmd = super().get_command(ctx, cmd_name)
        if cmd is not None:
            cmd.context_class = _HelpContext
        return cmd


#: ``typer.Typer`` settings of both commands' help: click's plain layout, wrapped at spaces (rich's option
#: tables cut option help mid-word at 80 columns), as wide as the terminal up to 100 columns.
HELP_SETTINGS: dict = {"rich_markup_mode": None, "cls": _HelpGroup,
                       "context_settings": {"max_content_width": 100}}
#: the distribution both packages ship in
DISTRIBUTION = "linkfea-vjm"


def package_version() -> str:
    """The installed distribution's version (``unknown`` when the sources run uninstalled)."""
    from importlib import metadata

    try:
        return metadata.version(DISTRIBUTION)
    except metadata.PackageNotFoundError:
        return "unknown"


def version_option(prog: str):
    """A ``--version`` option for an app's callback: prints ``PROG VERSION``, exit status 0."""
    def show(value: bool) -> None:
        if value:
            print(f"{prog} {package_version()}")
            raise typer.Exit(0)

    return typer.Option(False, "--version", help="print the version and exit", callback=show, is_eager=True)


def fail(msg, flags: dict | None = None, traceback: bool = False) -> None:
    """One ``error:`` line, exit 2; with ``traceback``, a link script's own traceback before it (its
    ``details``).  ``flags``: Python argument names whose CLI flag differs (see :func:`checks.cli_message`)."""
    from .checks import cli_message

    details = getattr(msg, "details", "")
    if traceback and details:
        print(details.rstrip("\n"), file=sys.stderr)
    print(f"error: {cli_message(msg, flags or {})}", file=sys.stderr)
    raise typer.Exit(code=2)


def run(app, argv=None, prog: str | None = None) -> int:
    """Run ``app`` on ``argv`` (default: ``sys.argv[1:]``); returns the exit status.

    Ctrl-C ends the command with status 130 and one ``error: interrupted`` line (typer turns
    ``KeyboardInterrupt`` into a silent exit 130, so the signal is noted on its way in)."""
    args = list(sys.argv[1:] if argv is None else argv)
    if not args:  # the help, as click prints it
        args = ["--help"]
    hits: list[int] = []
    previous = None
    if threading.current_thread() is threading.main_thread() and signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        def on_ctrl_c(signum, frame):
            hits.append(signum)
            signal.default_int_handler(signum, frame)

        previous = signal.signal(signal.SIGINT, on_ctrl_c)
    try:
        status = _run(app, args, prog)
    finally:
        if previous is not None:
            signal.signal(signal.SIGINT, previous)
    if hits and status == 130:
        print("error: interrupted (Ctrl-C)", file=sys.stderr)
    return status


def _run(app, args: list, prog: str | None) -> int:
    try:
        rv = app(args=args, prog_name=prog, standalone_mode=False)
    except typer.Exit as exc:
        return int(exc.exit_code or 0)
    except typer.Abort:
        print("error: aborted", file=sys.stderr)
        return 130
    except TyperException as exc:  # click's usage errors: a bad value, a missing argument, an unknown flag
        fmt = getattr(exc, "format_message", None)
        print(f"error: {' '.join((fmt() if fmt else str(exc)).split())}", file=sys.stderr)
        return int(getattr(exc, "exit_code", 2) or 2)
    return rv if isinstance(rv, int) else 0
