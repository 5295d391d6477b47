"""The one error type of vjm: its message is what a user reads."""


class VjmError(Exception):
    """Invalid model, input or posture in the stiffness stage.

    The CLI prints ``str(err)`` on one line and exits with status 2, so the
    message names what is wrong (the YAML key, the pose, the file) and, where
    possible, what to do.
    """
