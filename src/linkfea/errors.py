"""The one error type of linkfea: its message is what a user reads."""


class LinkFeaError(Exception):
    """Invalid input or a failed check in the link stage.

    The CLI prints ``str(err)`` on one line and exits non-zero, so the
    message must name what is wrong and, where possible, what to do.
    """
