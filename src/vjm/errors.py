"""The one error type of vjm: its message is what a user reads."""


class VjmError(Exception):
    """Invalid model, input or posture in the stiffness stage.

    The CLI prints ``str(err)`` on one line and exits with status 2, so the
    message names what is wrong (the YAML key, the pose, the file) and, where
    possible, what to do.
    """


def user_errors():
    """The exceptions a CLI reports as one line: ours, linkfea's (link results, file output), OS errors."""
    from linkfea.errors import LinkFeaError

    return (VjmError, LinkFeaError, OSError)


def one_line(exc: BaseException) -> str:
    """The message of ``exc`` on one line (YAML and CSV parsers put newlines in theirs)."""
    return " ".join(str(exc).split())
