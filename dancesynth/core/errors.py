"""The one exception type for problems a user can cause and fix."""


class DancesynthError(Exception):
    """A user-facing error: its message is one sentence saying what is wrong and what to do.

    The CLI prints the message without a traceback and exits with status 1.
    """
