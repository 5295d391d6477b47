"""linkfea's error types: their message is what a user reads.

``LinkFeaError`` is bad input or a failed check (a ``ValueError``);
``SolverError`` is a numerical step that failed on input that passed the checks
(a ``RuntimeError``).  Both print as one ``error: ...`` line in the CLI.

>>> from linkfea.runtime.errors import LinkFeaError, SolverError
>>> issubclass(LinkFeaError, ValueError), issubclass(SolverError, RuntimeError)
(True, True)
"""


class LinkFeaError(ValueError):
    """Invalid input or a failed check in the link stage.

    The CLI prints ``str(err)`` on one line and exits non-zero, so the
    message must name what is wrong and, where possible, what to do.
    """


class SolverError(LinkFeaError, RuntimeError):
    """The mesher, the factorization, the linear solve or CalculiX failed.

    A ``RuntimeError``; it is also a :class:`LinkFeaError` so that code and
    CLIs catching ``LinkFeaError`` keep reporting it as one line.  To tell it
    from bad input, catch ``RuntimeError`` (or ``SolverError``) first.
    """


class ScriptError(LinkFeaError):
    """A link script (the user's code) raised, exited or failed to import.

    ``str(err)`` names the script, the line and the exception; ``details`` is the traceback of
    the script's own frames (what ``--traceback`` prints).
    """

    def __init__(self, message: str, details: str = ""):
        super().__init__(message)
        self.details = details


class LinkFeaWarning(UserWarning):
    """Something the user should know that did not stop the run (e.g. a damaged mesh cache entry
    that was meshed again).  The CLI prints it as one ``warning: ...`` line."""


def warnings_as_lines(*categories: type) -> None:
    """Show warnings of ``categories`` as one ``warning: ...`` line on stderr (no source line), others
    as Python does.  The command lines call it at start."""
    import sys
    import warnings

    python_show = getattr(warnings.showwarning, "python_show", warnings.showwarning)

    def show(message, category, filename, lineno, file=None, line=None):
        if issubclass(category, categories):
            print("warning: " + " ".join(str(message).split()), file=sys.stderr)
        else:
            python_show(message, category, filename, lineno, file, line)

    show.python_show = python_show  # type: ignore[attr-defined]
    warnings.showwarning = show
