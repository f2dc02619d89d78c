"""The one exception type for bad user input; the command line turns it into one line and exit status 2."""


class UserError(Exception):
    """Bad input from the user (a file, a field, a flag): the message is one line naming what and where."""

    def __init__(self, message: str) -> None:
        super().__init__(" ".join(str(message).split()))
