"""vjm's error types: their message is what a user reads.

``VjmError`` is an invalid model, input or posture (a ``ValueError``);
``EquilibriumError`` is a solver that did not converge (a ``RuntimeError``).

>>> from vjm.errors import EquilibriumError, VjmError
>>> issubclass(VjmError, ValueError), issubclass(EquilibriumError, RuntimeError)
(True, True)
"""
from linkfea.runtime.checks import ArgumentError as _ArgumentError


class VjmError(ValueError):
    """Invalid model, input or posture in the stiffness stage.

    The CLI prints ``str(err)`` on one line and exits with status 2, so the
    message names what is wrong (the YAML key, the pose, the file) and, where
    possible, what to do.
    """


class EquilibriumError(VjmError, RuntimeError):
    """The nonlinear equilibrium (:mod:`vjm.stiffness.nonlinear`) was not found.

    A ``RuntimeError``; also a :class:`VjmError`, so that callers catching
    ``VjmError`` (the CLI, the diagnosis) keep handling it.  Catch
    ``RuntimeError`` first to tell it from bad input.
    """


class VjmWarning(UserWarning):
    """Something the user should know that did not stop the run (e.g. a local model file taking
    precedence over a bundled one of the same name).  The CLI prints it as one ``warning: ...`` line."""


class ArgumentError(VjmError, _ArgumentError):
    """A numeric argument of the wrong type or outside its range (see :mod:`linkfea.runtime.checks`):
    both a :class:`VjmError` and linkfea's ``ArgumentError``, so a CLI can name the flag."""


def user_errors():
    """The exceptions a CLI reports as one line: ours, linkfea's (link results, file output), OS errors."""
    from linkfea.runtime.errors import LinkFeaError

    return (VjmError, LinkFeaError, OSError)


def one_line(exc: BaseException) -> str:
    """The message of ``exc`` on one line (YAML and CSV parsers put newlines in theirs); a bad numeric
    argument is named by its CLI flag (``--noise-t``), not its Python name."""
    from linkfea.runtime.checks import cli_message

    return cli_message(exc)
