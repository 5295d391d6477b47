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
from typer.exceptions import TyperException


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
