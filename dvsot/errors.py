"""The exception types the command line turns into one line: bad input (exit status 2), a failed run (exit 1)."""


class UserError(Exception):
    """Bad input from the user (a file, a field, a flag): the message is one line naming what and where."""

    def __init__(self, message: str) -> None:
        super().__init__(" ".join(str(message).split()))


class RunError(Exception):
    """A run that could not finish (a full disk, a dead worker): one line naming the output or the cause; exit 1."""

    def __init__(self, message: str) -> None:
        super().__init__(" ".join(str(message).split()))
