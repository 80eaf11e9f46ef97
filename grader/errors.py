"""The one exception type users see: a clear, actionable sentence instead of a traceback."""


class GraderError(Exception):
    """A problem with the user's input or environment, explained in plain words.

    The CLI prints ``grader: error: <message>`` and exits with status 2.
    """
